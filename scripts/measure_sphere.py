"""Measure the red sphere of PINF's Sphere scene from its silhouette in the training views (docs/reconstruction.md).

For each view: the pixels that are red in any frame (the sphere is static, smoke only hides parts of it, so the
union over the frames is its whole silhouette; red = R above ``--red-min`` and above G and B by ``--red-margin``),
the largest connected part with its holes filled (highlights, spots always behind smoke), then a
least-squares circle fit (Kasa) to its boundary pixels. The centre is the point nearest, in the
least-squares sense, to the viewing rays through the circles' centres; the radius is the mean over the views of
D sin(a), with D the camera's distance to that centre and a the angle between the ray to the circle's centre and
the ray to a point on the circle (the angular radius of the ball). A view whose boundary is no circle (fit rms above
``--max-rms`` px: part of the ball is behind smoke in every frame) is left out.

    .venv/bin/python scripts/measure_sphere.py ../shared/data/pinf_sphere [--views train00,...,train04]

Prints the centre and radius in the file's own frame (z up, scene units) and in the project's (+y up:
``world_frame.UP_AXES["Z"]``, (x, y, z) -> (x, z, -y)), and the per-view circles and ray residuals.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fluidnexus.camera import Camera
from fluidnexus.video import read_video
from fluidnexus.world_frame import UP_AXES


def red_silhouette(video: np.ndarray, red_min: float, margin: float) -> np.ndarray:
    """[H, W] bool: pixels red in any frame of ``video`` [T, H, W, 3]."""
    r, g, b = video[..., 0], video[..., 1], video[..., 2]
    return np.any((r > red_min) & (r - g > margin) & (r - b > margin), axis=0)


def largest_component(mask: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    labels, n = ndimage.label(mask)
    if n == 0:
        raise SystemExit("no red pixels found")
    sizes = ndimage.sum(mask, labels, range(1, n + 1))
    return ndimage.binary_fill_holes(labels == (1 + int(np.argmax(sizes))))  # highlights and smoke spots inside


def fit_circle(mask: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(centre (u, v) in pixel coordinates, radius px, rms residual px) of the mask's boundary."""
    from scipy import ndimage

    edge = mask & ~ndimage.binary_erosion(mask)
    rows, cols = np.nonzero(edge)
    u, v = cols + 0.5, rows + 0.5
    a = np.stack([u, v, np.ones_like(u)], axis=1)
    sol, *_ = np.linalg.lstsq(a, u**2 + v**2, rcond=None)
    cu, cv = sol[0] / 2, sol[1] / 2
    radius = float(np.sqrt(sol[2] + cu**2 + cv**2))
    resid = float(np.sqrt(np.mean((np.hypot(u - cu, v - cv) - radius) ** 2)))
    return np.array([cu, cv]), radius, resid


def ray(cam: Camera, uv) -> tuple[np.ndarray, np.ndarray]:
    """(origin, unit direction) in world coordinates of the viewing ray through pixel ``uv``."""
    p = cam.unproject(np.asarray(uv, float)[None], np.array([1.0]))[0]
    d = p - cam.center
    return cam.center, d / np.linalg.norm(d)


def nearest_point(rays) -> tuple[np.ndarray, np.ndarray]:
    """The point minimising the summed squared distances to the rays, and each ray's distance to it."""
    a, b = np.zeros((3, 3)), np.zeros(3)
    for o, d in rays:
        m = np.eye(3) - np.outer(d, d)
        a += m
        b += m @ o
    x = np.linalg.solve(a, b)
    dist = np.array([np.linalg.norm((np.eye(3) - np.outer(d, d)) @ (x - o)) for o, d in rays])
    return x, dist


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--views", default="train00,train01,train02,train03,train04")
    parser.add_argument("--red-min", type=float, default=0.45)
    parser.add_argument("--red-margin", type=float, default=0.15)
    parser.add_argument("--max-rms", type=float, default=3.0, help="largest circle-fit rms (px) of a view kept")
    args = parser.parse_args()
    info = json.loads((args.folder / "info.json").read_text())
    entries = {e["file_name"].rsplit(".", 1)[0]: e
               for key in ("train_videos", "test_videos", "val_videos") for e in info.get(key, [])}
    circles = []
    for name in args.views.split(","):
        e = entries[name]
        h, w = e["camera_hw"]
        cam = Camera.from_nerf(e["transform_matrix"], w, h, e["camera_angle_x"])
        mask = largest_component(red_silhouette(read_video(args.folder / e["file_name"], channels=3),
                                                args.red_min, args.red_margin))
        center, radius, resid = fit_circle(mask)
        circles.append((name, cam, center, radius, resid, int(mask.sum())))
    kept = [c for c in circles if c[4] <= args.max_rms] or circles
    for name, *_, resid, _ in circles:
        if resid > args.max_rms:
            print(f"{name}: left out, its silhouette is not a circle (fit rms {resid:.2f} px: partly hidden in "
                  "every frame)")
    center, dist = nearest_point([ray(cam, c) for _, cam, c, *_ in kept])
    radii = []
    for (name, cam, c, r, resid, area), d_ray in zip(kept, dist):
        _, d0 = ray(cam, c)
        edge = [ray(cam, c + r * np.array([np.cos(t), np.sin(t)]))[1] for t in np.linspace(0, 2 * np.pi, 16, False)]
        alpha = float(np.mean([np.arccos(np.clip(d0 @ de, -1, 1)) for de in edge]))
        radii.append(np.linalg.norm(cam.center - center) * np.sin(alpha))
        print(f"{name}: circle centre ({c[0]:.1f}, {c[1]:.1f}) px, radius {r:.1f} px (fit rms {resid:.2f} px, "
              f"{area} px), ray misses the centre by {d_ray:.4f}, radius estimate {radii[-1]:.4f}")
    radius = float(np.mean(radii))
    up = UP_AXES[info.get("rot", "Y")]
    print(f"source frame (rot {info.get('rot', 'Y')!r}, file units): centre {np.round(center, 4).tolist()}, "
          f"radius {radius:.4f} (views: {np.min(radii):.4f}..{np.max(radii):.4f})")
    print(f"scene frame (+y up, same unit): centre {np.round(up @ center, 4).tolist()}, radius {radius:.4f}")


if __name__ == "__main__":
    main()
