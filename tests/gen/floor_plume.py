"""A tiny phone video of a plume standing on a floor, filmed by a camera at a known height and tilt.

The plume is an emission-only column of smoke (a disk of radius ``RADIUS`` across, its edge softened over ``EDGE``,
the top rising frame by frame) whose foot stands on the floor y = 0 at ``FOOT``. It is ray-marched with numpy from
its own pinhole rays (not ``fluidnexus.camera``) in the frame of the arc rig on a floor (docs/calibration.md): the
camera at ``(0, HEIGHT, HEIGHT / tan(TILT))``, pitched down by ``TILT`` towards -z, its centre ray meeting the floor
at the origin.
"""
from __future__ import annotations

import math

import numpy as np

WIDTH, HEIGHT_PX, FOV_DEG = 96, 128, 50.0
HEIGHT, TILT_DEG = 0.6, 30.0  # the camera's height above the floor (m) and its pitch down (degrees)
FOOT = np.array([0.07, 0.0, -0.09])  # the plume's foot on the floor: off the centre ray's floor point both ways
RADIUS, EDGE = 0.03, 0.006  # the column's radius and the width of its soft edge, m
FRAMES = 6
RISE = 0.06  # m per frame: the top of the smoke in frame t is RISE * t (frame 0 is empty)


def density(points: np.ndarray, frame: int) -> np.ndarray:
    """The smoke's density at ``points`` [..., 3] in ``frame``."""
    r2 = (points[..., 0] - FOOT[0]) ** 2 + (points[..., 2] - FOOT[2]) ** 2
    y = points[..., 1]
    return np.clip((RADIUS - np.sqrt(r2)) / EDGE + 0.5, 0.0, 1.0) * ((y >= 0) & (y <= RISE * frame))


def camera_rays(width: int = WIDTH, height: int = HEIGHT_PX, fov_deg: float = FOV_DEG, cam_height: float = HEIGHT,
                tilt_deg: float = TILT_DEG, azimuth_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Origin [3] and unit directions [H, W, 3] of a camera on the rig's circle at ``azimuth_deg`` (from +z towards
    +x), pitched down by ``tilt_deg``, looking at the origin."""
    f = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    t, a = math.radians(tilt_deg), math.radians(azimuth_deg)
    horizontal = np.array([-math.sin(a), 0.0, -math.cos(a)])  # towards the axis
    forward = math.cos(t) * horizontal + np.array([0.0, -math.sin(t), 0.0])
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    d = forward + ((u - width / 2) / f)[..., None] * right + ((v - height / 2) / f)[..., None] * down
    origin = -cam_height / math.tan(t) * horizontal + np.array([0.0, cam_height, 0.0])
    return origin, d / np.linalg.norm(d, axis=-1, keepdims=True)


def render(origin: np.ndarray, rays: np.ndarray, frames: int = FRAMES, gain: float = 4.0) -> np.ndarray:
    """[frames, H, W, 1] emission-only images: ``gain`` times the line integral of the density (metres)."""
    reach = float(np.linalg.norm(origin - FOOT))
    steps = np.linspace(reach - 0.4, reach + 0.4, 400)
    ds = steps[1] - steps[0]
    out = np.zeros((frames,) + rays.shape[:2] + (1,), np.float32)
    for k in range(frames):
        for s in steps:
            out[k, ..., 0] += density(origin + s * rays, k)
    return np.clip(out * ds * gain, 0.0, 1.0)
