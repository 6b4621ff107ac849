"""Seeds for what the stereo cannot place: the part of the volume that no view sees through (the static layer's
volume seeds, docs/static-layer.md).

A surface without texture (PINF Sphere's uniformly coloured ball) matches itself at every depth inside it, so
plane-sweep stereo confirms no depth there; its seeds come from carving instead (the visual hull, Laurentini
1994, with the stereo's depths). A node of a lattice over the volume is kept when

1. at least ``views_needed`` views (three; both where there are two) see it, each on a plate pixel of confidence
   at least ``min_confidence``. Two silhouettes bound a plain region only to the prism where their cones cross:
   over a photographed wall, a patch of pure black that only two views see (a plain colour has no stereo depth)
   filled that prism 0.3 m in front of the wall, the fit drew it as a dark body in front of the wall, and the
   obstacle finder made solids of it (BENCHMARKS.md, "A plain patch seen by two views");
2. every view that sees it shows something there: a pixel further than ``plain`` from the background colour
   (the silhouettes of objects over a plain backdrop);
3. no view sees past it to a surface: where a view's stereo depth is confirmed at the node's pixel, that surface
   lies no more than ``tolerance`` lattice spacings behind the node when its point lies outside the volume, and
   no more than ``inner_tolerance`` spacings when it lies inside. In front of a textured wall every node is carved
   away (without that test a textured backdrop, which is "something" in every pixel, would fill the whole
   volume), and so is the space above textured stairs or a floor inside the volume (PINF Game: with inner depths
   not carving, 8,421 of the lattice's 13,824 nodes were kept and veiled the stairs from the held-out camera).
   Inside the volume the tolerance is wider: on a surface with little texture the sweep's depth can lie a pixel
   of disparity deep, and a tight tolerance would carve the object's own hull.

Each node kept takes the mean colour of the views that see it.
"""
from __future__ import annotations

import numpy as np

from ..scene_scale import box_size
from .stereo import DepthMap, sample


def hull_points(views: list[DepthMap], lo, hi, background: np.ndarray, lattice: int = 24, plain: float = 0.03,
                tolerance: float = 1.0, min_confidence: float = 0.5, inner_tolerance: float = 3.0,
                views_needed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(points [K, 3], colours [K, C]): the lattice nodes (``lattice`` along the volume's size, cube root of its
    box volume) that the views do not see through (module docstring); ``views`` at the stereo's working size."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    spacing = box_size(hi - lo) / lattice
    axes = [np.arange(lo[k] + 0.5 * spacing, hi[k], spacing) for k in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    seen = np.zeros(len(nodes), int)
    kept = np.ones(len(nodes), bool)
    total = np.zeros((len(nodes), views[0].plate.shape[-1]))
    for view in views:
        cam = view.camera
        uv, z = cam.project(nodes)
        colour, inside = sample(view.plate, uv)
        conf, _ = sample(view.confidence[..., None], uv)
        sees = inside & (z > 0) & (conf[:, 0] >= min_confidence)
        shows = np.abs(colour - background).max(axis=-1) > plain
        px = np.clip(np.floor(np.nan_to_num(uv)).astype(int), 0, [cam.width - 1, cam.height - 1])
        surface = view.depth[px[:, 1], px[:, 0]]
        past = np.isfinite(surface) & (surface > z + tolerance * spacing)
        inner = in_box(cam.unproject(uv[past], surface[past]), lo, hi)
        past[past] = ~inner | (surface[past] > z[past] + inner_tolerance * spacing)
        kept &= ~sees | (shows & ~past)
        seen += sees
        total += np.where(sees[:, None], colour, 0.0)
    kept &= seen >= max(2, min(views_needed, len(views)))
    return nodes[kept], (total / np.maximum(seen, 1)[:, None])[kept]


def in_box(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """[N] bool: ``points`` [N, 3] inside the box ``lo``..``hi``."""
    return np.all((points >= lo) & (points <= hi), axis=1)
