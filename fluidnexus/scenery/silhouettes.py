"""A ball's centre and radius from its silhouettes (docs/static-layer.md, "Obstacles").

The static layer's surface depths are noisy (a ball without texture has no stereo depth; its Gaussians fill
its hull), but its silhouettes in the training views are exact: the layer reproduces those views. Every boundary
pixel of a silhouette is the image of a ray that grazes the ball, so the ball (c, r) satisfies, for every such ray
through the camera centre o with unit direction d,

    | (c - o) - ((c - o) . d) d | = r          (the distance of the centre from the ray)

which holds under perspective projection exactly (a ball's outline is an ellipse in the image, not a circle). The
rays of all views are solved together by robust non-linear least squares (soft-L1 residuals, so that static smoke
kept beside the ball does not pull it), starting from the layer's sphere.

A view's silhouette is the connected part of its object mask (the caller's: the static layer's Gaussians inside
the volume, drawn alone, alpha at least 0.5, which separates the ball from a textured backdrop behind it) that
holds the ball's projected centre; its outline runs between the silhouette's pixels and their neighbours outside it
(not along the image border, where the silhouette goes on out of view), and points further than ``reach``
projected radii from the projected centre are left out (other objects touching the ball's silhouette).
"""
from __future__ import annotations

import numpy as np

from ..camera import Camera


def silhouette_rays(camera: Camera, objects: np.ndarray, center: np.ndarray, radius: float,
                    reach: float = 1.6) -> tuple[np.ndarray, np.ndarray]:
    """(origins [K, 3], unit directions [K, 3]) of the rays through the boundary pixels of the silhouette of the
    ball (``center``, ``radius``: a first guess) in one view's object mask ``objects`` [H, W] bool; empty arrays
    when the projected centre lies outside the image or on no object pixel."""
    from scipy import ndimage

    empty = (np.zeros((0, 3)), np.zeros((0, 3)))
    uv, depth = camera.project(np.asarray(center, np.float64)[None])
    col, row = int(np.floor(uv[0, 0])), int(np.floor(uv[0, 1]))
    if depth[0] <= 0 or not (0 <= col < camera.width and 0 <= row < camera.height):
        return empty
    labels, _ = ndimage.label(objects)
    if labels[row, col] == 0:
        return empty
    mask = ndimage.binary_fill_holes(labels == labels[row, col])
    uv_edge = _outline(mask)
    pixel_radius = camera.K[0, 0] * radius / depth[0]
    near = np.hypot(uv_edge[:, 0] - uv[0, 0], uv_edge[:, 1] - uv[0, 1]) <= reach * pixel_radius
    points = camera.unproject(uv_edge[near], 1.0)
    origin = np.asarray(camera.center, np.float64)
    d = points - origin
    return np.repeat(origin[None], len(d), axis=0), d / np.linalg.norm(d, axis=1, keepdims=True)


def _outline(mask: np.ndarray) -> np.ndarray:
    """[K, 2] pixel coordinates (u, v) of the outline of ``mask`` [H, W]: the midpoints between each pixel of the
    mask and each of its 4-neighbours outside it (unbiased to half a pixel, where the inner boundary pixels' own
    centres lie half a pixel inside). Neighbours beyond the image border do not count: the outline goes on out
    of view there."""
    rows, cols = np.mgrid[0:mask.shape[0], 0:mask.shape[1]]
    points = []
    for dr, dc in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        inside = mask[max(0, -dr):mask.shape[0] - max(0, dr), max(0, -dc):mask.shape[1] - max(0, dc)]
        beyond = mask[max(0, dr):mask.shape[0] - max(0, -dr) or None, max(0, dc):mask.shape[1] - max(0, -dc) or None]
        r = rows[max(0, -dr):mask.shape[0] - max(0, dr), max(0, -dc):mask.shape[1] - max(0, dc)]
        c = cols[max(0, -dr):mask.shape[0] - max(0, dr), max(0, -dc):mask.shape[1] - max(0, dc)]
        edge = inside & ~beyond
        points.append(np.stack([c[edge] + 0.5 + 0.5 * dc, r[edge] + 0.5 + 0.5 * dr], axis=1))
    return np.concatenate(points).astype(np.float64)


def fit_ball_to_rays(origins: np.ndarray, directions: np.ndarray, center: np.ndarray,
                     radius: float) -> tuple[np.ndarray, float, float]:
    """(centre, radius, rms residual of the inlier rays, metres): the ball tangent to the rays, robustly
    (scipy's soft-L1 loss with a scale of 2 % of ``radius``), from the guess (``center``, ``radius``)."""
    from scipy.optimize import least_squares

    def residual(x):
        rel = x[:3] - origins
        along = np.einsum("ij,ij->i", rel, directions)
        return np.linalg.norm(rel - along[:, None] * directions, axis=1) - x[3]

    x0 = np.concatenate([np.asarray(center, np.float64), [float(radius)]])
    sol = least_squares(residual, x0, loss="soft_l1", f_scale=0.02 * radius)
    res = residual(sol.x)
    inliers = np.abs(res) <= 2.5 * np.median(np.abs(res)) + 1e-12
    return sol.x[:3], float(sol.x[3]), float(np.sqrt(np.mean(res[inliers] ** 2)))
