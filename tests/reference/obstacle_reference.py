"""Slow numpy references of the obstacle geometry (tests only)."""
from __future__ import annotations

import numpy as np


def triangle_distance(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distance [K, F] m from points [K, 3] to triangles [F, 3, 3] (closest point by Voronoi regions)."""
    a, b, c = tri[None, :, 0], tri[None, :, 1], tri[None, :, 2]
    p = points[:, None, :]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    safe = np.where(np.abs(denom) > 1e-30, denom, 1.0)
    v, w = vb / safe, vc / safe
    closest = a + ab * v[..., None] + ac * w[..., None]  # interior of the face
    tiny = 1e-30

    def edge(mask, start, vec, t):
        return np.where(mask[..., None], start + vec * np.clip(t, 0, 1)[..., None], closest)

    # edge regions (later assignments take precedence: vertices last)
    closest = edge((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b, c - b,
                   (d4 - d3) / np.maximum((d4 - d3) + (d5 - d6), tiny))
    closest = edge((vb <= 0) & (d2 >= 0) & (d6 <= 0), a, ac, d2 / np.maximum(d2 - d6, tiny))
    closest = edge((vc <= 0) & (d1 >= 0) & (d3 <= 0), a, ab, d1 / np.maximum(d1 - d3, tiny))
    closest = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, closest)
    closest = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, closest)
    closest = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, closest)
    return np.linalg.norm(p - closest, axis=-1)


def winding_number(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Generalised winding number [K] of a closed, outward-oriented triangle soup [F, 3, 3] at points [K, 3]."""
    a, b, c = (tri[None, :, k] - points[:, None, :] for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    det = np.einsum("kfi,kfi->kf", a, np.cross(b, c))
    div = la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la + (c * a).sum(-1) * lb
    return np.arctan2(det, div).sum(-1) / (2.0 * np.pi)  # Van Oosterom & Strackee solid angle / (4 pi)
