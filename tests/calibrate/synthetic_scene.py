"""A synthetic textured scene with known cameras, rendered by ray casting in numpy (test-only).

The scene is a closed room (the inside faces of a large box) with a few solid boxes on its floor, every face
covered with multi-octave value noise, so SIFT finds many distinctive blobs and corners. Every face also gets a
constant brightness (a view-independent shade), which keeps box edges visible. Pixels are anti-aliased by
averaging ``supersample x supersample`` rays per pixel placed on a regular grid inside the pixel.

Conventions follow docs/conventions.md: world +y up in metres, OpenCV cameras, pixel centres at +0.5, images
[H, W, 3] float32 in [0, 1].
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluidnexus.camera import Camera

ROOM = (np.array([-5.0, 0.0, -5.0]), np.array([5.0, 4.0, 5.0]))
BOXES = (
    (np.array([-0.6, 0.0, -0.6]), np.array([0.4, 0.8, 0.3])),
    (np.array([0.5, 0.0, -0.3]), np.array([1.0, 1.3, 0.3])),
    (np.array([-1.3, 0.0, 0.4]), np.array([-0.8, 0.45, 0.9])),
    (np.array([-0.3, 0.8, -0.4]), np.array([0.1, 1.1, 0.0])),
)
# Value-noise octaves: (cells per metre, amplitude). A 4 cm cell spans a few pixels at 3 m with fx ~ 450 px.
OCTAVES = ((2.5, 0.35), (8.0, 0.35), (25.0, 0.3))
LATTICE = 256


@dataclass(frozen=True, eq=False)
class TexturedScene:
    """Room + boxes with a random value-noise texture per face.

    Attributes:
        lattice: [LATTICE, LATTICE] random values in [0, 1], shared by every face (tiled).
        face_offsets: [num_surfaces, 6, 2] lattice offsets that decorrelate the faces.
        face_shade: [num_surfaces, 6] constant brightness per face.
    """

    lattice: np.ndarray
    face_offsets: np.ndarray
    face_shade: np.ndarray

    @classmethod
    def random(cls, seed: int = 0) -> "TexturedScene":
        rng = np.random.default_rng(seed)
        n = 1 + len(BOXES)
        return cls(rng.random((LATTICE, LATTICE)), rng.uniform(0, LATTICE, (n, 6, 2)),
                   rng.uniform(0.55, 1.0, (n, 6)))

    @property
    def surfaces(self):
        """[(lo, hi, inside)]: the room (seen from inside) then the solid boxes."""
        return [(ROOM[0], ROOM[1], True)] + [(lo, hi, False) for lo, hi in BOXES]


def render(scene: TexturedScene, camera: Camera, supersample: int = 3) -> np.ndarray:
    """Ray-cast ``camera``'s image of ``scene``.

    Returns:
        [H, W, 3] float32 image in [0, 1].
    """
    h, w = camera.height, camera.width
    jj, ii = np.meshgrid(np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64), indexing="ij")
    acc = np.zeros((h, w))
    for sy in range(supersample):
        for sx in range(supersample):
            uv = np.stack([ii + (sx + 0.5) / supersample, jj + (sy + 0.5) / supersample], -1).reshape(-1, 2)
            acc += _shade_rays(scene, camera, uv).reshape(h, w)
    grey = (acc / supersample**2).astype(np.float32)
    tint = np.array([1.0, 0.95, 0.9], dtype=np.float32)
    return np.clip(grey[..., None] * tint, 0.0, 1.0)


def _shade_rays(scene: TexturedScene, camera: Camera, uv: np.ndarray) -> np.ndarray:
    """Brightness [N] of the first surface hit by the rays through pixel positions ``uv`` [N, 2]."""
    origin = camera.center
    dirs = np.concatenate([uv, np.ones((len(uv), 1))], 1) @ np.linalg.inv(camera.K).T @ camera.R
    best_t = np.full(len(uv), np.inf)
    best_surface = np.zeros(len(uv), dtype=np.int64)
    for k, (lo, hi, inside) in enumerate(scene.surfaces):
        t = _ray_box(origin, dirs, lo, hi, inside)
        closer = t < best_t
        best_t[closer] = t[closer]
        best_surface[closer] = k
    hit = origin + best_t[:, None] * dirs
    out = np.zeros(len(uv))
    for k, (lo, hi, _) in enumerate(scene.surfaces):
        sel = best_surface == k
        p = hit[sel]
        # The face is the box plane the hit point lies on: index = 2 * axis + (0 for lo, 1 for hi).
        dist = np.abs(np.concatenate([p - lo, p - hi], 1))[:, [0, 3, 1, 4, 2, 5]]
        face = np.argmin(dist, 1)
        axis = face // 2
        plane_uv = np.stack([p[np.arange(len(p)), (axis + 1) % 3], p[np.arange(len(p)), (axis + 2) % 3]], 1)
        out[sel] = scene.face_shade[k, face] * _value_noise(scene, plane_uv, scene.face_offsets[k, face])
    return out


def _ray_box(origin: np.ndarray, dirs: np.ndarray, lo: np.ndarray, hi: np.ndarray, inside: bool) -> np.ndarray:
    """Ray parameter [N] of the first hit with an axis-aligned box (its exit point if ``inside``); inf if none."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - origin) / dirs
        t1 = (hi - origin) / dirs
    t_near = np.nanmax(np.minimum(t0, t1), 1)
    t_far = np.nanmin(np.maximum(t0, t1), 1)
    t = t_far if inside else t_near
    valid = (t_near <= t_far) & (t > 1e-6)
    return np.where(valid, t, np.inf)


def _value_noise(scene: TexturedScene, plane_uv: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Multi-octave smooth value noise [N] at face coordinates ``plane_uv`` [N, 2] (metres)."""
    total = np.zeros(len(plane_uv))
    for octave, (freq, amp) in enumerate(OCTAVES):
        q = plane_uv * freq + offsets + 37.0 * octave
        cell = np.floor(q)
        f = q - cell
        f = f * f * (3.0 - 2.0 * f)  # smoothstep weights
        i0 = cell.astype(np.int64) % LATTICE
        i1 = (i0 + 1) % LATTICE
        lat = scene.lattice
        top = lat[i0[:, 0], i0[:, 1]] * (1 - f[:, 1]) + lat[i0[:, 0], i1[:, 1]] * f[:, 1]
        bottom = lat[i1[:, 0], i0[:, 1]] * (1 - f[:, 1]) + lat[i1[:, 0], i1[:, 1]] * f[:, 1]
        total += amp * (top * (1 - f[:, 0]) + bottom * f[:, 0])
    return total


def rig_cameras(num: int = 6, width: int = 480, height: int = 360, radius: float = 3.0, arc_deg: float = 100.0,
                height_m: float = 1.5, target=(0.0, 0.5, 0.0), focal_spread: float = 0.05) -> list[Camera]:
    """``num`` upright cameras on a horizontal arc around ``target`` (centred on +z), tilted down at it.

    Camera heights alternate by 0.1 m and focal lengths differ by ``focal_spread`` steps, both mirror-symmetric
    about the arc's middle, so the cameras' mean horizontal viewing direction is exactly -z.
    """
    cams = []
    for i, a in enumerate(np.radians(np.linspace(-arc_deg / 2, arc_deg / 2, num))):
        mirror_index = min(i, num - 1 - i)
        eye = (radius * np.sin(a), height_m + 0.1 * (mirror_index % 2), radius * np.cos(a))
        fx = 0.9 * width * (1.0 + focal_spread * (mirror_index % 3))
        cams.append(Camera.look_at(width, height, fx, eye, target))
    return cams


def surface_distance(points: np.ndarray) -> np.ndarray:
    """[N] distance (metres) from world points [N, 3] to the nearest surface of the scene (room or box)."""
    best = np.full(len(points), np.inf)
    for lo, hi in (ROOM,) + BOXES:
        q = np.abs(points - 0.5 * (lo + hi)) - 0.5 * (hi - lo)
        signed = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(1), 0.0)
        best = np.minimum(best, np.abs(signed))
    return best
