"""The floor one view does not see (docs/static-layer.md, "A single view").

A single view over a textured backdrop (a room) seeds each of its rays where it meets the scene's floor, else on a
shell behind the volume (``static_layer``). A camera turned about the plume then sees the floor the input saw in its
place, and beyond the input's frame nothing: the background colour, one colour for the whole unseen world. The
floor does not stop at the input's frame, so this module states one assumption: **the floor goes on, of the colour
the input shows it**. Nodes of a square lattice on the floor plane, within the shell's radius of the point below
the volume's centre, that the input camera does not see (behind it or outside its image), each seed a Gaussian of
the mean colour of the input's floor pixels. The input's fit cannot move them (no view shows them); they are the
best single colour for a floor of unknown pattern (the mean minimises the squared error). Nothing is seeded where
the input shows too little floor to give its colour (under ``MIN_FLOOR`` of its sure pixels): a camera that looks
up (no floor in view) says nothing about the floor's colour. The rest of the view (its walls) gives the colour of
what it never saw above the floor: the static layer's background colour."""
from __future__ import annotations

import numpy as np

MIN_FLOOR = 0.05  # the input's floor colour needs at least this share of its sure pixels on the floor


def floor_pixels(camera, confidence: np.ndarray, floor, center: np.ndarray, radius: float) -> np.ndarray | None:
    """[H, W] bool: the sure pixels (confidence >= 0.5) whose rays meet ``floor`` from above within ``radius`` of
    ``center``'s foot on it; None where they are under ``MIN_FLOOR`` of the sure pixels or the camera is not above
    the floor."""
    normal, point = np.asarray(floor.normal, np.float64), np.asarray(floor.point, np.float64)
    sure = np.asarray(confidence) >= 0.5
    if float((camera.center - point) @ normal) <= 0 or not sure.any():
        return None
    rows, cols = np.nonzero(sure)
    rays = camera.unproject(np.stack([cols + 0.5, rows + 0.5], axis=1), np.ones(len(rows))) - camera.center
    s = floor.reach(camera.center, rays)
    hit = camera.center + np.where(np.isfinite(s), s, 0.0)[:, None] * rays
    foot = center - ((center - point) @ normal) * normal
    on_floor = np.isfinite(s) & (np.linalg.norm(hit - foot, axis=1) <= radius)
    if on_floor.sum() < MIN_FLOOR * len(rows):
        return None
    mask = np.zeros_like(sure)
    mask[rows[on_floor], cols[on_floor]] = True
    return mask


def wall_colour(camera, plate: np.ndarray, confidence: np.ndarray, floor, center: np.ndarray, radius: float,
                near: float) -> np.ndarray | None:
    """[C] the mean colour of the view's sure pixels whose rays do not meet ``floor`` within ``radius`` of
    ``center``'s foot on it (its walls: what the view shows above the floor); None where under ``MIN_FLOOR`` of its
    sure pixels are such, or the view shows too little floor within ``near`` (``radius`` is at least ``near``)."""
    image = np.asarray(plate, np.float64).reshape(plate.shape[0], plate.shape[1], -1)
    if floor_pixels(camera, confidence, floor, center, near) is None:
        return None
    sure = np.asarray(confidence) >= 0.5
    off = sure & ~floor_pixels(camera, confidence, floor, center, radius)  # not None: it holds the near floor
    return image[off].mean(axis=0) if off.sum() >= MIN_FLOOR * sure.sum() else None


def floor_beyond_frame(camera, plate: np.ndarray, confidence: np.ndarray, floor, center: np.ndarray, radius: float,
                       near: float, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points [N, 3], colours [N, C], spacing [N]): the seeds of the floor ``camera`` does not see (module
    docstring; the lattice's spacing puts about ``count`` nodes in the disc of ``radius`` about ``center``'s foot
    on ``floor``, in the mean colour of the floor pixels within ``near`` of it); none where the view shows too
    little floor within ``near``."""
    channels = np.asarray(plate).reshape(plate.shape[0], plate.shape[1], -1).shape[-1]
    image = np.asarray(plate, np.float64).reshape(plate.shape[0], plate.shape[1], channels)
    center = np.asarray(center, np.float64)
    close = floor_pixels(camera, confidence, floor, center, near)
    if close is None:
        return np.zeros((0, 3)), np.zeros((0, channels)), np.zeros(0)
    normal, point = np.asarray(floor.normal, np.float64), np.asarray(floor.point, np.float64)
    foot = center - ((center - point) @ normal) * normal
    a = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    spacing = radius * float(np.sqrt(np.pi / max(count, 1)))
    steps = np.arange(-np.floor(radius / spacing), np.floor(radius / spacing) + 1) * spacing
    i, j = (g.ravel() for g in np.meshgrid(steps, steps))
    inside = i * i + j * j <= radius * radius
    nodes = foot + i[inside, None] * a + j[inside, None] * b
    uv, z = camera.project(nodes)
    seen = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= camera.width) & (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height)
    nodes = nodes[~seen]
    colours = np.tile(image[close].mean(axis=0), (len(nodes), 1))
    return nodes, colours, np.full(len(nodes), spacing)
