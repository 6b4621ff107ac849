"""What each camera sees behind the smoke (docs/background.md, "In the pipeline"): one rule for recon, predict,
eval and render.

A frame is the smoke composited over the static scene, ``I = sum_i c_i a_i T_i + T_N B`` (3DGS compositing with a
per-pixel background B). For a camera the static scene is, in this order:

1. an **input view with a clean plate** (``fluidnexus background``): the plate is B, and the static layer's
   Gaussians inside the volume (obstacles) are drawn with the smoke, so that they hide the smoke behind them;
2. a **synthesised novel view written as a smoke layer** (``synth`` on an input view with a plate records
   ``provenance.smoke_layer``): B is black;
3. any other camera (held-out, novel without video, orbit) of a run with a **static layer**: every static
   Gaussian, over the layer's background colour;
4. the scene's known **backdrop colour** (PINF ``frame_bkg_color``) as a constant B;
5. black (ScalarFlow-like footage: smoke that glows on black, as before any of this existed).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..camera import Camera
from ..images import resize_image, to_channels
from ..scene import Scene


@dataclass(frozen=True, eq=False)
class Behind:
    """What a render composites the smoke with: ``background`` [C] (one colour) or [H, W, C] (per pixel), and
    ``static`` (a ``scenery.static_layer.StaticLayer`` whose Gaussians are depth-sorted with the smoke) or None.
    ``reach``: the most that opaque smoke changes a channel of this view's frames, in the units of a smoke mask's
    threshold (1; a smoke layer over black: its smoke colour's brightest channel, so dark smoke that absorbs is as
    visible in its smoke layer as white smoke in its own, ``smoke_mask``)."""

    background: np.ndarray
    static: object | None = None
    reach: float = 1.0

    def smoke_mask(self, image: np.ndarray, threshold: float) -> np.ndarray:
        """[H, W] bool: the pixels of this view's ``image`` that show smoke (:func:`smoke_mask` against the
        background, at ``threshold`` times ``reach``)."""
        return smoke_mask(image, threshold * self.reach, self.background)

    def render_args(self, dtype) -> dict:
        """``background=`` and ``static=`` of ``engine.render`` as tensors of ``dtype`` (the static Gaussians
        frozen)."""
        import torch

        static = None if self.static is None else self.static.gaussians(dtype)
        return {"background": torch.as_tensor(self.background, dtype=dtype), "static": static}


@dataclass(frozen=True, eq=False)
class Backdrop:
    """The static scene of a scene or run (module docstring), at ``channels`` colour channels.

    Attributes:
        plates: input view name -> its clean plate [H, W, 3] at the camera's full size.
        smoke_layers: name -> smoke colour's brightest channel, of the views whose videos are smoke layers over
            black (``synth`` recorded ``smoke_layer`` in their provenance; 1 where it recorded no colour).
        layer: the run's static layer (``scenery.static_layer.StaticLayer``, in ``channels``) or None.
        color: the scene's backdrop colour (3,) or None.
    """

    channels: int
    plates: dict
    smoke_layers: dict = field(default_factory=dict)
    layer: object | None = None
    color: np.ndarray | None = None

    def behind(self, camera: Camera, view: str | None = None) -> Behind:
        """What ``camera`` sees behind the smoke; ``view`` names the scene view it belongs to (None: any other
        camera, e.g. a held-out or orbit camera)."""
        if view in self.plates:
            plate = resize_image(self.plates[view], camera.width, camera.height)
            return Behind(to_channels(plate, self.channels), self.obstacles())
        if view in self.smoke_layers:
            return Behind(np.zeros(self.channels, np.float32), reach=self.smoke_layers[view])
        if self.layer is not None:
            return Behind(np.asarray(self.layer.background, np.float32), self.layer)
        return Behind(self.constant())

    def constant(self) -> np.ndarray:
        """The backdrop colour [C] where there is no plate and no layer (black without one)."""
        if self.color is None:
            return np.zeros(self.channels, np.float32)
        return to_channels(np.asarray(self.color, np.float32), self.channels)

    def obstacles(self):
        """The static layer's Gaussians inside its volume (the content a plate shows in front of the backdrop),
        or None."""
        if self.layer is None:
            return None
        from .static_layer import inside_volume

        part = inside_volume(self.layer)
        return part if len(part) else None


def black_backdrop(channels: int) -> Backdrop:
    """Black behind every camera (``render --background black``, ``eval --background black``)."""
    return Backdrop(channels, {})


def scene_backdrop(scene: Scene, channels: int, layer=None) -> Backdrop:
    """The backdrop of ``scene`` (its plates and colour) with an optional static layer."""
    from .plate_store import read_plate

    plates = {name: read_plate(scene, name)[0] for name in scene.backgrounds}
    color = None if scene.backdrop_color is None else np.asarray(scene.backdrop_color, np.float32)
    layers = {v.name: _reach(v.provenance["smoke_layer"], channels) for v in scene.views
              if v.video is not None and (v.provenance or {}).get("smoke_layer")}
    return Backdrop(channels, plates, layers, layer, color)


def _reach(record: dict, channels: int) -> float:
    """The brightest channel of a smoke layer's smoke colour (its provenance ``smoke_layer`` record), in
    ``channels``; 1 where none was recorded."""
    color = record.get("smoke_color")
    return 1.0 if color is None else float(to_channels(np.asarray(color, np.float32), channels).max())


def run_backdrop(run) -> Backdrop:
    """The backdrop of a run (``fluidnexus.runs.Run``): its scene's plates and colour, and its static layer
    (``RUN/static.npz``) where recon fitted one."""
    from .static_layer import STATIC_FILE, load_static

    layer = load_static(run.root / STATIC_FILE) if (run.root / STATIC_FILE).is_file() else None
    return scene_backdrop(run.scene(check_videos=False), run.channels, layer)


def smoke_mask(image: np.ndarray, threshold: float, backdrop=None) -> np.ndarray:
    """[H, W] bool: pixels of ``image`` [H, W, C] that differ from the backdrop ([C] one value or [H, W, C] a
    plate; black without one) by more than ``threshold`` in some channel (smoke glows on black, darkens white).
    A view's ``Behind.smoke_mask`` scales the threshold by how far its smoke can reach."""
    if backdrop is None:
        return image.max(axis=2) > threshold
    return np.abs(image - np.asarray(backdrop, image.dtype)).max(axis=2) > threshold
