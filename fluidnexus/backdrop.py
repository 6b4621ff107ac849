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

from dataclasses import dataclass

import cv2
import numpy as np

from .camera import Camera
from .scene import Scene

LUMA = np.array([0.299, 0.587, 0.114], np.float32)  # the gray of a colour, as fluidnexus.video reads gray footage


def to_channels(image: np.ndarray, channels: int) -> np.ndarray:
    """An [..., 3] colour image or value as [..., channels] (1: luma; 3: as is)."""
    image = np.asarray(image, np.float32)
    if channels == image.shape[-1]:
        return image
    if channels == 1 and image.shape[-1] == 3:
        return (image @ LUMA)[..., None].astype(np.float32)
    if channels == 3 and image.shape[-1] == 1:
        return np.repeat(image, 3, axis=-1)
    raise ValueError(f"cannot convert {image.shape[-1]} channels into {channels}")


def resize_image(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """[H, W, C] resized to ``height x width`` (area averaging to shrink, bilinear to enlarge)."""
    if image.shape[:2] == (height, width):
        return image
    shrink = width <= image.shape[1] and height <= image.shape[0]
    out = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
    return out.reshape(height, width, image.shape[2])


@dataclass(frozen=True, eq=False)
class Behind:
    """What a render composites the smoke with: ``background`` [C] (one colour) or [H, W, C] (per pixel), and
    ``static`` (a ``fluidnexus.static.StaticLayer`` whose Gaussians are depth-sorted with the smoke) or None."""

    background: np.ndarray
    static: object | None = None

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
        smoke_layers: names of the views whose videos are smoke layers over black (``synth`` recorded
            ``smoke_layer`` in their provenance).
        layer: the run's static layer (``fluidnexus.static.StaticLayer``, in ``channels``) or None.
        color: the scene's backdrop colour (3,) or None.
    """

    channels: int
    plates: dict
    smoke_layers: frozenset = frozenset()
    layer: object | None = None
    color: np.ndarray | None = None

    def behind(self, camera: Camera, view: str | None = None) -> Behind:
        """What ``camera`` sees behind the smoke; ``view`` names the scene view it belongs to (None: any other
        camera, e.g. a held-out or orbit camera)."""
        if view in self.plates:
            plate = resize_image(self.plates[view], camera.width, camera.height)
            return Behind(to_channels(plate, self.channels), self.obstacles())
        if view in self.smoke_layers:
            return Behind(np.zeros(self.channels, np.float32))
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
        from .static import inside_volume

        part = inside_volume(self.layer)
        return part if len(part) else None


def black_backdrop(channels: int) -> Backdrop:
    """Black behind every camera (``render --background black``, ``eval --background black``)."""
    return Backdrop(channels, {})


def scene_backdrop(scene: Scene, channels: int, layer=None) -> Backdrop:
    """The backdrop of ``scene`` (its plates and colour) with an optional static layer."""
    from .background.store import read_plate

    plates = {name: read_plate(scene, name)[0] for name in scene.backgrounds}
    color = None if scene.backdrop_color is None else np.asarray(scene.backdrop_color, np.float32)
    layers = frozenset(v.name for v in scene.views if v.video is not None and (v.provenance or {}).get("smoke_layer"))
    return Backdrop(channels, plates, layers, layer, color)


def run_backdrop(run) -> Backdrop:
    """The backdrop of a run (``fluidnexus.runs.Run``): its scene's plates and colour, and its static layer
    (``RUN/static.npz``) where recon fitted one."""
    from .static import STATIC_FILE, load_static

    layer = load_static(run.root / STATIC_FILE) if (run.root / STATIC_FILE).is_file() else None
    return scene_backdrop(run.scene(check_videos=False), run.channels, layer)
