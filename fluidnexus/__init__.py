"""fluidnexus: 3D smoke reconstruction, prediction and interaction from video.

Importing the package is light: the Taichi engine (``fluidnexus.engine``) and the generative backends
(``fluidnexus.gen``) load only when used.
"""
import os

# torch's OpenMP threads otherwise spin after every torch op and take the cores from the next Taichi kernel
# (1.5-5x slower engine calls on CPU, measured in benchmarks/bench_splat.py). It must be set before torch loads.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.1.0"
