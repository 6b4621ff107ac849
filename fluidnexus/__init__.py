"""fluidnexus: 3D smoke reconstruction, prediction and interaction from video.

Importing the package is light: the Taichi engine (``fluidnexus.engine``) and the generative backends
(``fluidnexus.gen``) load only when used.
"""
__version__ = "0.1.0"
