"""``fluidnexus view``: look at a run (or two side by side) in a web browser, frame by frame.

- :mod:`.content`: what is drawn, as arrays (splats of the visual Gaussians, particles coloured by speed, frusta).
- :mod:`.sources`: what is read from a run folder, lazily (frame states, cameras, video thumbnails, obstacles).
- :mod:`.server`: the viser scene and its control panel (needs the ``[view]`` extra: viser).
"""
from .server import check_port, open_viewer, require_viser, serve

__all__ = ["check_port", "open_viewer", "require_viser", "serve"]
