"""The family's cameras and the solid things they see: pinhole cameras, ray intersections with spheres, boxes and
the room around the rig, and the room's procedural texture. Its own code (not fluidnexus.camera), so that a
convention error in the project cannot cancel out against the same error here.

Cameras follow docs/conventions.md: OpenCV axes (x right, y down, z forward), world-to-camera [R | t], pixel
centres at (i + 0.5, j + 0.5); the PINF files get OpenGL camera-to-world matrices (``pinf_out``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

LIGHT = np.array([0.35, 0.85, 0.4]) / np.linalg.norm([0.35, 0.85, 0.4])
AMBIENT = 0.45


@dataclass(frozen=True)
class PinholeCamera:
    """``width`` x ``height`` pixels, focal length ``fx`` (= fy) in pixels, principal point at the image centre,
    ``w2c`` [4, 4] in OpenCV axes."""

    width: int
    height: int
    fx: float
    w2c: np.ndarray

    @classmethod
    def look_at(cls, width: int, height: int, fov_x_deg: float, eye, target, up=(0.0, 1.0, 0.0)):
        eye, target, up = (np.asarray(a, float) for a in (eye, target, up))
        z = target - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, up)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        w2c = np.eye(4)
        w2c[:3, :3] = np.stack([x, y, z])
        w2c[:3, 3] = -w2c[:3, :3] @ eye
        return cls(width, height, 0.5 * width / math.tan(math.radians(0.5 * fov_x_deg)), w2c)

    @property
    def center(self) -> np.ndarray:
        return -self.w2c[:3, :3].T @ self.w2c[:3, 3]

    @property
    def fov_x(self) -> float:
        """Horizontal field of view, radians."""
        return 2.0 * math.atan(0.5 * self.width / self.fx)

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(uv [N, 2] pixels, depth [N]) of world points [N, 3]."""
        cam = np.asarray(points, float) @ self.w2c[:3, :3].T + self.w2c[:3, 3]
        uv = self.fx * cam[:, :2] / cam[:, 2:3] + np.array([self.width / 2.0, self.height / 2.0])
        return uv, cam[:, 2]

    def rays(self) -> tuple[np.ndarray, np.ndarray]:
        """(origin [3], unit directions [H * W, 3]) through the pixel centres, row by row."""
        rows, cols = np.mgrid[0:self.height, 0:self.width]
        cam = np.stack([(cols.ravel() + 0.5 - self.width / 2.0) / self.fx,
                        (rows.ravel() + 0.5 - self.height / 2.0) / self.fx, np.ones(rows.size)], 1)
        d = cam @ self.w2c[:3, :3]  # R^T applied to each row
        return self.center, d / np.linalg.norm(d, axis=1, keepdims=True)


def hit_sphere(o, d, center, radius) -> tuple[np.ndarray, np.ndarray]:
    """(t [N], normals [N, 3]): nearest positive hit along the rays, inf where they miss."""
    oc = o - np.asarray(center)
    b = d @ oc
    disc = b * b - (oc @ oc - radius * radius)
    s = np.sqrt(np.maximum(disc, 0.0))
    t = np.where(-b - s > 0, -b - s, -b + s)
    t = np.where((disc > 0) & (t > 0), t, np.inf)
    n = (o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - center) / radius
    return t, n


def slab(o, d, lo, hi) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_enter, t_exit, enter axis) of the rays through the box (lo, hi); t_enter > t_exit where they miss."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(np.abs(d) < 1e-12, 1e-12, d)
        t1, t2 = (np.asarray(lo) - o) * inv, (np.asarray(hi) - o) * inv
    near, far = np.minimum(t1, t2), np.maximum(t1, t2)
    return near.max(1), far.min(1), near.argmax(1)


def hit_box(o, d, center, half) -> tuple[np.ndarray, np.ndarray]:
    """(t [N], normals [N, 3]) of rays hitting a box from outside; inf where they miss."""
    lo, hi = np.asarray(center) - half, np.asarray(center) + half
    t0, t1, axis = slab(o, d, lo, hi)
    t = np.where((t0 <= t1) & (t0 > 0), t0, np.inf)
    n = np.zeros((len(d), 3))
    n[np.arange(len(d)), axis] = -np.sign(d[np.arange(len(d)), axis])
    return t, n


def hit_room(o, d, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """(t [N], inward normals [N, 3]) where rays from inside the room meet its walls, floor or ceiling."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(np.abs(d) < 1e-12, 1e-12, d)
        far = np.maximum((np.asarray(lo) - o) * inv, (np.asarray(hi) - o) * inv)
    axis = far.argmin(1)
    n = np.zeros((len(d), 3))
    n[np.arange(len(d)), axis] = -np.sign(d[np.arange(len(d)), axis])
    return far.min(1), n


def value_noise(points: np.ndarray, seed: int, scale: float) -> np.ndarray:
    """[N] smooth noise in [0, 1] at world points: two octaves of a seeded 24^3 random lattice, trilinear,
    wrapped; ``scale`` metres per lattice cell of the first octave."""
    lattice = np.random.default_rng(seed).random((24, 24, 24))
    out = np.zeros(len(points))
    for weight, cell in ((0.65, scale), (0.35, scale / 2.3)):
        out += weight * ndimage.map_coordinates(lattice, (points / cell).T, order=1, mode="grid-wrap")
    return (out - 0.25) / 0.5  # the sum of two smoothed uniforms concentrates around 0.5


def shade(normals: np.ndarray) -> np.ndarray:
    """Lambert with a fixed light from above and an ambient term."""
    return AMBIENT + (1.0 - AMBIENT) * np.clip(normals @ LIGHT, 0.0, 1.0)


def surfaces(o, d, bodies, backdrop) -> tuple[np.ndarray, np.ndarray]:
    """(t [N], colour [N, 3]) of the first solid thing along each ray: a body (flat colour, shaded) or the room
    (textured); t = inf and the backdrop's plain colour where a ray meets neither."""
    n = len(d)
    t = np.full(n, np.inf)
    color = np.tile(np.asarray(backdrop.color, float), (n, 1))
    if backdrop.room is not None:
        t_room, normals = hit_room(o, d, *backdrop.room)
        p = o + t_room[:, None] * d
        a, b = (np.asarray(c, float) for c in backdrop.colors)
        tex = np.clip(value_noise(p, backdrop.texture_seed, backdrop.texture_scale), 0, 1)[:, None]
        t, color = t_room, (a + (b - a) * tex) * shade(normals)[:, None]
    for body in bodies:
        if body.kind == "sphere":
            tb, nb = hit_sphere(o, d, body.center, body.radius)
        else:
            tb, nb = hit_box(o, d, body.center, np.asarray(body.half))
        near = tb < t
        t = np.where(near, tb, t)
        color = np.where(near[:, None], np.asarray(body.color) * shade(nb)[:, None], color)
    return t, np.clip(color, 0.0, 1.0)
