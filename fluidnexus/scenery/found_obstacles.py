"""Obstacles found in the footage: opaque static content inside the scene volume, from the static layer
(docs/static-layer.md).

1. **Surfaces**: each view renders the static layer's Gaussians inside the volume (``layer.render_static``) with
   their depth; pixels whose alpha is at least ``opaque`` and whose colour differs from the layer's background
   colour by more than ``plain`` give a surface point at the expected depth (depth / alpha).
2. **Carving** (space carving by depth): a voxel of a grid over the volume is free when some view sees past it:
   nothing inside the volume is opaque at its pixel (or it shows the layer's background colour), or the surface
   there lies more than ``tolerance`` voxels behind the voxel. What no view sees past, and at least one view sees
   through a pixel its plate is sure of (confidence at least ``plates.CONFIDENT``), is occupied: where every view's
   plate is unsure the footage shows smoke there most of the time (a jet at its pipe), the layer's Gaussians are
   unconstrained, and their surface is not a body's. **Smoke is not a body**: a voxel that every view sees as smoke
   in one of the footage's frames (its visual hull against the plates) is free too, wherever the layer's surface
   lies. The depth tolerance leaves a band in front of every surface occupied, and faint Gaussians floating in
   front of a surface pull its expected depth further forward; smoke hugging the floor or the stairs lies there
   (on PINF's Game most of the smoke's hull inside the carved stairs lay within two voxels of its surface). The
   hull also holds the space right behind the smoke, so a body under dense smoke gets a dent as deep as the
   views' rays through the smoke reach into it.
3. **Bodies**: connected occupied parts holding at least ``min_points`` surface points, which at least ``views``
   sure views see (three, or both where there are two; the median over the part's voxels), are obstacles (the
   backdrop lies outside the volume and carves nothing). Two views bound a plain region only to the prism where
   their cones cross: over a photographed wall, the layer's Gaussians in front of a patch of pure black that two
   views see (the others look elsewhere) made five solids in an empty volume. Each gets a signed-distance grid
   (negative inside, the format of ``engine.obstacle.GridObstacle``) and a least-squares sphere fitted to its
   surface points; a body whose surface points lie within ``sphere_rms`` of the sphere (relative to its radius), and
   whose volume that sphere's matches (within ``ball_share``, :func:`ball_fits`), is sphere-like, and its engine
   body is that ball (the carved part also holds what no camera sees behind the ball, e.g. under it when every
   camera looks down). The volume's faces are not a body's surface: the grid continues the body beyond the faces it
   touches, so a point inside it is moved to the surface that faces the flow, never out of the volume.
4. **Kinds**: a body that covers at least ``boundary_contact`` of one of the volume's faces (a floor, stairs, a
   wall) is a **boundary**: the scene itself, which the gas slides along (its carved grid, whatever its shape); any
   other body is a **solid** in the flow, which the gas flows around (``FoundObstacle.gas``).

5. **Balls from silhouettes**: a body whose silhouettes (the matte of the layer's Gaussians inside the volume in
   each training view) outline one ball (the rays through the outlines graze it, ``silhouettes``) becomes that
   ball when its volume matches the body's (:func:`ball_fits`); the layer's surface depths only approximate it.
   Parts of it found separately are dropped (:func:`refine_balls`). A boundary is never refitted.

Declared obstacles (scene.json ``obstacles``) win: a found body that overlaps a declared one is dropped
(:func:`merge_with_declared`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..scene_scale import box_size
from .plates import CONFIDENT
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
    ball_share: tuple[float, float] = (0.125, 4.0)  # a ball's volume over its body's, for the ball to stand for it
    boundary_contact: float = 0.25  # share of one of the volume's faces a boundary covers
    views: int = 3  # sure views that must see a body (both where there are two)


BOUNDARY, SOLID = "boundary", "solid"
FACES = ("-x", "+x", "-y", "+y", "-z", "+z")


@dataclass(frozen=True, eq=False)
class FoundObstacle:
    """One obstacle found in the footage.

    Attributes:
        phi: [nx, ny, nz] signed distance, metres (negative inside), at ``origin + spacing * index``.
        origin, spacing: the grid (metres).
        points: [K, 3] the body's surface points seen by the views (metres).
        center, radius: the least-squares sphere through ``points``; ``rms`` its residual (metres).
        volume: the occupied volume, m^3.
        contact: the share of each of the volume's faces (``FACES``) the body covers, [6].
        kind: ``BOUNDARY`` (the scene: a floor, stairs, a wall) or ``SOLID`` (a body in the flow).
    """

    phi: np.ndarray
    origin: tuple[float, float, float]
    spacing: float
    points: np.ndarray
    center: tuple[float, float, float]
    radius: float
    rms: float
    volume: float
    contact: tuple[float, ...]
    kind: str

    def sphere_like(self, tolerance: float = FinderConfig.sphere_rms,
                    share: tuple[float, float] = FinderConfig.ball_share) -> bool:
        """A solid whose fitted ball lies within ``tolerance`` of its surface (rms, relative to the radius) and
        matches its volume (:func:`ball_fits`)."""
        return (self.kind == SOLID and self.rms <= tolerance * self.radius
                and ball_fits(self.radius, self.volume, share))

    def engine_body(self, tolerance: float = FinderConfig.sphere_rms):
        """The engine's one-way coupling body: the fitted ball when sphere-like, else the carved grid."""
        from ..engine.obstacle import GridObstacle, SphereObstacle

        if self.sphere_like(tolerance):
            return SphereObstacle(self.center, self.radius)
        return GridObstacle(self.phi, self.origin, self.spacing)

    def gas(self) -> str:
        """What the gas does with the body, in words."""
        if self.kind == BOUNDARY:
            faces = ", ".join(f for f, c in zip(FACES, self.contact) if c > 0)
            return (f"slides along it: a boundary of the scene (touches the volume's faces {faces}); a particle "
                    "entering it is moved back to the surface it faces, its tangential velocity kept, and no gas "
                    "is placed inside it")
        shape = f"the ball of radius {self.radius:.4g} m" if self.sphere_like() else "the carved body"
        return f"flows around {shape}: a solid in the flow; no gas is placed inside it"

    def to_dict(self) -> dict:
        return {"kind": self.kind, "center": [round(float(v), 6) for v in self.center],
                "radius": round(self.radius, 6), "rms": round(self.rms, 6), "volume": round(self.volume, 9),
                "points": int(len(self.points)), "sphere_like": self.sphere_like(),
                "faces": {f: round(c, 4) for f, c in zip(FACES, self.contact) if c > 0}, "gas": self.gas()}


def ball_fits(radius: float, volume: float, share: tuple[float, float] = FinderConfig.ball_share) -> bool:
    """Whether a ball of ``radius`` can stand for a carved body of ``volume``: its volume within ``share`` of the
    body's. No view sees into an opaque ball, so its carved body is about its size: less where the layer's surface
    depths lie behind the ball's surface or smoke carved a dent (a ball of the test scene's stairs, 4.8 voxels in
    radius, carved to half its volume), more by the depth tolerance's band and what no camera sees behind it. A
    sphere fitted to a flat patch of surface, or tangent to the rays that a few pixels of outline give, passes the
    residual test at any radius (on PINF's Game: balls of radius 3.4 m and 1.2 mm for bodies of 0.03 and 0.01
    m^3)."""
    ball = 4.0 / 3.0 * np.pi * radius ** 3
    return share[0] * volume <= ball <= share[1] * volume


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


def find_obstacles(layer: StaticLayer, cameras, lo, hi, cfg: FinderConfig = FinderConfig(),
                   confidences=None, smoke=()) -> list[FoundObstacle]:
    """The obstacles inside the volume ``lo``..``hi`` (metres) that the static layer shows to ``cameras``,
    largest first (module docstring).

    Args:
        confidences: per camera, its plate's confidence [H, W] at the camera's size (None: every pixel sure).
        smoke: per frame of footage, per camera, [H, W] bool: the pixels that show smoke (none: no footage).

    A single view finds nothing: what lies behind its surfaces is never carved, so every surface it shows would
    become a body reaching to the volume's far side (a single video's floor seeds made a "ball" 0.36 m across).
    A single video's obstacles are declared (scene.json ``obstacles``), or over a plain backdrop taken as balls
    at the plume's depth (``view_objects``, :func:`ball_obstacle`).
    """
    if len(cameras) < 2:
        return []
    from scipy import ndimage

    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    spacing = box_size(hi - lo) / cfg.resolution
    res = np.maximum(np.ceil((hi - lo) / spacing).astype(int), 2)
    axes = [lo[k] + (np.arange(res[k]) + 0.5) * spacing for k in range(3)]
    centers = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    carved = np.zeros(len(centers), bool)
    seen = np.zeros(len(centers), int)  # the sure views that see each voxel
    hulls = np.ones((len(smoke), len(centers)), bool)  # every view sees smoke there, per frame
    views = surface_points(layer, cameras, cfg.opaque, cfg.plain)
    confidences = [None] * len(cameras) if confidences is None else confidences
    for v, (camera, (_, z, _), confidence) in enumerate(zip(cameras, views, confidences)):
        uv, depth = camera.project(centers)
        col, row = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
        inside = (depth > 0) & (col >= 0) & (col < camera.width) & (row >= 0) & (row < camera.height)
        surface = np.full(len(centers), -np.inf)
        surface[inside] = z[row[inside], col[inside]]
        sure = inside.copy()
        if confidence is not None:
            sure[inside] = np.asarray(confidence)[row[inside], col[inside]] >= CONFIDENT
        seen += sure
        carved |= inside & (depth < surface - cfg.tolerance * spacing)
        for k, masks in enumerate(smoke):
            shows = np.zeros(len(centers), bool)
            shows[inside] = masks[v][row[inside], col[inside]]
            hulls[k] &= shows
    carved |= hulls.any(axis=0)
    occupied = ((seen > 0) & ~carved).reshape(tuple(res))
    views_seeing = seen.reshape(tuple(res))
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
        if np.median(views_seeing[body]) < min(cfg.views, len(cameras)):
            continue  # two views bound a plain region only to where their cones cross
        center, radius, rms = fit_sphere(mine)
        contact = face_contact(body)
        kind = BOUNDARY if max(contact) >= cfg.boundary_contact else SOLID
        found.append(FoundObstacle(signed_distance(body, spacing), tuple(float(v) for v in lo - 0.5 * spacing),
                                   float(spacing), mine, tuple(float(v) for v in center), radius, rms,
                                   float(body.sum()) * spacing ** 3, contact, kind))
    return sorted(found, key=lambda f: -f.volume)


def face_contact(body: np.ndarray) -> tuple[float, ...]:
    """The share of each face of the grid (``FACES``' order) that the voxel set ``body`` [nx, ny, nz] covers: the
    occupied share of the grid's outermost layer of voxels on that side."""
    out = []
    for axis in range(3):
        for end in (0, -1):
            out.append(float(np.take(body, end, axis=axis).mean()))
    return tuple(out)


def refine_balls(found: list[FoundObstacle], layer: StaticLayer, cameras,
                 cfg: FinderConfig = FinderConfig()) -> list[FoundObstacle]:
    """``found`` with every body that the layer's silhouettes show as a ball refitted to them: in each of
    ``cameras`` the object mask is the matte of the layer's Gaussians inside its volume (drawn alone, alpha at least
    0.5); where the rays through the outlines around the body's projected centre graze one ball within
    ``cfg.sphere_rms`` of its radius (rms) and matches the body's volume (:func:`ball_fits`), the body becomes that
    ball (its ``rms`` the silhouettes' residual, so it is sphere-like); other bodies keep the layer's sphere and
    grid. Bodies whose centre lies inside an earlier (larger) refitted ball are parts of it and are dropped."""
    inner = inside_volume(layer)
    mattes = [render_static(inner, cam)[1].numpy() >= 0.5 for cam in cameras]
    out = []
    for body in found:
        if body.kind == BOUNDARY:
            out.append(body)
            continue
        if any(b.sphere_like(cfg.sphere_rms, cfg.ball_share)
               and np.linalg.norm(np.subtract(body.center, b.center)) < b.radius for b in out):
            continue
        rays = [silhouette_rays(cam, matte, np.asarray(body.center), body.radius)
                for cam, matte in zip(cameras, mattes)]
        origins = np.concatenate([r[0] for r in rays])
        if len(origins) >= cfg.min_points:
            center, radius, rms = fit_ball_to_rays(origins, np.concatenate([r[1] for r in rays]),
                                                   np.asarray(body.center), body.radius)
            ball = replace(body, center=tuple(float(v) for v in center), radius=radius, rms=rms)
            if ball.sphere_like(cfg.sphere_rms, cfg.ball_share):
                body = ball
        out.append(body)
    return out


def signed_distance(body: np.ndarray, spacing: float) -> np.ndarray:
    """Signed distance (metres, negative inside) of a voxel set, sampled at the voxel centres of its grid padded by
    one voxel on every side (the first padded centre lies at ``lo - 0.5 spacing``). The padding continues the body
    beyond the grid's faces (the volume's faces are not its surface): the distance inside is to the surface that
    faces the free voxels."""
    from scipy import ndimage

    padded = np.pad(body, 1, mode="edge")
    outside = ndimage.distance_transform_edt(~padded)
    inside = ndimage.distance_transform_edt(padded)
    return np.where(padded, -(inside - 0.5), outside - 0.5) * spacing


def ball_obstacle(center, radius: float, lo, hi, cfg: FinderConfig = FinderConfig()) -> FoundObstacle:
    """A solid ball in the flow as a found obstacle (a single view's object, ``view_objects.object_balls``): its
    signed distance on the finder's voxel size, 200 surface points, sphere-like (rms 0), touching no face."""
    center = np.asarray(center, np.float64)
    spacing = box_size(np.subtract(hi, lo)) / cfg.resolution
    origin = center - radius - 2 * spacing
    n = int(np.ceil((2 * radius + 4 * spacing) / spacing)) + 1
    grid = origin + spacing * np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1)
    phi = np.linalg.norm(grid - center, axis=-1) - radius
    k = np.arange(200) + 0.5  # a Fibonacci sphere
    polar, azimuth = np.arccos(1 - 2 * k / 200), np.pi * (1 + 5 ** 0.5) * k
    points = center + radius * np.stack([np.sin(polar) * np.cos(azimuth), np.cos(polar),
                                         np.sin(polar) * np.sin(azimuth)], axis=1)
    return FoundObstacle(phi, tuple(float(v) for v in origin), float(spacing), points,
                         tuple(float(v) for v in center), float(radius), 0.0, 4 / 3 * np.pi * radius ** 3,
                         (0.0,) * len(FACES), SOLID)


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
