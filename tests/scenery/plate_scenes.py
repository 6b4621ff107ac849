"""Small synthetic footage with a known backdrop (test-only).

A coloured, textured backdrop (value noise of three octaves) with smoke composited over it as
``I = B (1 - a) + A a`` (the haze model of docs/background.md): ``A`` is bright (glowing smoke on a dark backdrop) or
dark (absorbing smoke on a bright one). The smoke is two soft, internally textured bands: one sweeps from left to
right, one from bottom to top, so every pixel is covered at some moment and clear at others.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from fluidnexus.camera import Camera
from fluidnexus.scene import GroundTruth, Scene, View, save_scene
from fluidnexus.video import write_video

WIDTH, HEIGHT, FRAMES = 64, 48, 40
SMOKE = {"bright": (0.95, 0.95, 0.92), "dark": (0.12, 0.12, 0.14)}
BACKDROP = {"bright": (0.05, 0.35), "dark": (0.55, 0.95)}  # backdrop brightness range under each smoke


def noise(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """[H, W] value noise in [0, 1] (three octaves of bilinearly upsampled random lattices)."""
    out = np.zeros((height, width), np.float32)
    for cells, amp in ((4, 0.5), (10, 0.3), (24, 0.2)):
        lattice = rng.random((cells, cells)).astype(np.float32)
        out += amp * cv2.resize(lattice, (width, height), interpolation=cv2.INTER_LINEAR)
    return (out - out.min()) / (out.max() - out.min())


def backdrop(seed: int, kind: str, height: int = HEIGHT, width: int = WIDTH) -> np.ndarray:
    """[H, W, 3] a textured, tinted backdrop whose brightness lies in BACKDROP[kind]."""
    rng = np.random.default_rng(seed)
    lo, hi = BACKDROP[kind]
    tint = rng.uniform(0.8, 1.0, 3).astype(np.float32)
    return (lo + (hi - lo) * noise(rng, height, width))[..., None] * tint


def smoke_alpha(seed: int, frames: int = FRAMES, clean: int = 0, height: int = HEIGHT, width: int = WIDTH,
                cover: bool = False) -> np.ndarray:
    """[T, H, W] smoke opacity: zero for the first ``clean`` frames, then the two sweeping bands (or, with
    ``cover``, smoke over the whole frame with a new texture in every frame)."""
    rng = np.random.default_rng(seed + 1)
    tex = noise(rng, 2 * height, 2 * width)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    out = np.zeros((frames, height, width), np.float32)
    moving = frames - clean
    for k in range(moving):
        f = k / max(moving - 1, 1)
        if cover:
            out[clean + k] = 0.4 + 0.6 * noise(rng, height, width)
            continue
        bx = np.exp(-(((xx - f * width) / (0.13 * width)) ** 2))
        by = np.exp(-(((yy - (1 - f) * height) / (0.13 * height)) ** 2))
        ox, oy = int(3 * k) % width, int(2 * k) % height
        texture = 0.55 + 0.45 * tex[oy:oy + height, ox:ox + width]
        out[clean + k] = np.clip(0.9 * np.maximum(bx, by) * texture, 0, 1)
    return out


def composite(back: np.ndarray, alpha: np.ndarray, kind: str) -> np.ndarray:
    """[T, H, W, 3] = back (1 - a) + A a."""
    smoke = np.asarray(SMOKE[kind], np.float32)
    return back[None] * (1 - alpha[..., None]) + smoke * alpha[..., None]


def camera(k: int) -> Camera:
    eye = (2.0 * np.sin(0.4 * k), 0.5, 2.0 * np.cos(0.4 * k))
    return Camera.look_at(WIDTH, HEIGHT, 60.0, eye, (0.0, 0.5, 0.0))


def make_scene(root: Path, kind: str = "dark", views: int = 2, clean: int = 0, cover: tuple[str, ...] = (),
               frames: int = FRAMES) -> dict[str, np.ndarray]:
    """Write a scene (``views`` input cameras ``cam0``... with MP4 footage, one ground-truth camera ``gt``) into
    ``root``; return the true backdrop of each view (and of ``gt``). Views named in ``cover`` are fully covered by
    moving smoke in every frame."""
    root.mkdir(parents=True, exist_ok=True)
    truth, scene_views = {}, []
    for k, name in enumerate([f"cam{i}" for i in range(views)] + ["gt"]):
        back = backdrop(10 * k + (0 if kind == "dark" else 5), kind)
        alpha = smoke_alpha(10 * k, frames, clean, cover=name in cover)
        write_video(root / f"videos/{name}.mp4", composite(back, alpha, kind), 25.0, crf=12)
        truth[name] = back
        if name != "gt":
            scene_views.append(View(name, "input", camera(k), f"videos/{name}.mp4"))
    scene = Scene(root, 25.0, frames, tuple(scene_views))
    save_scene(scene, (GroundTruth("gt", camera(views), "videos/gt.mp4"),))
    return truth


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((np.asarray(a, np.float64) - b) ** 2)))
