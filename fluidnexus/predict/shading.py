"""The obstacle in the videos: an opaque, shaded body composited with the splatted smoke.

The body is ray-marched once per camera (sphere tracing of its signed distance; the body and the cameras are
static) into a shade and a depth image. Each frame's smoke comes from the splat renderer with its accumulated
alpha and depth; where the ray hits the body, smoke whose expected depth is in front of the body is drawn over
it (out = smoke + (1 - alpha) shade), smoke behind it is hidden (out = shade). This per-pixel ordering is an
approximation for smoke that straddles the body.
"""
from __future__ import annotations

import numpy as np
import torch

from .. import engine
from ..camera import Camera
from ..engine.tensors import torch_dtype
from ..state import FrameState

MARCH_STEPS = 96
HIT = 1e-4  # metres
FAR = 50.0  # metres
AMBIENT, DIFFUSE, ALBEDO = 0.25, 0.75, 0.8


class ObstacleLayer:
    """The body as one camera sees it: ``shade`` [H, W] in [0, 1] and camera-space ``depth`` [H, W] m (inf where
    the ray misses)."""

    def __init__(self, obstacle, camera: Camera):
        h, w = camera.height, camera.width
        u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        d_cam = np.linalg.solve(camera.K, np.stack([u.ravel(), v.ravel(), np.ones(u.size)]))  # z = 1
        d_world = (camera.R.T @ d_cam).T
        length = np.linalg.norm(d_world, axis=1)
        unit = d_world / length[:, None]
        origin = camera.center
        t = np.zeros(len(unit))
        alive = np.ones(len(unit), bool)
        hit = np.zeros(len(unit), bool)
        for _ in range(MARCH_STEPS):
            idx = np.flatnonzero(alive)
            if idx.size == 0:
                break
            dist = _bounded_distance(obstacle, origin + unit[idx] * t[idx, None])
            close = dist < HIT
            hit[idx[close]] = True
            t[idx] += np.where(close, 0.0, dist)
            alive[idx[close | (t[idx] > FAR)]] = False
        points = origin + unit * t[:, None]
        normal = _normal(obstacle, points[hit])
        light = -unit[hit] + np.array([0.0, 0.6, 0.0])  # a headlight raised above the camera
        light /= np.linalg.norm(light, axis=1, keepdims=True)
        shade = np.zeros(len(unit))
        shade[hit] = ALBEDO * (AMBIENT + DIFFUSE * np.clip((normal * light).sum(1), 0.0, 1.0))
        depth = np.full(len(unit), np.inf)
        depth[hit] = t[hit] / length[hit]  # camera-space z of the hit (d_cam has z = 1)
        self.shade = shade.reshape(h, w).astype(np.float32)
        self.depth = depth.reshape(h, w)

    def composite(self, smoke: np.ndarray, alpha: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Smoke image [H, W, C] with its alpha [H, W] and accumulated depth [H, W] over the body."""
        hit = np.isfinite(self.depth)
        expected = np.where(alpha > 1e-6, depth / np.maximum(alpha, 1e-6), np.inf)
        in_front = expected < self.depth
        shade = self.shade[..., None]
        over = np.where(in_front[..., None], smoke + (1.0 - alpha[..., None]) * shade, shade)
        return np.where(hit[..., None], over, smoke).astype(np.float32)


def _bounded_distance(obstacle, points: np.ndarray) -> np.ndarray:
    """A step no longer than the distance to the body (grid bodies: the distance to their grid box outside it)."""
    d = obstacle.distance(points)
    if not np.isinf(d).any():
        return d
    lo = np.asarray(obstacle.origin)
    hi = lo + obstacle.spacing * (np.asarray(obstacle.phi_np.shape) - 1)
    outside = np.linalg.norm(points - np.clip(points, lo, hi), axis=1) + 0.5 * obstacle.spacing
    return np.where(np.isinf(d), outside, d)


def _normal(obstacle, points: np.ndarray, eps: float = 1e-3) -> np.ndarray:
    """Unit outward normals [K, 3]: central differences of the signed distance."""
    if len(points) == 0:
        return np.zeros((0, 3))
    grad = np.stack([_bounded_distance(obstacle, points + eps * e) - _bounded_distance(obstacle, points - eps * e)
                     for e in np.eye(3)], axis=1)
    return grad / np.maximum(np.linalg.norm(grad, axis=1, keepdims=True), 1e-12)


def render_with_obstacle(state: FrameState, camera: Camera, layer: ObstacleLayer | None) -> np.ndarray:
    """The smoke of ``state`` seen by ``camera`` [H, W, C], with the body of ``layer`` when given."""
    def t(a):
        return torch.as_tensor(np.asarray(a), dtype=torch_dtype())

    with torch.no_grad():
        image, alpha, depth = engine.render(camera, t(state.visual_positions), t(state.visual_scales),
                                            t(state.visual_rotations), t(state.visual_opacities),
                                            t(state.visual_colors), return_depth=layer is not None)
    image = image.clamp(0, 1).numpy().astype(np.float32)
    if layer is None:
        return image
    return layer.composite(image, alpha.numpy(), depth.numpy())
