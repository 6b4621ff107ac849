"""The embedded ScalarFlow sample composited over a textured 3D backdrop (test-only).

A plane at z = ``PLANE_Z``, 0.1 m behind the sample's volume (every camera of the rig looks towards -z), carries
smooth waves of gray; each camera's plate is that plane ray cast through its pixels. A backdrop right behind the
smoke, as in a lab: the held-out camera train02 sees its part of the plane in two or more input views at 96 % of
its pixels (a plane 0.75 m behind the volume's centre, at z = -1.0, is seen by two input views at 25 % of train02's
pixels and by none at 6 %: the rig's narrow views look at different parts of a far wall, and no method can place
what one view alone sees). The sample's smoke glows on black:
read as the alpha of white smoke (a pixel's value S is its opacity times 1), it composites over the plate B as
``I = S + B (1 - S)``, which is exactly what the renderer draws for white Gaussians over a per-pixel background.
The same frames on black are the reference.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from fluidnexus.calibrate.pinf import read_pinf, source_at_volume_foot
from fluidnexus.camera import Camera
from fluidnexus.samples import sample_path
from fluidnexus.scene import GroundTruth, Scene, View, save_scene
from fluidnexus.video import read_video, write_video

PLANE_Z = -0.6
INPUTS = ("train00", "train01", "train03", "train04")
HELD_OUT = "train02"


def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Gray in [0.2, 0.6] at plane coordinates (x, y) metres: three waves of 0.4-1.1 m."""
    return 0.4 + 0.09 * np.sin(9.0 * x + 2.0 * y) + 0.07 * np.sin(-3.5 * x + 7.5 * y + 1.0) \
        + 0.04 * np.sin(5.5 * x + 5.5 * y + 2.0)


def plate(camera: Camera) -> np.ndarray:
    """[H, W] the backdrop seen by ``camera`` (one ray per pixel centre; 0.4 where a ray misses the plane)."""
    rows, cols = np.mgrid[0:camera.height, 0:camera.width]
    uv = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=1)
    d = camera.unproject(uv, 1.0) - camera.center
    t = (PLANE_Z - camera.center[2]) / d[:, 2]
    p = camera.center + t[:, None] * d
    out = np.where(t > 0, texture(p[:, 0], p[:, 1]), 0.4)
    return out.reshape(camera.height, camera.width).astype(np.float32)


def write_scenes(root: Path, frames: int, scale: float) -> tuple[Path, Path]:
    """(scene on black, scene over the backdrop with the input views' plates given as PNG files for
    ``fluidnexus background --plate``): the first ``frames`` frames of the sample at ``scale`` of its size, four
    input views and ``HELD_OUT`` as ground truth. The plates are written as ``ROOT/plates/NAME.png``."""
    cap = read_pinf(sample_path("scalarflow") / "info.json")
    (root / "plates").mkdir(parents=True, exist_ok=True)
    out = []
    for kind in ("black", "backdrop"):
        scene_dir = root / kind
        views, truths = [], []
        for name, rec in cap.recordings.items():
            small = rec.camera.scaled(scale)
            smoke = read_video(rec.media, frames=slice(0, frames), size=(small.width, small.height), channels=1)
            if kind == "backdrop":
                back = cv2.resize(plate(rec.camera), (small.width, small.height), interpolation=cv2.INTER_AREA)
                smoke = smoke + back[None, :, :, None] * (1.0 - smoke)
                cv2.imwrite(str(root / "plates" / f"{name}.png"), np.rint(plate(rec.camera) * 65535).astype(np.uint16))
            folder = "ground_truth" if name == HELD_OUT else "videos"
            write_video(scene_dir / folder / f"{name}.mp4", smoke, cap.fps, crf=12)
            if name == HELD_OUT:
                truths.append(GroundTruth(name, rec.camera, f"{folder}/{name}.mp4"))
            elif name in INPUTS:
                views.append(View(name, "input", rec.camera, f"{folder}/{name}.mp4"))
        save_scene(Scene(scene_dir, cap.fps, frames, tuple(views), cap.volume, source_at_volume_foot(cap.volume)),
                   tuple(truths))
        out.append(scene_dir)
    return out[0], out[1]
