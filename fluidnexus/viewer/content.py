"""What the viewer draws, as plain arrays (no viser here): Gaussian splats of a frame, physical particles coloured
by speed, camera frusta, the source disk and the volume's box. World metres, +y up (docs/conventions.md)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Camera

# role of a camera in the viewer -> RGB 0..255 of its frustum
ROLE_COLORS = {"input": (40, 200, 90), "synthesised": (255, 160, 30), "held-out": (230, 60, 60)}
# speed colour map: blue (still) -> cyan -> yellow -> red (the fastest shown)
SPEED_STOPS = np.array([[30, 60, 220], [0, 200, 230], [250, 220, 40], [230, 40, 30]], np.float64)


@dataclass(frozen=True)
class Splats:
    """Gaussians as a splat renderer takes them: centres [N, 3] m, covariances [N, 3, 3] m^2, rgb [N, 3] and
    opacities [N, 1] in [0, 1]."""

    centers: np.ndarray
    covariances: np.ndarray
    rgbs: np.ndarray
    opacities: np.ndarray

    def __len__(self) -> int:
        return int(self.centers.shape[0])

    def moved(self, offset) -> "Splats":
        return Splats(self.centers + np.asarray(offset, np.float32), self.covariances, self.rgbs, self.opacities)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """[N, 4] unit quaternions (w, x, y, z) -> [N, 3, 3] rotation matrices (body to world), in q's float type."""
    q = np.asarray(q)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """A [3, 3] rotation matrix -> its unit quaternion (w, x, y, z) with w >= 0."""
    R = np.asarray(R, np.float64)
    # the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2 gives a well-conditioned square root
    trace = np.trace(R)
    cands = np.array([trace, R[0, 0] - R[1, 1] - R[2, 2], R[1, 1] - R[0, 0] - R[2, 2], R[2, 2] - R[0, 0] - R[1, 1]])
    i = int(np.argmax(cands))
    s = 2.0 * np.sqrt(max(1.0 + cands[i], 1e-300))
    if i == 0:
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif i == 1:
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif i == 2:
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.asarray(q)
    return q if q[0] >= 0 else -q


def gaussian_splats(positions, colors, scales, rotations, opacities) -> Splats:
    """Splats of Gaussians given as in a ``FrameState``: covariance ``R diag(s^2) R^T``, gray colours repeated to
    RGB.

    Args:
        positions: [N, 3] centres, m. colors: [N, C] in [0, 1], C = 1 or 3. scales: [N, 3] standard deviations, m.
        rotations: [N, 4] quaternions (w, x, y, z), body to world. opacities: [N] in [0, 1].
    """
    M = quat_to_matrix(np.asarray(rotations, np.float32)) * np.asarray(scales, np.float32)[:, None, :]  # R diag(s)
    cov = M @ M.transpose(0, 2, 1)
    colors = np.asarray(colors, np.float32)
    rgbs = np.repeat(colors, 3, axis=1) if colors.shape[1] == 1 else colors
    return Splats(np.asarray(positions, np.float32), cov.astype(np.float32), np.clip(rgbs, 0, 1),
                  np.clip(np.asarray(opacities, np.float32), 0, 1)[:, None])


def state_splats(state) -> Splats:
    """The visual Gaussians of a ``FrameState``."""
    return gaussian_splats(state.visual_positions, state.visual_colors, state.visual_scales, state.visual_rotations,
                           state.visual_opacities)


def speed_colors(velocities: np.ndarray, top_speed: float) -> np.ndarray:
    """[N, 3] uint8 colours of particles by speed ``|u|``: blue at 0 through cyan and yellow to red at
    ``top_speed`` m/s and above."""
    speed = np.linalg.norm(np.asarray(velocities, np.float64), axis=1) / max(float(top_speed), 1e-12)
    at = np.clip(speed, 0.0, 1.0) * (len(SPEED_STOPS) - 1)
    stops = np.arange(len(SPEED_STOPS))
    rgb = np.stack([np.interp(at, stops, SPEED_STOPS[:, c]) for c in range(3)], axis=1)
    return np.round(rgb).astype(np.uint8)


@dataclass(frozen=True)
class FrustumPose:
    """A pinhole camera as a frustum: vertical field of view (radians), aspect (width / height), and the
    camera-to-world rotation (w, x, y, z) and position of its OpenCV axes (x right, y down, z forward)."""

    fov: float
    aspect: float
    wxyz: np.ndarray
    position: np.ndarray


def frustum_pose(camera: Camera) -> FrustumPose:
    c2w = camera.c2w
    fov = 2.0 * np.arctan(0.5 * camera.height / camera.K[1, 1])
    return FrustumPose(float(fov), camera.width / camera.height, matrix_to_quat(c2w[:3, :3]), c2w[:3, 3].copy())


def disk_mesh(center, radius: float, normal, segments: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """A flat disk (the smoke source) as a triangle fan: (vertices [S + 1, 3], faces [2 S, 3]), both sides."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 0, 1.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    rim = np.asarray(center) + radius * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)
    vertices = np.vstack([np.asarray(center, np.float64)[None], rim]).astype(np.float32)
    k = np.arange(segments)
    front = np.stack([np.zeros(segments, int), 1 + k, 1 + (k + 1) % segments], axis=1)
    return vertices, np.vstack([front, front[:, ::-1]]).astype(np.uint32)


def box_segments(lo, hi) -> np.ndarray:
    """The 12 edges of an axis-aligned box as line segments [12, 2, 3]."""
    corners = np.array([[hi[i] if (c >> i) & 1 else lo[i] for i in range(3)] for c in range(8)], np.float32)
    edges = [(a, a | (1 << i)) for a in range(8) for i in range(3) if not (a >> i) & 1]
    return np.stack([corners[[a, b]] for a, b in edges])
