"""Photographs mapped onto a 3D backdrop behind the ScalarFlow sample (``bench_composite.py --backdrop PHOTO``).

The backdrop is a photographer's set sized by the sample's volume (L its width): two walls folded at a vertical edge
``0.3 L`` behind the volume's back face, behind its centre, each turned 20 degrees towards the cameras. The photograph
covers them, unrolled across the fold, ``2 L`` wide, its foot level with the volume's bottom; beyond its edges it
repeats mirrored, so there are no seams and every ray meets the set. The two wings are shaded differently (1.0 and
0.8), as light from one side would, so the fold shows. There is no floor: ScalarFlow's rig stands 6 cm above the
volume's floor, and a floor put a strip into each low camera's view that no other camera sees (the held-out
camera's bottom 20-40 rows with a floor out to the cameras; 2,200 pixels of void past a floor that ends at the
volume's front). Without one, 1,600 of train02's 129,600 pixels (its bottom rows) show wall that no input view sees
(BENCHMARKS.md, "ScalarFlow's smoke over photographs").
Each pixel averages 3 x 3 rays, and each ray reads the photo filtered over its footprint (mip-mapping), so the
photo's detail is not aliased where a wing is seen at a slant.

Photos come from scikit-image's bundled data (offline: ``coffee`` is a cup on a table with bright highlights,
``chelsea`` a cat, ``astronaut`` a portrait, ``rocket`` one on its pad against the sky) or from an image file.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from fluidnexus.camera import Camera
from fluidnexus.scene import Volume

PHOTOS = ("coffee", "chelsea", "astronaut", "rocket")
TURN = np.radians(20.0)
SHADING = (1.0, 0.8)  # left wing, right wing
SUPERSAMPLE = 3


def load_photo(name: str) -> np.ndarray:
    """[h, w, 3] RGB in [0, 1]: one of scikit-image's bundled photos by name, or an image file."""
    if Path(name).is_file():
        image = cv2.imread(name, cv2.IMREAD_COLOR)
        if image is None:
            raise SystemExit(f"{name}: not an image file")
        return image[:, :, ::-1].astype(np.float32) / 255.0
    from skimage import data

    if name not in PHOTOS:
        raise SystemExit(f"--backdrop {name}: not a file, nor one of scikit-image's photos {', '.join(PHOTOS)}")
    image = getattr(data, name)()
    return image[:, :, :3].astype(np.float32) / 255.0


def _mirrored(coord: np.ndarray, size: int) -> np.ndarray:
    """Pixel coordinates folded into [0, size - 1] by mirroring the image about its edges."""
    period = 2.0 * (size - 1)
    c = np.mod(coord, period)
    return np.where(c > size - 1, period - c, c)


def trace(camera: Camera, volume: Volume, photo_shape, supersample: int = 1):
    """Rays through ``supersample`` x ``supersample`` points of every pixel of ``camera``, each to the nearer of the
    two walls: (camera-space depth, photo column, photo row, shading), each [H * s, W * s]."""
    lo, hi = np.asarray(volume.min, float), np.asarray(volume.max, float)
    width = hi[0] - lo[0]
    apex = np.array([0.5 * (lo[0] + hi[0]), lo[1], lo[2] - 0.3 * width])
    metres_per_pixel = 2.0 * width / photo_shape[1]
    rows, cols = np.mgrid[0:camera.height * supersample, 0:camera.width * supersample]
    uv = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=1) / supersample
    d = camera.unproject(uv, 1.0) - camera.center  # unit camera-space depth: t along it is the depth
    o = camera.center
    best = np.full(len(d), np.inf)
    u = np.zeros(len(d))
    v = np.zeros(len(d))
    shading = np.zeros(len(d))
    for side, shade in ((-1.0, SHADING[0]), (1.0, SHADING[1])):
        along = np.array([side * np.cos(TURN), 0.0, np.sin(TURN)])  # from the fold outwards, towards the cameras
        normal = np.array([-side * np.sin(TURN), 0.0, np.cos(TURN)])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((apex - o) @ normal) / (d @ normal)
        p = o + t[:, None] * d
        s = (p - apex) @ along
        hit = (t > 0) & (s >= 0) & (t < best)
        best = np.where(hit, t, best)
        u = np.where(hit, photo_shape[1] / 2.0 + side * s / metres_per_pixel, u)
        v = np.where(hit, photo_shape[0] - (p[:, 1] - apex[1]) / metres_per_pixel, v)
        shading = np.where(hit, shade, shading)
    shape = (camera.height * supersample, camera.width * supersample)
    return tuple(a.reshape(shape) for a in (best, u, v, shading))


def plate(camera: Camera, volume: Volume, photo: np.ndarray) -> np.ndarray:
    """[H, W, 3] the set seen by ``camera``: each ray's colour is the photo filtered over the ray's footprint (a
    pyramid level per ray, blended between the two nearest, as a GPU's trilinear mip-mapping does), so a surface
    seen at a grazing angle shows its average colour, as a camera's pixel integrates it, not aliased noise."""
    _, u, v, shading = trace(camera, volume, photo.shape, SUPERSAMPLE)
    footprint = np.maximum.reduce([np.abs(np.gradient(c, axis=a)) for c in (u, v) for a in (0, 1)])
    level = np.log2(np.maximum(footprint, 1.0))
    pyramid = [photo]
    while min(pyramid[-1].shape[:2]) > 8:
        pyramid.append(cv2.pyrDown(pyramid[-1]))
    level = np.minimum(level, len(pyramid) - 1)
    below = np.floor(level).astype(int)
    seen = np.zeros(u.shape + (photo.shape[2],), np.float32)
    for k, image in enumerate(pyramid):
        weight = np.where(below == k, 1.0 - (level - below), 0.0) + np.where(below + 1 == k, level - below, 0.0)
        if not weight.any():
            continue
        scale = photo.shape[1] / image.shape[1]
        maps = [_mirrored(c / scale - 0.5, n).astype(np.float32) for c, n in ((u, image.shape[1]), (v, image.shape[0]))]
        seen += weight[:, :, None].astype(np.float32) * cv2.remap(image, maps[0], maps[1], cv2.INTER_LINEAR)
    seen *= shading[:, :, None].astype(np.float32)
    return cv2.resize(seen, (camera.width, camera.height), interpolation=cv2.INTER_AREA).clip(0.0, 1.0)
