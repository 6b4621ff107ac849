"""Brightness across views: what a view's total smoke intensity should be, given the input view's (a measurement
for ``bench_synth_brightness.py`` and the tests; the tool itself does not use it).

For emission-only smoke a pixel is the line integral of the density along its ray, and a pixel covers the solid
angle ``z^3 / (fx fy r^3)`` (camera depth z and distance r of what it sees; ``1 / f^2`` on the optical axis). A
volume element at distance r is seen under ``1 / r^2`` per unit of its cross-section, so summed over the image a
view's total intensity is the smoke's mass weighted by ``g = fx fy r / z^3``: ``(f / d)^2`` for a plume at distance d
on the optical axis, whatever the direction it is seen from. So a novel view should hold the input's total times
``g(novel) / g(input)`` at the plume's centre.

The plume's centre in a frame: the point of the vertical through its foot nearest to the input ray through the
frame's intensity centroid. The ratio depends on that foot: a foot placed too far from the input camera makes the
input's smoke bigger and brighter in every other view.
"""
from __future__ import annotations

import numpy as np

from fluidnexus.camera import Camera

UP = np.array([0.0, 1.0, 0.0])
MIN_SHARE = 0.01  # frames with less smoke than this share of the input's most are not measured (noise, not smoke)


def pixel_density(camera: Camera, point: np.ndarray) -> float:
    """Pixels per steradian (``fx fy r^3 / z^3``) times ``1 / r^2`` at world ``point``: ``fx fy r / z^3``."""
    offset = np.asarray(point, np.float64) - camera.center
    r = float(np.linalg.norm(offset))
    z = float(offset @ camera.forward)
    return float(camera.K[0, 0] * camera.K[1, 1]) * r / max(z, 1e-12) ** 3


def plume_centre(frame: np.ndarray, camera: Camera, foot: np.ndarray) -> np.ndarray | None:
    """The point of the vertical through ``foot`` nearest to ``camera``'s ray through the intensity centroid of
    ``frame`` [H, W, C] (None where the frame is empty)."""
    image = frame.mean(axis=-1)
    total = float(image.sum())
    if total <= 0:
        return None
    rows, cols = np.indices(image.shape)
    uv = np.array([[(image * (cols + 0.5)).sum() / total, (image * (rows + 0.5)).sum() / total]])
    ray = camera.unproject(uv, 1.0)[0] - camera.center
    ray /= np.linalg.norm(ray)
    # closest points of camera.center + s ray and foot + h UP
    w = camera.center - np.asarray(foot, np.float64)
    b, d, e = float(ray @ UP), float(ray @ w), float(UP @ w)
    denom = 1.0 - b * b
    h = e if denom < 1e-12 else (e - b * d) / denom
    return np.asarray(foot, np.float64) + h * UP


def brightness_ratios(footage: np.ndarray, camera: Camera, videos: dict[str, np.ndarray],
                      cameras: dict[str, Camera], foot: np.ndarray) -> dict[str, np.ndarray]:
    """Per view, per frame: its total intensity over the total the input ``footage`` [T, H, W, C] of ``camera``
    implies (module docstring); NaN in frames whose input holds under ``MIN_SHARE`` of its largest total.

    Args:
        videos: view name -> [T', h, w, C] (T' <= T; any size: each camera is resized to its video's).
        cameras: view name -> its camera.
        foot: [3] the plume's foot (source centre).
    """
    cam_in = camera.resized(footage.shape[2], footage.shape[1])
    totals = footage.reshape(len(footage), -1, footage.shape[-1]).mean(-1).sum(-1)
    out = {}
    for name, video in videos.items():
        cam = cameras[name].resized(video.shape[2], video.shape[1])
        ratio = np.full(len(video), np.nan)
        for t, frame in enumerate(video):
            centre = plume_centre(footage[t], cam_in, foot)
            if centre is None or totals[t] < MIN_SHARE * totals.max():
                continue
            implied = totals[t] * pixel_density(cam, centre) / pixel_density(cam_in, centre)
            ratio[t] = float(frame.mean(-1).sum()) / implied
        out[name] = ratio
    return out
