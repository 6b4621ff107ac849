"""The family's renderer: numpy ray marching through the smoke density, independent of the project's splat renderer.

Emission-absorption (Max 1995, "Optical models for direct volume rendering", Sec. 4): along each pixel's ray, the
density grid is sampled trilinearly at steps of ``dt`` = 0.5 cells between where the ray enters the box and where it
leaves it or meets the first solid surface (a depth test: smoke behind a body or the set is hidden, smoke in front of
it covers it). Each sample has extinction sigma = kappa * density and adds T * (1 - exp(-sigma dt)) * smoke colour;
the transmittance T falls by exp(-sigma dt). What is left of T shows the surface behind (``geometry.surfaces``) or the
backdrop's plain colour. Glowing smoke has a colour brighter than what is behind it, absorbing smoke a darker one;
both are the same formula.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from .geometry import PinholeCamera, slab, surfaces

STEP_CELLS = 0.5


def static_image(camera: PinholeCamera, bodies, backdrop) -> np.ndarray:
    """[H, W, 3] what the camera sees without smoke (the clean plate)."""
    o, d = camera.rays()
    _, color = surfaces(o, d, bodies, backdrop)
    return color.reshape(camera.height, camera.width, 3).astype(np.float32)


def render(camera: PinholeCamera, density: np.ndarray, grid, kappa: float, smoke_color, bodies,
           backdrop) -> np.ndarray:
    """[T, H, W, 3] images of the density frames [T, nx, ny, nz] (on ``grid``) from ``camera``, in [0, 1]."""
    o, d = camera.rays()
    t_surface, behind = surfaces(o, d, bodies, backdrop)
    t0, t1, _ = slab(o, d, grid.lo, grid.hi)
    t0 = np.maximum(t0, 0.0)
    t1 = np.minimum(t1, t_surface)
    step = STEP_CELLS * grid.dx
    hits = np.nonzero(t1 > t0)[0]
    frames = len(density)
    out = np.tile(behind[None], (frames, 1, 1)).astype(np.float64)
    if len(hits):
        count = int(np.ceil((t1[hits] - t0[hits]).max() / step))
        ts = t0[hits, None] + (np.arange(count) + 0.5) * step           # [R, S]
        inside = ts < t1[hits, None]
        pts = o + ts[..., None] * d[hits, None, :]                      # [R, S, 3]
        coords = ((pts - np.asarray(grid.lo)) / grid.dx - 0.5).reshape(-1, 3).T
        color = np.asarray(smoke_color, float)
        for f in range(frames):
            if not density[f].any():
                continue
            rho = ndimage.map_coordinates(density[f], coords, order=1, mode="constant").reshape(ts.shape)
            alpha = 1.0 - np.exp(-kappa * np.clip(rho, 0, None) * step * inside)
            trans = np.cumprod(np.concatenate([np.ones((len(hits), 1)), 1.0 - alpha[:, :-1]], 1), 1)
            emitted = (trans * alpha).sum(1)
            left = trans[:, -1] * (1.0 - alpha[:, -1])
            out[f, hits] = emitted[:, None] * color + left[:, None] * behind[hits]
    return np.clip(out, 0, 1).reshape(frames, camera.height, camera.width, 3).astype(np.float32)
