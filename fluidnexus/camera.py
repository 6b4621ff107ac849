"""Pinhole cameras in the project's convention (see docs/conventions.md).

A :class:`Camera` is an undistorted pinhole camera: image size, intrinsics ``K`` and a 4x4 world-to-camera
matrix in OpenCV axes (x right, y down, z forward). Pixel coordinates are continuous with (0, 0) at the top-left
corner of the top-left pixel, so the centre of pixel (column i, row j) is (i + 0.5, j + 0.5), as in COLMAP.
With that convention a resolution change scales the first two rows of ``K`` exactly.

Other conventions (NeRF/PINF OpenGL camera-to-world, COLMAP/pycolmap) are converted here, at IO only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError, require_finite

# NeRF/OpenGL camera axes (x right, y up, z backward) <-> OpenCV camera axes (x right, y down, z forward).
GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])

ROTATION_TOL = 1e-4


@dataclass(frozen=True, eq=False)
class Camera:
    """An undistorted pinhole camera.

    Attributes:
        width, height: image size in pixels.
        K: [3, 3] float64 intrinsics (fx, fy, cx, cy in pixels; zero skew not required).
        w2c: [4, 4] float64 world-to-camera matrix in OpenCV axes; world units are metres.
    """

    width: int
    height: int
    K: np.ndarray
    w2c: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "K", np.array(self.K, dtype=np.float64))
        object.__setattr__(self, "w2c", np.array(self.w2c, dtype=np.float64))
        validate_camera(self)

    # ---- derived quantities -------------------------------------------------------------------------
    @property
    def R(self) -> np.ndarray:
        """[3, 3] world-to-camera rotation."""
        return self.w2c[:3, :3]

    @property
    def t(self) -> np.ndarray:
        """[3] world-to-camera translation."""
        return self.w2c[:3, 3]

    @property
    def c2w(self) -> np.ndarray:
        """[4, 4] camera-to-world matrix in OpenCV axes (the numerical inverse, so round trips are exact)."""
        return np.linalg.inv(self.w2c)

    @property
    def center(self) -> np.ndarray:
        """[3] camera centre in world coordinates (metres)."""
        return self.c2w[:3, 3]

    @property
    def forward(self) -> np.ndarray:
        """[3] unit viewing direction (camera +z) in world coordinates."""
        return self.R[2].copy()

    @property
    def fov_x(self) -> float:
        """Horizontal field of view in radians (for a centred principal point)."""
        return 2.0 * math.atan(0.5 * self.width / self.K[0, 0])

    # ---- geometry -----------------------------------------------------------------------------------
    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points to pixels.

        Args:
            points: [N, 3] world positions in metres.
        Returns:
            uv: [N, 2] pixel coordinates (u right, v down; pixel centres at +0.5).
            depth: [N] camera-space z in metres (<= 0 means behind the camera; uv is then meaningless).
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        cam = pts @ self.R.T + self.t
        depth = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            hom = cam @ self.K.T
            uv = hom[:, :2] / hom[:, 2:3]
        return uv, depth

    def unproject(self, uv: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Lift pixels at given camera-space depths back to world points.

        Args:
            uv: [N, 2] pixel coordinates.
            depth: [N] (or scalar) camera-space z in metres.
        Returns:
            [N, 3] world positions.
        """
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        depth = np.broadcast_to(np.asarray(depth, dtype=np.float64), (uv.shape[0],))
        hom = np.concatenate([uv, np.ones((uv.shape[0], 1))], axis=1)
        cam = (hom @ np.linalg.inv(self.K).T) * depth[:, None]
        return (cam - self.t) @ np.linalg.inv(self.R).T

    def scaled(self, factor: float) -> "Camera":
        """The same camera at another resolution.

        The new size is ``round(width * factor) x round(height * factor)``; K's first two rows are scaled by the
        exact per-axis ratios, so pixel corners map onto pixel corners.
        """
        if not (math.isfinite(factor) and factor > 0):
            raise InputError(None, "resolution", f"scale factor must be > 0, got {factor!r}")
        w, h = max(1, round(self.width * factor)), max(1, round(self.height * factor))
        return self.resized(w, h)

    def resized(self, width: int, height: int) -> "Camera":
        """The same camera rendered at ``width x height`` pixels (K scaled per axis)."""
        K = self.K.copy()
        K[0] *= width / self.width
        K[1] *= height / self.height
        K[2] = [0.0, 0.0, 1.0]
        return Camera(int(width), int(height), K, self.w2c)

    # ---- constructors from other conventions ---------------------------------------------------------
    @classmethod
    def look_at(cls, width: int, height: int, fx: float, eye, target, up=(0.0, 1.0, 0.0)) -> "Camera":
        """A camera at ``eye`` looking at ``target`` with world ``up`` pointing up in the image."""
        eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
        z = target - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, up)
        if np.linalg.norm(x) < 1e-9:
            raise InputError(None, "camera", "viewing direction is parallel to the up vector")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        w2c = np.eye(4)
        w2c[:3, :3] = np.stack([x, y, z])
        w2c[:3, 3] = -w2c[:3, :3] @ eye
        K = np.array([[fx, 0.0, width / 2.0], [0.0, fx, height / 2.0], [0.0, 0.0, 1.0]])
        return cls(int(width), int(height), K, w2c)

    @classmethod
    def from_nerf(cls, transform_matrix, width: int, height: int, camera_angle_x: float | None = None,
                  fl_x: float | None = None, fl_y: float | None = None,
                  cx: float | None = None, cy: float | None = None) -> "Camera":
        """From a NeRF/PINF frame: camera-to-world in OpenGL axes plus the horizontal FOV (radians).

        Explicit ``fl_x``/``fl_y``/``cx``/``cy`` (instant-ngp / nerfstudio keys) win over ``camera_angle_x``;
        the principal point defaults to the image centre.
        """
        c2w_gl = np.asarray(transform_matrix, dtype=np.float64)
        if c2w_gl.shape == (3, 4):
            c2w_gl = np.vstack([c2w_gl, [0.0, 0.0, 0.0, 1.0]])
        if c2w_gl.shape != (4, 4):
            raise InputError(None, "transform_matrix", f"expected 4x4, got shape {c2w_gl.shape}")
        if fl_x is None:
            if camera_angle_x is None:
                raise InputError(None, "camera_angle_x", "missing (and no fl_x given)")
            fl_x = 0.5 * width / math.tan(0.5 * float(camera_angle_x))
        fl_y = fl_x if fl_y is None else fl_y
        cx = width / 2.0 if cx is None else cx
        cy = height / 2.0 if cy is None else cy
        K = np.array([[fl_x, 0.0, cx], [0.0, fl_y, cy], [0.0, 0.0, 1.0]])
        c2w_cv = c2w_gl @ GL_TO_CV
        return cls(int(width), int(height), K, np.linalg.inv(c2w_cv))

    def to_nerf(self) -> dict:
        """NeRF/PINF fields: ``transform_matrix`` (OpenGL camera-to-world), ``camera_angle_x`` and the exact
        intrinsics as ``fl_x, fl_y, cx, cy, w, h`` (so a non-centred or non-square camera survives)."""
        return {
            "transform_matrix": (self.c2w @ GL_TO_CV).tolist(),
            "camera_angle_x": self.fov_x,
            "fl_x": float(self.K[0, 0]), "fl_y": float(self.K[1, 1]),
            "cx": float(self.K[0, 2]), "cy": float(self.K[1, 2]),
            "w": self.width, "h": self.height,
        }

    @classmethod
    def from_pycolmap(cls, camera, cam_from_world) -> "Camera":
        """From a ``pycolmap.Camera`` (a pinhole model without distortion) and its ``cam_from_world`` Rigid3d."""
        model = camera.model.name if hasattr(camera.model, "name") else str(camera.model)
        params = np.asarray(camera.params, dtype=np.float64)
        fx, fy, cx, cy = _colmap_pinhole(model, params)
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        w2c = np.eye(4)
        w2c[:3, :4] = np.asarray(cam_from_world.matrix(), dtype=np.float64)
        return cls(int(camera.width), int(camera.height), K, w2c)

    def to_pycolmap(self, camera_id: int = 1):
        """Return ``(pycolmap.Camera, pycolmap.Rigid3d)``: a PINHOLE camera and its cam_from_world pose."""
        import pycolmap

        if abs(self.K[0, 1]) > 0:
            raise InputError(None, "K", "COLMAP pinhole cameras have no skew")
        cam = pycolmap.Camera(model="PINHOLE", width=self.width, height=self.height,
                              params=[self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]],
                              camera_id=camera_id)
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(self.R), self.t)
        return cam, pose

    # ---- scene.json ---------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"width": self.width, "height": self.height, "K": self.K.tolist(),
                "world_to_camera": self.w2c.tolist()}

    @classmethod
    def from_dict(cls, data: dict, path=None, field: str = "camera") -> "Camera":
        """Parse a scene.json camera; errors name ``path`` and ``field``."""
        try:
            if not isinstance(data, dict):
                raise InputError(None, None, "expected an object")
            for key in ("width", "height", "K", "world_to_camera"):
                if key not in data:
                    raise InputError(None, key, "missing")
            K = require_finite(data["K"], None, "K")
            w2c = require_finite(data["world_to_camera"], None, "world_to_camera")
            if K.shape != (3, 3):
                raise InputError(None, "K", f"expected 3x3, got shape {K.shape}")
            if w2c.shape != (4, 4):
                raise InputError(None, "world_to_camera", f"expected 4x4, got shape {w2c.shape}")
            return cls(_int_field(data, "width"), _int_field(data, "height"), K, w2c)
        except InputError as err:
            raise err.at(path, field) from None


def _int_field(data: dict, key: str) -> int:
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
        raise InputError(None, key, f"expected an integer, got {value!r}")
    return int(value)


def _colmap_pinhole(model: str, params: np.ndarray) -> tuple[float, float, float, float]:
    """fx, fy, cx, cy of a COLMAP camera model; distortion must be zero (undistort first)."""
    if model == "PINHOLE":
        return tuple(params[:4])
    if model == "SIMPLE_PINHOLE":
        return params[0], params[0], params[1], params[2]
    single_focal = {"SIMPLE_RADIAL": 3, "RADIAL": 3}
    double_focal = {"OPENCV": 4, "FULL_OPENCV": 4}
    if model in single_focal and np.allclose(params[single_focal[model]:], 0):
        return params[0], params[0], params[1], params[2]
    if model in double_focal and np.allclose(params[double_focal[model]:], 0):
        return tuple(params[:4])
    raise InputError(None, "camera.model",
                     f"COLMAP model {model} with distortion {params.tolist()} is not supported; "
                     "undistort the images first (colmap image_undistorter)")


def validate_camera(cam: Camera) -> None:
    """Raise :class:`InputError` (field names only; callers add the file) for an impossible camera."""
    if cam.width <= 0 or cam.height <= 0:
        raise InputError(None, "width/height", f"must be > 0, got {cam.width}x{cam.height}")
    K = require_finite(cam.K, None, "K")
    w2c = require_finite(cam.w2c, None, "world_to_camera")
    if K.shape != (3, 3) or w2c.shape != (4, 4):
        raise InputError(None, "K/world_to_camera", "expected 3x3 and 4x4 matrices")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InputError(None, "K", f"focal lengths must be > 0, got fx={K[0, 0]}, fy={K[1, 1]}")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0:
        raise InputError(None, "K", "must be upper triangular with last row [0, 0, 1]")
    if not np.allclose(w2c[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError(None, "world_to_camera", "last row must be [0, 0, 0, 1]")
    R = w2c[:3, :3]
    err = np.abs(R @ R.T - np.eye(3)).max()
    if err > ROTATION_TOL or np.linalg.det(R) <= 0:
        raise InputError(None, "world_to_camera",
                         f"rotation part is not a rotation (|R R^T - I| = {err:.2g}, det = {np.linalg.det(R):.4g})")
