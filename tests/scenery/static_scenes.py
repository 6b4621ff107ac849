"""A small static test scene, ray cast in numpy: a textured backdrop plane behind a 1 m volume and a shaded red
ball inside it, seen by cameras on a horizontal arc (world +y up, metres)."""
from __future__ import annotations

import numpy as np

from fluidnexus.camera import Camera

LO, HI = (-0.5, 0.0, -0.5), (0.5, 1.0, 0.5)
BALL_CENTER, BALL_RADIUS = np.array([0.06, 0.48, -0.04]), 0.2
BACKDROP_Z = -1.0
TARGET = np.array([0.0, 0.5, 0.0])


def camera(azimuth_deg: float, size: int = 64, distance: float = 2.6) -> Camera:
    a = np.radians(azimuth_deg)
    eye = TARGET + distance * np.array([np.sin(a), 0.12, np.cos(a)])
    return Camera.look_at(size, size, 1.1 * size, eye, TARGET)


def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """[K, 3] colours of the backdrop at plane coordinates (x, y): three waves in different directions and
    wavelengths per channel (no period shared by all, so no two places look alike)."""
    def waves(*terms):
        return sum(a * np.sin(fx * x + fy * y + p) for a, fx, fy, p in terms)

    r = 0.5 + waves((0.25, 7.1, 2.3, 0.3), (0.15, -3.2, 9.7, 1.1))
    g = 0.45 + waves((0.2, 4.3, -6.1, 2.0), (0.12, 11.3, 1.7, 0.4))
    b = 0.5 + waves((0.22, -8.9, -3.1, 0.9), (0.15, 2.9, 5.3, 2.6))
    return np.stack([r, g, b], axis=1).clip(0, 1)


def floor_mask(cam: Camera) -> np.ndarray:
    """[H, W] bool: the pixels whose ray meets the floor (y = 0) before the backdrop plane."""
    rows, cols = np.mgrid[0:cam.height, 0:cam.width]
    d = cam.unproject(np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=1), 1.0) - cam.center
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = (LO[1] - cam.center[1]) / d[:, 1]
        t_plane = (BACKDROP_Z - cam.center[2]) / d[:, 2]
    return ((t_floor > 0) & ((t_floor < t_plane) | (t_plane <= 0))).reshape(cam.height, cam.width)


def ball_mask(cam) -> np.ndarray:
    """[H, W] bool: the pixels whose ray hits the scene's ball."""
    rows, cols = np.mgrid[0:cam.height, 0:cam.width]
    d = cam.unproject(np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=1), 1.0) - cam.center
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    oc = cam.center - BALL_CENTER
    b = d @ oc
    return ((b ** 2 - (oc @ oc - BALL_RADIUS ** 2) > 0) & (b < 0)).reshape(cam.height, cam.width)


def render(cam: Camera, floor: bool = False) -> np.ndarray:
    """[H, W, 3] image of the scene seen by ``cam`` (one ray per pixel centre); with ``floor``, a textured floor
    at the volume's bottom face (y = 0) in front of the backdrop plane."""
    rows, cols = np.mgrid[0:cam.height, 0:cam.width]
    uv = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=1)
    origin = cam.center
    d = cam.unproject(uv, 1.0) - origin
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    image = np.full((len(d), 3), 0.9)
    t_plane = (BACKDROP_Z - origin[2]) / d[:, 2]
    hit = t_plane > 0
    p = origin + t_plane[:, None] * d
    image[hit] = texture(p[hit, 0], p[hit, 1])
    if floor:
        on = floor_mask(cam).ravel()
        q = origin + ((LO[1] - origin[1]) / d[on, 1])[:, None] * d[on]
        image[on] = texture(0.3 * q[:, 0] + 2.0, 0.3 * q[:, 2] + 5.0)  # coarser than the wall
    oc = origin - BALL_CENTER
    b = d @ oc
    disc = b ** 2 - (oc @ oc - BALL_RADIUS ** 2)
    ball = disc > 0
    t_ball = -b - np.sqrt(np.maximum(disc, 0))
    ball &= t_ball > 0
    n = (origin + t_ball[:, None] * d - BALL_CENTER) / BALL_RADIUS
    light = np.array([0.4, 0.8, 0.45]) / np.linalg.norm([0.4, 0.8, 0.45])
    shade = 0.45 + 0.55 * np.clip(n @ light, 0, 1)
    image[ball] = shade[ball, None] * np.array([0.9, 0.15, 0.1])
    return image.reshape(cam.height, cam.width, 3).astype(np.float32)
