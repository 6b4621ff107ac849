"""Writing a generated scene as a user's PINF capture: ``info.json`` in the file's own unit and up axis, one H.264
MP4 per camera (imageio-ffmpeg), the true clean plates as 16-bit PNGs, and ``truth.json``.

The generator's world is metres with +y up. The file's world is ``x_file = F x / m``: ``m`` the unit's length in
metres, ``F`` the identity for a y-up file and ``(x, y, z) -> (x, -z, y)`` for a z-up one (the inverse of the
importer's ``(x, y, z) -> (x, z, -y)``, docs/conventions.md). ``calibrate --from-pinf info.json
--metres-per-unit m`` therefore gives back the generator's world, in which truth.json is written.
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import imageio_ffmpeg
import numpy as np

GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])
TO_FILE = {"Y": np.eye(3), "Z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])}


def to_file(points, up: str, metres_per_unit: float) -> np.ndarray:
    """World points [..., 3] (metres, +y up) in the file's axes and unit."""
    return np.asarray(points, float) @ TO_FILE[up].T / metres_per_unit


def nerf_matrix(camera, up: str, metres_per_unit: float) -> list:
    """The camera's PINF ``transform_matrix``: camera-to-world in OpenGL axes, in the file's world."""
    c2w = np.linalg.inv(camera.w2c) @ GL_TO_CV
    out = np.eye(4)
    out[:3, :3] = TO_FILE[up] @ c2w[:3, :3]
    out[:3, 3] = TO_FILE[up] @ c2w[:3, 3] / metres_per_unit
    return out.tolist()


def video_entry(name: str, cameras: list, fps: float, frames: int, up: str, mpu: float) -> dict:
    """One ``train_videos`` / ``test_videos`` entry; a list of several cameras is a moving camera
    (``transform_matrix_list``, one per frame)."""
    first = cameras[0]
    out = {"file_name": f"{name}.mp4", "frame_rate": fps, "frame_num": frames,
           "camera_angle_x": first.fov_x, "camera_hw": [first.height, first.width]}
    if len(cameras) == 1:
        out["transform_matrix"] = nerf_matrix(first, up, mpu)
    else:
        out["transform_matrix_list"] = [nerf_matrix(c, up, mpu) for c in cameras]
    return out


def volume_fields(lo, hi, up: str, mpu: float) -> dict:
    """``voxel_matrix`` and ``voxel_scale`` of the box (lo, hi) in the file's world (PINF's convention:
    world = R (voxel_scale * p) + t with R | t the matrix with its columns 0 and 2 swapped)."""
    corners = to_file([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1)
                       for k in (0, 1)], up, mpu)
    flo, fhi = corners.min(0), corners.max(0)
    m = np.eye(4)
    m[:3, :3] = np.eye(3)[:, [2, 1, 0]]
    m[:3, 3] = flo
    return {"voxel_matrix": m.tolist(), "voxel_scale": (fhi - flo).tolist()}


def write_mp4(path: Path, frames: np.ndarray, fps: float, crf: int = 12) -> None:
    """[T, H, W, 3] floats in [0, 1] (H and W even) as an H.264 yuv420p MP4."""
    height, width = frames.shape[1:3]
    writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264", pix_fmt_in="rgb24",
                                         pix_fmt_out="yuv420p", quality=None, macro_block_size=1,
                                         output_params=["-crf", str(crf)], ffmpeg_log_level="error")
    writer.send(None)
    for f in frames:
        writer.send(np.ascontiguousarray(np.rint(np.clip(f, 0, 1) * 255).astype(np.uint8)))
    writer.close()


def write_plate(path: Path, image: np.ndarray) -> None:
    """[H, W, 3] in [0, 1] as a 16-bit RGB PNG."""
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.rint(np.clip(image[..., ::-1], 0, 1) * 65535).astype(np.uint16))


def write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=1))
