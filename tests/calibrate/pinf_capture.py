"""A PINF capture built in the tests: the structure of PINF's published Sphere ``info.json`` (z-up world, one
``voxel_scale`` number, ``train_videos`` / ``test_videos`` / ``val_videos``, ``frame_bkg_color``, ``near``, ``far``,
``phi``, ``render_center``) with cameras made here and tiny generated videos."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from fluidnexus.camera import Camera
from fluidnexus.video import write_video

# Sphere's reconstruction box: voxel_matrix rotates about x by 90 degrees (the real file's -1.7e-8 entries are
# rounding of that rotation); one voxel_scale number makes it a 4.8-unit cube.
VOXEL_MATRIX = [[0.4, 0.0, 0.0, -2.42], [0.0, 0.0, -0.4, 2.46], [0.0, 0.4, 0.0, -2.71], [0.0, 0.0, 0.0, 1.0]]
VOXEL_SCALE = 12.0064
RING_RADIUS, RING_HEIGHT = 4.0, 1.66  # cameras on a horizontal ring around the z axis, as in Sphere
TARGET = (0.0, 0.0, -0.3)  # where they look (near the box centre)


def source_box(voxel_matrix=VOXEL_MATRIX, voxel_scale=VOXEL_SCALE) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) of the box in the file's own world, straight from PINF's definition."""
    m = np.asarray(voxel_matrix, dtype=float)
    R, t = m[:3, :3][:, [2, 1, 0]], m[:3, 3]
    s = np.broadcast_to(np.asarray(voxel_scale, dtype=float).reshape(-1), (3,))
    corners = np.array([R @ (s * np.array(p)) + t for p in np.ndindex(2, 2, 2)])
    return corners.min(0), corners.max(0)


def ring_camera(azimuth_deg: float, size: int, up_axis: str = "Z", scale: float = 1.0) -> Camera:
    """A camera of the ring at ``azimuth_deg``, in a world whose up axis is ``up_axis`` ("Z" or "Y")."""
    a = math.radians(azimuth_deg)
    ring = (RING_RADIUS * math.sin(a), -RING_RADIUS * math.cos(a), RING_HEIGHT)  # z up
    target = TARGET
    up = (0.0, 0.0, 1.0)
    if up_axis == "Y":  # the same rig with y up: (x, y, z)_zup -> (x, z, -y)
        ring, target, up = ((p[0], p[2], -p[1]) for p in (ring, target, up))
    fx = 0.5 * size / math.tan(0.5 * 0.6911112070083618)
    return Camera.look_at(size, size, fx, np.multiply(ring, scale), np.multiply(target, scale), up)


def entry(name: str, camera: Camera, frames: int, poses: list[Camera] | None = None) -> dict:
    """One PINF video entry (``transform_matrix_list`` when ``poses`` is given)."""
    nerf = camera.to_nerf()
    out = {"file_name": name, "frame_rate": 25, "frame_num": frames, "camera_angle_x": nerf["camera_angle_x"],
           "camera_hw": [camera.height, camera.width]}
    if poses is None:
        out["transform_matrix"] = nerf["transform_matrix"]
    else:
        out["transform_matrix_list"] = [c.to_nerf()["transform_matrix"] for c in poses]
    return out


def tiny_video(path: Path, frames: int, size: int) -> Path:
    """A small gray MP4 whose brightness changes over time."""
    t = np.arange(frames, dtype=np.float32)[:, None, None, None]
    y = np.linspace(0, 1, size, dtype=np.float32)[None, :, None, None]
    write_video(path, np.clip(0.3 + 0.4 * y + 0.05 * t, 0, 1) * np.ones((1, 1, size, 3), np.float32), 25)
    return path


def write_capture(folder: Path, frames: int = 3, size: int = 16, rot: str | None = "Z", voxel_scale=VOXEL_SCALE,
                  scale: float = 1.0, videos: bool = True, **overrides) -> Path:
    """Write a Sphere-shaped info.json (and tiny videos) into ``folder``; return the info.json path.

    train00..04 stand on the ring every 72 degrees, test04 at 144 + 36 and test02 at 180 degrees (a val video),
    as in Sphere. ``scale`` multiplies every length of the file (cameras and box); ``overrides`` replace
    top-level fields (None removes one).
    """
    folder.mkdir(parents=True, exist_ok=True)
    up = "Y" if rot in (None, "Y") else "Z"
    names = {f"train{i:02d}": 72.0 * i for i in range(5)}
    names.update(test04=180.0 + 36.0, test02=180.0)
    m = np.array(VOXEL_MATRIX)
    if up == "Y":  # the same box in a y-up world
        flip = np.eye(4)
        flip[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
        m = flip @ m
    m[:3, 3] *= scale
    entries = {n: entry(f"{n}.mp4", ring_camera(az, size, up, scale), frames) for n, az in names.items()}
    info = {"train_videos": [entries[f"train{i:02d}"] for i in range(5)], "test_videos": [entries["test04"]],
            "val_videos": [entries["test02"]], "frame_bkg_color": [1.0, 1.0, 1.0],
            "voxel_scale": voxel_scale if np.ndim(voxel_scale) == 0 and scale == 1 else
            (np.asarray(voxel_scale, dtype=float) * scale).tolist(),
            "voxel_matrix": m.tolist(), "render_center": [0.0, 0.0, 0.0], "near": 2.0 * scale,
            "far": 6.0 * scale, "phi": -30.0, "rot": rot}
    info.update(overrides)
    info = {k: v for k, v in info.items() if v is not None}
    if videos:
        for n in names:
            tiny_video(folder / f"{n}.mp4", frames, size)
    path = folder / "info.json"
    path.write_text(json.dumps(info, indent=1))
    return path
