"""The source frame of an imported scene: how the scene's world relates to the world of the file it came from.

The rule (docs/conventions.md): ``scene.json`` is always in metres with +y up. A calibration file whose world has
another up axis or another length unit is converted once, at import, by one similarity transform

    x_scene = metres_per_unit * R @ x_source

(R a proper rotation, ``metres_per_unit`` > 0, no translation: the origin stays the source's origin). Cameras,
volume, source and obstacles are stored converted; the transform itself is kept as scene.json's ``source_frame``
record ``{"rotation": R (3x3, source axes to scene axes), "metres_per_unit": m}`` so that exports can be written
back in the source's own frame (``fluidnexus export --frame source``) and ``--to-pinf`` gives the file back.
A scene without the record is its own source frame (the identity).

Quantities convert by their dimension: positions and vectors (velocities) by ``m R``, lengths (radii, Gaussian
scales) by ``m``, orientations by ``R``, number densities (1/m^3) by ``m^-3``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .camera import Camera
from .errors import InputError, require_finite, require_positive

UP_AXES = {
    "Y": np.eye(3),
    # z up -> y up: (x, y, z) -> (x, z, -y), a rotation of -90 degrees about x (no mirror)
    "Z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}
"""Rotation taking a world with the named up axis into the project's +y-up world (PINF's ``rot`` values)."""


@dataclass(frozen=True, eq=False)
class SourceFrame:
    """``x_scene = metres_per_unit * rotation @ x_source``."""

    rotation: np.ndarray
    metres_per_unit: float = 1.0

    def __post_init__(self):
        R = np.array(self.rotation, dtype=np.float64)
        object.__setattr__(self, "rotation", R)
        if R.shape != (3, 3) or np.abs(R @ R.T - np.eye(3)).max() > 1e-9 or np.linalg.det(R) <= 0:
            raise InputError(None, "rotation", f"must be a proper 3x3 rotation, got {R.tolist()}")
        require_positive(self.metres_per_unit, None, "metres_per_unit")

    @classmethod
    def identity(cls) -> "SourceFrame":
        return cls(np.eye(3), 1.0)

    @classmethod
    def for_import(cls, up: str = "Y", metres_per_unit: float = 1.0) -> "SourceFrame":
        """The frame of a source whose up axis is ``up`` ("Y" or "Z") and whose unit is ``metres_per_unit`` m."""
        if up not in UP_AXES:
            raise InputError(None, "rot", f"unknown up axis {up!r}; expected one of {sorted(UP_AXES)}")
        return cls(UP_AXES[up], float(metres_per_unit))

    @property
    def is_identity(self) -> bool:
        return self.metres_per_unit == 1.0 and bool(np.array_equal(self.rotation, np.eye(3)))

    # ---- points, vectors, lengths --------------------------------------------------------------------------
    def to_scene(self, points) -> np.ndarray:
        """Source positions or vectors [..., 3] (units, units/s) -> scene (metres, m/s), float64."""
        if self.is_identity:
            return np.array(points, dtype=np.float64)
        return self.metres_per_unit * (np.asarray(points, dtype=np.float64) @ self.rotation.T)

    def from_scene(self, points) -> np.ndarray:
        """Inverse of :meth:`to_scene`."""
        if self.is_identity:
            return np.array(points, dtype=np.float64)
        return (np.asarray(points, dtype=np.float64) @ self.rotation) / self.metres_per_unit

    def length_to_scene(self, length):
        return np.asarray(length, dtype=np.float64) * self.metres_per_unit

    def length_from_scene(self, length):
        return np.asarray(length, dtype=np.float64) / self.metres_per_unit

    def density_from_scene(self, density) -> np.ndarray:
        """A number density (1/m^3) in 1/unit^3."""
        return np.asarray(density, dtype=np.float64) * self.metres_per_unit ** 3

    def quaternions_from_scene(self, q) -> np.ndarray:
        """Unit quaternions (w, x, y, z), body -> scene, as body -> source: ``conj(q_R) * q``."""
        return _quat_mul(_quat_conj(_quat_of(self.rotation)), np.asarray(q, dtype=np.float64))

    # ---- cameras ------------------------------------------------------------------------------------------
    def pose_to_scene(self, w2c) -> np.ndarray:
        """A 4x4 world-to-camera matrix of the source world -> of the scene world (camera space in metres)."""
        w2c = np.array(w2c, dtype=np.float64)
        if self.is_identity:
            return w2c
        out = np.eye(4)
        out[:3, :3] = w2c[:3, :3] @ self.rotation.T
        out[:3, 3] = self.metres_per_unit * w2c[:3, 3]
        return out

    def pose_from_scene(self, w2c) -> np.ndarray:
        """Inverse of :meth:`pose_to_scene`."""
        w2c = np.array(w2c, dtype=np.float64)
        if self.is_identity:
            return w2c
        out = np.eye(4)
        out[:3, :3] = w2c[:3, :3] @ self.rotation
        out[:3, 3] = w2c[:3, 3] / self.metres_per_unit
        return out

    def camera_to_scene(self, camera: Camera) -> Camera:
        return Camera(camera.width, camera.height, camera.K, self.pose_to_scene(camera.w2c))

    def camera_from_scene(self, camera: Camera) -> Camera:
        return Camera(camera.width, camera.height, camera.K, self.pose_from_scene(camera.w2c))

    def state_from_scene(self, state):
        """A :class:`~fluidnexus.state.FrameState` with positions, velocities, scales and rotations in the source
        frame (float32, as states are)."""
        if self.is_identity:
            return state
        f32 = np.float32
        return replace(state,
                       physical_positions=self.from_scene(state.physical_positions).astype(f32),
                       physical_velocities=self.from_scene(state.physical_velocities).astype(f32),
                       visual_positions=self.from_scene(state.visual_positions).astype(f32),
                       visual_scales=self.length_from_scene(state.visual_scales).astype(f32),
                       visual_rotations=self.quaternions_from_scene(state.visual_rotations).astype(f32))

    # ---- scene.json ---------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"rotation": self.rotation.tolist(), "metres_per_unit": self.metres_per_unit}

    @classmethod
    def from_dict(cls, data, path=None, fld: str = "source_frame") -> "SourceFrame":
        """Parse scene.json's ``source_frame`` record; errors name ``path`` and ``fld``."""
        if not isinstance(data, dict) or "rotation" not in data or "metres_per_unit" not in data:
            raise InputError(path, fld, "expected {rotation: 3x3, metres_per_unit: m}")
        R = require_finite(data["rotation"], path, f"{fld}.rotation")
        scale = require_positive(data["metres_per_unit"], path, f"{fld}.metres_per_unit")
        try:
            return cls(R, scale)
        except InputError as err:
            raise err.at(path, fld) from None


def _quat_of(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a proper rotation matrix (the largest-component branch, stable for every angle)."""
    m = R
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = np.zeros(4)
        q[0] = (m[k, j] - m[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + k] = (m[k, i] + m[i, k]) / s
    return np.asarray(q, dtype=np.float64)


def _quat_conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of (w, x, y, z) quaternions; ``b`` may be [N, 4]."""
    aw, ax, ay, az = a
    bw, bx, by, bz = np.moveaxis(np.asarray(b), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)
