"""Obstacles found in the footage: opaque static content inside the scene volume, from the static layer
(docs/static-layer.md).

1. **Surfaces**: each view renders the static layer's Gaussians inside the volume (``layer.render_static``) with
   their depth; pixels whose alpha is at least ``opaque`` and whose colour differs from the layer's background
   colour by more than ``plain`` give a surface point at the expected depth (depth / alpha).
2. **Carving** (space carving by depth): a voxel of a grid over the volume is free when some view sees past it:
   nothing inside the volume is opaque at its pixel (or it shows the layer's background colour), or the surface
   there lies more than ``tolerance`` voxels behind the voxel. What no view sees past, and at least one view sees, is occupied.
3. **Bodies**: connected occupied parts holding at least ``min_points`` surface points are obstacles (the
   backdrop lies outside the volume and carves nothing). Each gets a signed-distance grid (negative inside, the
   format of ``engine.obstacle.GridObstacle``) and a least-squares sphere fitted to its surface points; a body
   whose surface points lie within ``sphere_rms`` of the sphere (relative to its radius) is sphere-like, and its
   engine body is that ball (the carved part also holds what no camera sees behind the ball, e.g. under it when
   every camera looks down).

4. **Balls from silhouettes**: a body whose silhouettes (the matte of the layer's Gaussians inside the volume in
   each training view) outline one ball (the rays through the outlines graze it, ``silhouettes``) becomes that
   ball, which the layer's surface depths only approximate; parts of it found separately are dropped
   (:func:`refine_balls`).

Declared obstacles (scene.json ``obstacles``) win: a found body that overlaps a declared one is dropped
(:func:`merge_with_declared`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..scene_scale import box_size
from .silhouettes import fit_ball_to_rays, silhouette_rays
from .static_layer import StaticLayer, inside_volume, render_static


@dataclass(frozen=True)
class FinderConfig:
    resolution: int = 48  # voxels along the volume's size (cube root of its volume)
    opaque: float = 0.95
    plain: float = 0.03  # a pixel within this of the background colour shows nothing
    tolerance: float = 1.5  # voxels
    min_points: int = 30
    sphere_rms: float = 0.08


@dataclass(frozen=True, eq=False)
class FoundObstacle:
    """One obstacle found in the footage.

    Attributes:
        phi: [nx, ny, nz] signed distance, metres (negative inside), at ``origin + spacing * index``.
        origin, spacing: the grid (metres).
        points: [K, 3] the body's surface points seen by the views (metres).
        center, radius: the least-squares sphere through ``points``; ``rms`` its residual (metres).
        volume: the occupied volume, m^3.
    """

    phi: np.ndarray
    origin: tuple[float, float, float]
    spacing: float
    points: np.ndarray
    center: tuple[float, float, float]
    radius: float
    rms: float
    volume: float

    def sphere_like(self, tolerance: float = FinderConfig.sphere_rms) -> bool:
        return self.rms <= tolerance * self.radius

    def engine_body(self, tolerance: float = FinderConfig.sphere_rms):
        """The engine's one-way coupling body: the fitted ball when sphere-like, else the carved grid."""
        from ..engine.obstacle import GridObstacle, SphereObstacle

        if self.sphere_like(tolerance):
            return SphereObstacle(self.center, self.radius)
        return GridObstacle(self.phi, self.origin, self.spacing)

    def to_dict(self) -> dict:
        return {"center": [round(float(v), 6) for v in self.center], "radius": round(self.radius, 6),
                "rms": round(self.rms, 6), "volume": round(self.volume, 9), "points": int(len(self.points)),
                "sphere_like": self.sphere_like()}


def fit_sphere(points: np.ndarray, rounds: int = 5) -> tuple[np.ndarray, float, float]:
    """Least-squares sphere through ``points`` [K, 3]: the algebraic fit |x|^2 = 2 c.x + d, refitted ``rounds``
    times on the points whose radial residual is within 2.5 times the median residual (stray Gaussians in front
    of a body do not pull it). Returns (centre, radius, rms of the radial residual over the points kept)."""
    p = np.asarray(points, np.float64)
    keep = np.ones(len(p), bool)
    for _ in range(rounds):
        q = p[keep]
        a = np.concatenate([2 * q, np.ones((len(q), 1))], axis=1)
        sol, *_ = np.linalg.lstsq(a, (q ** 2).sum(axis=1), rcond=None)
        center = sol[:3]
        radius = float(np.sqrt(max(sol[3] + center @ center, 0.0)))
        resid = np.abs(np.linalg.norm(p - center, axis=1) - radius)
        new = resid <= 2.5 * np.median(resid) + 1e-12
        if new.sum() < 4 or np.array_equal(new, keep):
            break
        keep = new
    rms = float(np.sqrt(np.mean(resid[keep] ** 2)))
    return center, radius, rms


def surface_points(layer: StaticLayer, cameras, opaque: float = FinderConfig.opaque,
                   plain: float = FinderConfig.plain):
    """Per view: (alpha [H, W], expected depth [H, W] (inf where not opaque), world points [K, 3] of the opaque
    pixels) of the layer's Gaussians inside its volume, drawn alone (a backdrop behind would pull the expected
    depth of a pixel that is not quite opaque). A pixel is opaque when its alpha is at least ``opaque`` and its
    colour differs from the layer's background colour by more than ``plain``."""
    out = []
    inner = inside_volume(layer)
    for camera in cameras:
        image, alpha, depth = render_static(inner, camera, return_depth=True)
        alpha, depth = alpha.double().numpy(), depth.double().numpy()
        # Gaussians that show the background colour are indistinguishable from none (e.g. over a white backdrop)
        shown = np.abs(image.double().numpy() - layer.background).max(axis=-1) > plain
        solid = (alpha >= opaque) & shown
        z = np.where(solid, depth / np.maximum(alpha, 1e-12), np.inf)
        rows, cols = np.nonzero(solid)
        uv = np.stack([cols + 0.5, rows + 0.5], axis=1)
        out.append((alpha, z, camera.unproject(uv, z[rows, cols]) if len(rows) else np.zeros((0, 3))))
    return out


def find_obstacles(layer: StaticLayer, cameras, lo, hi, cfg: FinderConfig = FinderConfig()) -> list[FoundObstacle]:
    """The obstacles inside the volume ``lo``..``hi`` (metres) that the static layer shows to ``cameras``,
    largest first (module docstring)."""
    from scipy import ndimage

    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    spacing = box_size(hi - lo) / cfg.resolution
    res = np.maximum(np.ceil((hi - lo) / spacing).astype(int), 2)
    axes = [lo[k] + (np.arange(res[k]) + 0.5) * spacing for k in range(3)]
    centers = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    carved = np.zeros(len(centers), bool)
    seen = np.zeros(len(centers), bool)
    views = surface_points(layer, cameras, cfg.opaque, cfg.plain)
    for camera, (_, z, _) in zip(cameras, views):
        uv, depth = camera.project(centers)
        col, row = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
        inside = (depth > 0) & (col >= 0) & (col < camera.width) & (row >= 0) & (row < camera.height)
        surface = np.full(len(centers), -np.inf)
        surface[inside] = z[row[inside], col[inside]]
        seen |= inside
        carved |= inside & (depth < surface - cfg.tolerance * spacing)
    occupied = (seen & ~carved).reshape(tuple(res))
    points = np.concatenate([v[2] for v in views])
    points = points[np.all((points >= lo) & (points <= hi), axis=1)]
    labels, count = ndimage.label(occupied)
    found = []
    if count == 0 or len(points) == 0:
        return found
    idx = np.clip(np.floor((points - lo) / spacing).astype(int), 0, res - 1)
    # a surface point sits on its body's boundary: take the label of any occupied voxel within one voxel
    near = ndimage.grey_dilation(labels, size=(3, 3, 3))
    point_label = near[idx[:, 0], idx[:, 1], idx[:, 2]]
    for label in range(1, count + 1):
        mine = points[point_label == label]
        if len(mine) < cfg.min_points:
            continue
        body = labels == label
        center, radius, rms = fit_sphere(mine)
        found.append(FoundObstacle(_signed_distance(body, spacing), tuple(float(v) for v in lo - 0.5 * spacing),
                                   float(spacing), mine, tuple(float(v) for v in center), radius, rms,
                                   float(body.sum()) * spacing ** 3))
    return sorted(found, key=lambda f: -f.volume)


def refine_balls(found: list[FoundObstacle], layer: StaticLayer, cameras,
                 cfg: FinderConfig = FinderConfig()) -> list[FoundObstacle]:
    """``found`` with every body that the layer's silhouettes show as a ball refitted to them: in each of
    ``cameras`` the object mask is the matte of the layer's Gaussians inside its volume (drawn alone, alpha at least
    0.5); where the rays through the outlines around the body's projected centre graze one ball within
    ``cfg.sphere_rms`` of its radius (rms), the body becomes that ball (its ``rms`` the silhouettes' residual, so it
    is sphere-like); other bodies keep the layer's sphere and grid. Bodies whose centre lies inside an earlier
    (larger) refitted ball are parts of it and are dropped."""
    inner = inside_volume(layer)
    mattes = [render_static(inner, cam)[1].numpy() >= 0.5 for cam in cameras]
    out = []
    for body in found:
        if any(b.sphere_like(cfg.sphere_rms) and np.linalg.norm(np.subtract(body.center, b.center)) < b.radius
               for b in out):
            continue
        rays = [silhouette_rays(cam, matte, np.asarray(body.center), body.radius)
                for cam, matte in zip(cameras, mattes)]
        origins = np.concatenate([r[0] for r in rays])
        if len(origins) >= cfg.min_points:
            center, radius, rms = fit_ball_to_rays(origins, np.concatenate([r[1] for r in rays]),
                                                   np.asarray(body.center), body.radius)
            if rms <= cfg.sphere_rms * radius:
                body = replace(body, center=tuple(float(v) for v in center), radius=radius, rms=rms)
        out.append(body)
    return out


def _signed_distance(body: np.ndarray, spacing: float) -> np.ndarray:
    """Signed distance (metres, negative inside) of a voxel set, sampled at the voxel centres of its grid padded by
    one free voxel on every side (the first padded centre lies at ``lo - 0.5 spacing``)."""
    from scipy import ndimage

    padded = np.pad(body, 1)
    outside = ndimage.distance_transform_edt(~padded)
    inside = ndimage.distance_transform_edt(padded)
    return np.where(padded, -(inside - 0.5), outside - 0.5) * spacing


def merge_with_declared(found: list[FoundObstacle], declared) -> list[FoundObstacle]:
    """The found obstacles that do not touch a declared one (``declared``: the engine body of scene.json's
    ``obstacles``, or None): a found body with a surface point within two voxels of a declared body is dropped,
    since where the user declared a body, theirs wins."""
    if declared is None:
        return list(found)
    keep = []
    for body in found:
        if np.any(declared.distance(body.points) < 2 * body.spacing):
            continue
        keep.append(body)
    return keep
