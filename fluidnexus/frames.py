"""Images of a run: render saved states from any camera, orbit cameras, side-by-side comparisons."""
from __future__ import annotations

import math

import numpy as np
import torch

from fluidnexus.scenery.backdrop import Behind

from . import engine
from .camera import Camera
from .engine.tensors import torch_dtype
from .scene import Volume
from .state import FrameState


def render_state(state: FrameState, camera: Camera, behind: Behind | None = None, matte: bool = False):
    """The visual particles of ``state`` seen by ``camera``: float32 [H, W, C] in [0, 1], composited with
    ``behind`` (``scenery.backdrop``: a background and static Gaussians; black without it). With ``matte``,
    the smoke's own alpha [H, W, 1] instead (the static Gaussians and the background left out)."""
    dtype = torch_dtype()
    extra = {} if behind is None or matte else behind.render_args(dtype)

    def t(a):
        return torch.as_tensor(np.asarray(a), dtype=dtype)

    with torch.no_grad():
        image, alpha, _ = engine.render(camera, t(state.visual_positions), t(state.visual_scales),
                                        t(state.visual_rotations), t(state.visual_opacities), t(state.visual_colors),
                                        **extra)
    out = alpha[..., None] if matte else image
    return out.clamp(0, 1).numpy().astype(np.float32)


def orbit_cameras(volume: Volume, like: Camera, count: int, elevation_deg: float = 10.0) -> list[Camera]:
    """``count`` cameras on a horizontal circle around the volume's vertical axis, looking at its centre.

    They keep ``like``'s image size and focal length and stand as far from the centre as ``like`` does.
    """
    center = volume.center
    radius = float(np.linalg.norm((like.center - center)[[0, 2]])) or 1.0
    height = center[1] + radius * math.tan(math.radians(elevation_deg))
    start = math.atan2(like.center[0] - center[0], like.center[2] - center[2])
    cams = []
    for k in range(count):
        a = start + 2 * math.pi * k / count
        eye = np.array([center[0] + radius * math.sin(a), height, center[2] + radius * math.cos(a)])
        cams.append(Camera.look_at(like.width, like.height, float(like.K[0, 0]), eye, center))
    return cams


def side_by_side(*images: np.ndarray, gap: int = 4) -> np.ndarray:
    """Images [H, W, C] next to each other with a white gap; gray images are promoted to RGB if any is RGB."""
    channels = max(im.shape[2] for im in images)
    tiles = [np.repeat(im, channels // im.shape[2], axis=2) for im in images]
    sep = np.ones((tiles[0].shape[0], gap, channels), np.float32)
    out = [tiles[0]]
    for tile in tiles[1:]:
        out += [sep, tile]
    return np.concatenate(out, axis=1)
