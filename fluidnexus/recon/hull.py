"""Where the smoke is in a frame: a multi-view visual hull.

The first frame's hull seeds the visual particles before their positions are fitted to the first frame (Alg. S1,
initialisation), and the hulls of the first frames with smoke locate the inflow in the footage itself
(``source_finder``), which is more reliable than a box corner of the calibration. A voxel centre is kept when it
projects onto smoke in every view (a pixel that differs from what the view sees behind the smoke by more than
``threshold``: its clean plate, the backdrop colour, or black; ``scenery.backdrop``). A voxel outside some view's
image is dropped, which keeps ghosts at the image borders out.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..scene import Volume
from ..scenery.backdrop import smoke_mask


@dataclass(frozen=True)
class Hull:
    points: np.ndarray  # [K, 3] voxel centres inside the hull, metres
    voxel: float


CHUNK_POINTS = 1 << 18  # voxels tested at once: the hull's working memory is bounded by this, not by the grid


def hull_grid(volume: Volume, voxel: float) -> list[np.ndarray]:
    """The voxel centres along each axis of a ``voxel``-metre grid over ``volume``."""
    lo, hi = np.asarray(volume.min), np.asarray(volume.max)
    return [np.arange(lo[a] + voxel / 2, hi[a], voxel) for a in range(3)]


def visual_hull(cameras: tuple[Camera, ...], images: np.ndarray, volume: Volume, voxel: float,
                threshold: float = 0.05, behind=None) -> Hull:
    """Voxel centres on a ``voxel``-metre grid over ``volume`` that every view sees as smoke (``smoke_mask``
    against the view's entry of ``behind``, [V] ``scenery.backdrop.Behind``: its background, at ``threshold``
    times its reach; black at ``threshold`` without them).

    The grid is tested in slabs of at most ``CHUNK_POINTS`` voxels (whole x-planes), so the memory needed is
    that of one slab plus the kept points, whatever the grid's size.

    Args:
        cameras: [V] cameras matching ``images``.
        images: [V, H, W, C] one frame per view, in [0, 1].
    """
    xs, ys, zs = hull_grid(volume, voxel)
    if behind is None:
        masks = [smoke_mask(image, threshold) for image in images]
    else:
        masks = [b.smoke_mask(image, threshold) for image, b in zip(images, behind)]
    planes = max(1, CHUNK_POINTS // max(1, len(ys) * len(zs)))
    kept = [np.zeros((0, 3))]
    for i in range(0, len(xs), planes):
        pts = np.stack(np.meshgrid(xs[i:i + planes], ys, zs, indexing="ij"), -1).reshape(-1, 3)
        inside = np.ones(len(pts), bool)
        for cam, mask in zip(cameras, masks):
            uv, depth = cam.project(pts)
            col, row = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
            seen = (depth > 0) & (col >= 0) & (col < cam.width) & (row >= 0) & (row < cam.height)
            smoke = np.zeros(len(pts), bool)
            smoke[seen] = mask[row[seen], col[seen]]
            inside &= smoke  # a voxel outside a view's image cannot be confirmed as smoke: it is carved
        kept.append(pts[inside])
    return Hull(np.concatenate(kept), voxel)
