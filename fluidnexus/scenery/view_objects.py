"""Objects one view shows over a plain backdrop, given a depth and a body (docs/static-layer.md, "A single view").

One view does not see how far away an object is, nor how deep it is. Over a textured backdrop a single view's
static layer seeds its rays on the floor and a shell (``static_layer``); over a plain backdrop (black, white) what
differs from the backdrop's colour is an object, which those seeds would put behind the scene. This module states
two assumptions instead and fills the object's body with seeds from them:

- **It stands at the smoke's depth.** An object seen in a smoke video over a plain backdrop is what the smoke
  meets (a ball, a box in the plume's path), so its upright axis is at the camera-space depth of ``anchor``: the
  declared source, else the plume's foot that ``synth`` found (``world.view_anchor``).
- **It is round in plan.** Each connected patch of object pixels is a solid of revolution about an axis along the
  scene's up (the floor's normal) through the patch's middle pixel at the anchor's depth, each row's slice a disk
  as wide as the row's pixels there: a pixel's ray crosses the body along the chord it cuts through that disk, and
  seeds fill the chord with the pixel's colour. From a camera turned about the plume the object then shows as wide
  as it is across, upright, where the plume is; the input view's fit sets the colours and opacities it sees.

``object_seeds`` fills each body with the static layer's seeds; ``object_balls`` gives the ball each stands for,
a solid the gas flows around (``world.view_balls``). Patches under ``min_pixels`` are left out (a plate's noise,
not an object)."""
from __future__ import annotations

import cv2
import numpy as np

MIN_PIXELS = 4  # a patch of fewer object pixels is noise, not an object


def object_mask(plate: np.ndarray, confidence: np.ndarray, fill: np.ndarray, plain: float) -> np.ndarray:
    """[H, W] bool: the sure pixels (confidence >= 0.5) whose colour differs from ``fill`` by more than ``plain``."""
    plate = np.asarray(plate, np.float64)
    differs = np.abs(plate - np.asarray(fill, np.float64).reshape(1, 1, -1)).max(axis=-1) > plain
    return differs & (np.asarray(confidence) >= 0.5)


def _patches(camera, plate, confidence, fill, anchor, plain: float, min_pixels: int):
    """(metres per pixel at the anchor's depth z0, z0, [(rows, cols)] of each patch of at least ``min_pixels``
    object pixels), or None when the anchor is behind the camera or the view shows no object."""
    mask = object_mask(plate, confidence, fill, plain)
    z0 = float(camera.project(np.asarray(anchor, np.float64)[None])[1][0])
    if z0 <= 0 or not mask.any():
        return None
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    patches = [np.nonzero(labels == label) for label in range(1, count)]
    return z0 / float(camera.K[0, 0]), z0, [(r, c) for r, c in patches if len(r) >= min_pixels]


def _lattice(camera, patches: list, stride: int, metres_per_px: float, z0: float, up: np.ndarray):
    """Per ``stride``-th object pixel of every patch: (column, row, camera-space depth of the middle of the chord its
    ray cuts through the body, half that chord's length in depth). The body about a patch is upright along ``up``
    (unit, world) through the patch's middle pixel at depth ``z0``; each row's slice of it a disk as wide as the
    row's pixels at that depth. A ray that passes the disk (its pixel at the row's edge) keeps the depth where it
    comes nearest the axis, a chord of length 0."""
    out = []
    for rows, cols in patches:
        axis_px = [0.5 * (cols.min() + cols.max() + 1), 0.5 * (rows.min() + rows.max() + 1)]
        o = camera.center - camera.unproject(np.array([axis_px]), np.array([z0]))[0]  # the camera from the axis
        oh = o - (o @ up) * up  # its part across the axis
        for row in np.unique(rows[rows % stride == 0]):
            in_row = cols[rows == row]
            half = 0.5 * (in_row.max() + 1 - in_row.min()) * metres_per_px  # the row's half-width a
            c = in_row[in_row % stride == 0]
            uv = np.stack([c + 0.5, np.full(len(c), row + 0.5)], axis=1)
            d = camera.unproject(uv, np.ones(len(c))) - camera.center  # the ray X(z) = axis + o + z d
            dh = d - (d @ up)[:, None] * up[None]
            aa, bb, cc = np.maximum((dh * dh).sum(axis=1), 1e-12), dh @ oh, float(oh @ oh) - half ** 2
            mid = -bb / aa  # where the ray comes nearest the axis
            reach = np.sqrt(np.maximum(bb * bb - aa * cc, 0.0)) / aa  # half the chord inside |X_h| <= a
            out.append((c, np.full(len(c), row), mid, reach))
    if not out:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0), np.zeros(0)
    return tuple(np.concatenate(a) for a in zip(*out))


def object_seeds(camera, plate: np.ndarray, confidence: np.ndarray, fill: np.ndarray, anchor, plain: float,
                 budget: int, up, min_pixels: int = MIN_PIXELS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points [N, 3], colours [N, C], spacing [N]): every object patch of the view filled as its body (module
    docstring), upright along ``up`` (world), on a lattice of ``stride`` pixels' footprint at the axis's depth,
    across the image and in depth, each seed with its pixel's colour; the stride is the smallest that keeps N
    within ``budget``, and ``spacing`` is the lattice's. Nothing when the anchor is behind the camera."""
    empty = (np.zeros((0, 3)), np.zeros((0, plate.shape[-1])), np.zeros(0))
    found = _patches(camera, plate, confidence, fill, anchor, plain, min_pixels)
    if found is None:
        return empty
    metres_per_px, z0, patches = found
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    stride = 0
    while True:  # the seeds fall as the stride's cube
        stride += 1
        step = stride * metres_per_px
        cols, rows, mid, reach = _lattice(camera, patches, stride, metres_per_px, z0, up)
        layers = np.floor(reach / step).astype(int)  # seeds at k * step in front of and behind the chord's middle
        if int((2 * layers + 1).sum()) <= budget:
            break
    if len(cols) == 0:
        return empty
    k = np.concatenate([np.arange(-n, n + 1) for n in layers])
    pixel = np.repeat(np.arange(len(cols)), 2 * layers + 1)
    uv = np.stack([cols[pixel] + 0.5, rows[pixel] + 0.5], axis=1)
    points = camera.unproject(uv, mid[pixel] + k * step)
    colors = np.asarray(plate, np.float64)[rows[pixel], cols[pixel]].reshape(len(pixel), -1)
    return points, colors, np.full(len(points), step)


def object_balls(camera, plate: np.ndarray, confidence: np.ndarray, fill: np.ndarray, anchor, plain: float,
                 min_pixels: int = MIN_PIXELS) -> list[tuple[np.ndarray, float]]:
    """(centre [3], radius) of the ball each object patch of the view stands for (module docstring): centred on
    the patch's axis at the anchor's depth, at the middle of its rows, as large as a ball that covers the patch's
    area (radius ``sqrt(pixels / pi)`` pixels' footprint at that depth). Largest first; none when the anchor is
    behind the camera."""
    found = _patches(camera, plate, confidence, fill, anchor, plain, min_pixels)
    if found is None:
        return []
    metres_per_px, z0, patches = found
    balls = []
    for rows, cols in patches:
        uv = np.array([[0.5 * (cols.min() + cols.max() + 1), 0.5 * (rows.min() + rows.max() + 1)]])
        balls.append((camera.unproject(uv, np.array([z0]))[0], float(np.sqrt(len(rows) / np.pi)) * metres_per_px))
    return sorted(balls, key=lambda b: -b[1])
