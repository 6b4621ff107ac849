"""Observation model of diagnose: low-resolution smoke images per view and the observables read from them.

Measured footage and simulated particles go through the same functions, so every observable compares like
with like. Images are gray intensity [V, T, h, w] float64 (smoke bright on dark, conventions.md pixels).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fluidnexus.camera import Camera


@dataclass(frozen=True)
class Observed:
    """The measured footage at observation resolution.

    Attributes:
        names: view names [V].
        cameras: the views' cameras resized to the observation resolution [V].
        images: gray intensity [V, T, h, w] float64, frames ``first .. first + T - 1`` of the scene.
        first: scene frame index of ``images[:, 0]``.
        fps: frames per second.
    """

    names: tuple
    cameras: tuple
    images: np.ndarray
    first: int
    fps: float


def splat_points(camera: Camera, points: np.ndarray, weights: np.ndarray, sigma_px: float) -> np.ndarray:
    """Additive image of weighted points: bilinear splat into ``camera``'s pixels, then a Gaussian blur.

    Args:
        camera: the view (its width x height is the image size).
        points: [N, 3] world positions [m].
        weights: [N] smoke amount per point (intensity units).
        sigma_px: blur standard deviation [px] (the footprint of one particle).

    Returns:
        [h, w] float64 image.
    """
    h, w = camera.height, camera.width
    img = np.zeros(h * w)
    if len(points):
        uv, depth = camera.project(points)
        x, y = uv[:, 0] - 0.5, uv[:, 1] - 0.5  # pixel centres at +0.5
        x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
        fx, fy = x - x0, y - y0
        front = depth > 0
        for dx, dy, wt in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
            xi, yi = x0 + dx, y0 + dy
            ok = front & (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
            img += np.bincount(yi[ok] * w + xi[ok], weights=(weights * wt)[ok], minlength=h * w)
    img = img.reshape(h, w)
    return cv2.GaussianBlur(img, (0, 0), sigma_px) if sigma_px > 0 else img


@dataclass(frozen=True)
class Observables:
    """Per-frame observables of a plume seen by several views (all arrays [T]; world metres, seconds).

    Attributes:
        centroid: smoke centroid [T, 3] m, least-squares intersection of the views' image-centroid rays.
        front: height of the plume's top [m] (mean over views of the top of the smoke at the centroid depth).
        rise_speed: d front / dt [m/s].
        width: mean over views of the smoke's horizontal standard deviation [m] at the centroid depth.
        intensity: total visible smoke, mean over views of the image sum (intensity units).
        tilt: rotation signature, mean over views of the principal-axis tilt from vertical [deg] (signed).
    """

    centroid: np.ndarray
    front: np.ndarray
    rise_speed: np.ndarray
    width: np.ndarray
    intensity: np.ndarray
    tilt: np.ndarray


def observables(images: np.ndarray, cameras, fps: float, floor: float = 0.02) -> Observables:
    """Observables of a multi-view image sequence [V, T, h, w] (see :class:`Observables`).

    ``floor`` is the fraction of a view's peak row mass below which a row counts as empty (front detection).
    Frames without smoke give NaN geometry and zero intensity.
    """
    V, T, h, w = images.shape
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    centroid = np.full((T, 3), np.nan)
    front, width, tilt = (np.full(T, np.nan) for _ in range(3))
    intensity = images.reshape(V, T, -1).sum(-1).mean(0)
    for t in range(T):
        uvs, mass = [], images[:, t].reshape(V, -1).sum(-1)
        if np.any(mass <= 1e-9):
            continue
        for v in range(V):
            img = images[v, t]
            uvs.append([(img * xs).sum() / mass[v], (img * ys).sum() / mass[v]])
        c = triangulate(cameras, np.asarray(uvs))
        centroid[t] = c
        tops, wides, tilts = [], [], []
        for v, cam in enumerate(cameras):
            img = images[v, t]
            _, depth = cam.project(c[None])
            metres_per_px = depth[0] / cam.K[0, 0]
            rows = img.sum(1)
            top = np.argmax(rows > floor * rows.max())
            tops.append(cam.unproject(np.array([[uvs[v][0], top]]), depth)[0, 1])
            du, dv = xs - uvs[v][0], ys - uvs[v][1]
            m_uu, m_vv, m_uv = ((img * a).sum() / mass[v] for a in (du * du, dv * dv, du * dv))
            wides.append(np.sqrt(max(m_uu, 0.0)) * metres_per_px)
            tilts.append(np.degrees(0.5 * np.arctan2(2 * m_uv, m_vv - m_uu)))
        front[t], width[t], tilt[t] = np.mean(tops), np.mean(wides), np.mean(tilts)
    rise = np.gradient(front) * fps if T > 1 else np.zeros(T)
    return Observables(centroid, front, rise, width, intensity, tilt)


def triangulate(cameras, uv: np.ndarray) -> np.ndarray:
    """The world point [3] closest (least squares) to the rays through pixel ``uv[v]`` of each camera."""
    A, b = np.zeros((3, 3)), np.zeros(3)
    for cam, p in zip(cameras, uv):
        origin = cam.center
        d = cam.unproject(p[None], 1.0)[0] - origin
        d /= np.linalg.norm(d)
        m = np.eye(3) - np.outer(d, d)
        A += m
        b += m @ origin
    return np.linalg.solve(A, b)


def image_error(observed: np.ndarray, simulated: np.ndarray) -> np.ndarray:
    """Image error per frame: mean squared difference over views and pixels, relative to the mean squared
    observed intensity of the whole sequence (so 1.0 = predicting nothing). [V, T, h, w] x 2 -> [T]."""
    scale = np.mean(observed**2) + 1e-12
    return ((observed - simulated) ** 2).mean(axis=(0, 2, 3)) / scale
