"""A small textured 3D scene ray cast in numpy: a floor and two steps that run through a 1 m volume's faces, a
textured wall behind them, a red ball in the flow and a blob of white smoke above the floor (world +y up, metres).
Used by the tests of found obstacles that are the scene itself."""
from __future__ import annotations

import numpy as np

from fluidnexus.camera import Camera

from .static_scenes import texture

LO, HI = (-0.5, 0.0, -0.5), (0.5, 1.0, 0.5)
# boxes (lo, hi): the floor's top at y = 0.1, two steps at the back; all run far beyond the volume
BOXES = (((-3.0, -0.5, -3.0), (3.0, 0.1, 3.0)),
         ((-3.0, -0.5, -3.0), (3.0, 0.3, -0.2)),
         ((-3.0, -0.5, -3.0), (3.0, 0.5, -0.35)))
WALL_Z = -0.9
BALL_CENTER, BALL_RADIUS = np.array([0.22, 0.62, 0.12]), 0.1
SMOKE_CENTER, SMOKE_SIGMA, SMOKE_DENSITY = np.array([-0.12, 0.2, 0.1]), 0.07, 40.0
TARGET = np.array([0.0, 0.35, 0.0])
LIGHT = np.array([0.4, 0.8, 0.45]) / np.linalg.norm([0.4, 0.8, 0.45])


def camera(azimuth_deg: float, size: int = 64, distance: float = 2.4, elevation_deg: float = 28.0) -> Camera:
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    eye = TARGET + distance * np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
    return Camera.look_at(size, size, 1.1 * size, eye, TARGET)


def in_body(points: np.ndarray) -> np.ndarray:
    """[K] bool: points inside a box or the ball."""
    p = np.asarray(points)
    inside = np.linalg.norm(p - BALL_CENTER, axis=1) < BALL_RADIUS
    for lo, hi in BOXES:
        inside |= np.all((p > lo) & (p < hi), axis=1)
    return inside


def smoke_density(points: np.ndarray, t: float = 0.0) -> np.ndarray:
    """The smoke's density at ``points`` [K, 3] at time ``t`` (frames): a Gaussian blob drifting along +x."""
    center = SMOKE_CENTER + np.array([0.02 * t, 0.0, 0.0])
    return SMOKE_DENSITY * np.exp(-0.5 * np.sum((points - center) ** 2, axis=-1) / SMOKE_SIGMA ** 2)


def _rays(cam: Camera):
    rows, cols = np.mgrid[0:cam.height, 0:cam.width]
    uv = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=1)
    d = cam.unproject(uv, 1.0) - cam.center
    return cam.center, d / np.linalg.norm(d, axis=1, keepdims=True)


def _scenery(origin: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(colour [K, 3], hit distance [K]) of the static scene along unit rays ``d`` from ``origin``."""
    far = np.full(len(d), np.inf)
    color = np.full((len(d), 3), 0.9)
    t_wall = (WALL_Z - origin[2]) / d[:, 2]
    wall = t_wall > 0
    p = origin + t_wall[:, None] * d
    far[wall] = t_wall[wall]
    color[wall] = 0.8 * texture(p[wall, 0], p[wall, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo, hi in BOXES:  # slab test; the face hit decides the texture's plane and the shading
            t0, t1 = (np.asarray(lo) - origin) / d, (np.asarray(hi) - origin) / d
            near, across = np.minimum(t0, t1), np.maximum(t0, t1)
            enter, leave = near.max(axis=1), across.min(axis=1)
            hit = (enter <= leave) & (enter > 0) & (enter < far)
            axis = near.argmax(axis=1)
            q = origin + enter[:, None] * d
            normal = np.zeros((len(d), 3))
            normal[np.arange(len(d)), axis] = -np.sign(d[np.arange(len(d)), axis])
            u = np.where(axis == 0, q[:, 2], q[:, 0])
            v = np.where(axis == 1, q[:, 2], q[:, 1])
            shade = 0.35 + 0.65 * np.clip(normal @ LIGHT, 0, 1)
            far[hit] = enter[hit]
            color[hit] = shade[hit, None] * texture(u[hit] + 1.7 * axis[hit], v[hit])
        oc = origin - BALL_CENTER
        b = d @ oc
        disc = b ** 2 - (oc @ oc - BALL_RADIUS ** 2)
        t_ball = -b - np.sqrt(np.maximum(disc, 0))
        ball = (disc > 0) & (t_ball > 0) & (t_ball < far)
        n = (origin + t_ball[:, None] * d - BALL_CENTER) / BALL_RADIUS
        far[ball] = t_ball[ball]
        color[ball] = (0.45 + 0.55 * np.clip(n[ball] @ LIGHT, 0, 1))[:, None] * np.array([0.9, 0.15, 0.1])
    return color, far


def render(cam: Camera, t: float | None = None) -> np.ndarray:
    """[H, W, 3] image of the scene seen by ``cam``: with the smoke at time ``t`` (frames) in front of what it
    covers, or without smoke (``t`` None)."""
    origin, d = _rays(cam)
    color, far = _scenery(origin, d)
    if t is not None:  # emission-absorption march through the blob, stopped at the scenery
        depth = np.linalg.norm(SMOKE_CENTER - origin)
        steps = np.linspace(depth - 4 * SMOKE_SIGMA, depth + 4 * SMOKE_SIGMA, 48)
        ds = steps[1] - steps[0]
        optical = np.zeros(len(d))
        for s in steps:
            sigma = smoke_density(origin + s * d, t)
            optical += np.where(s < far, sigma * ds, 0.0)
        alpha = 1.0 - np.exp(-optical)
        color = (1.0 - alpha)[:, None] * color + alpha[:, None] * 0.95
    return color.reshape(cam.height, cam.width, 3).astype(np.float32)
