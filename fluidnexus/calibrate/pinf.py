"""PINF / HyFluid / ScalarFlow ``info.json``: read it into recordings, and write a scene back as one.

The file lists ``train_videos`` and ``test_videos``; each entry has ``file_name``, ``frame_rate``, ``frame_num``,
``camera_angle_x`` (horizontal FOV, radians), ``camera_hw`` = [H, W] and ``transform_matrix`` (camera-to-world,
OpenGL axes). The reconstruction box is ``world = R (voxel_scale * p) + t`` for p in [0, 1]^3, where ``R | t`` is
``voxel_matrix`` with its columns 0 and 2 swapped (the PINF loaders' convention).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import read_json
from ..camera import Camera
from ..errors import InputError, require_finite
from ..scene import GroundTruth, Scene, Source, Volume
from .assemble import Recording

# fields of info.json kept verbatim in scene.json's extra["pinf"] so a scene converts back exactly
KEPT_FIELDS = ("voxel_matrix", "voxel_scale", "near", "far", "render_center", "phi", "rot", "frame_bkg_color")
DEFAULT_SOURCE_RADIUS = 0.025  # metres; ScalarFlow's inflow is about 4.5 cm wide in every view


@dataclass(frozen=True)
class PinfCapture:
    recordings: dict[str, Recording]
    fps: float
    frame_count: int
    volume: Volume | None
    kept: dict


def read_pinf(info_path: str | Path) -> PinfCapture:
    """Parse an info.json; videos are looked up next to it."""
    info_path = Path(info_path)
    info = read_json(info_path)
    entries = [(f"{split}[{i}]", e) for split in ("train_videos", "test_videos")
               for i, e in enumerate(info.get(split, []))]
    if not entries:
        raise InputError(info_path, "train_videos", "no video entries")
    recordings, rates, counts = {}, set(), set()
    for fld, entry in entries:
        try:
            name, cam, rate, count = _entry(entry)
        except InputError as err:
            raise err.at(info_path, fld) from None
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(info_path, fld, f"malformed entry ({err!r})") from None
        recordings[name] = Recording(name, cam, info_path.parent / entry["file_name"])
        rates.add(rate)
        counts.add(count)
    if len(rates) != 1:
        raise InputError(info_path, "frame_rate", f"videos disagree on the frame rate: {sorted(rates)}")
    if len(counts) != 1:
        raise InputError(info_path, "frame_num", f"videos disagree on the frame count: {sorted(counts)}")
    kept = {k: info[k] for k in KEPT_FIELDS if k in info}
    return PinfCapture(recordings, rates.pop(), counts.pop(), _volume(info, info_path), kept)


def _entry(entry: dict) -> tuple[str, Camera, float, int]:
    h, w = (int(x) for x in entry["camera_hw"])
    cam = Camera.from_nerf(require_finite(entry["transform_matrix"], None, "transform_matrix"), w, h,
                           float(require_finite(entry["camera_angle_x"], None, "camera_angle_x")))
    return Path(entry["file_name"]).stem, cam, float(entry["frame_rate"]), int(entry["frame_num"])


def _volume(info: dict, path: Path) -> Volume | None:
    if "voxel_matrix" not in info or "voxel_scale" not in info:
        return None
    m = require_finite(info["voxel_matrix"], path, "voxel_matrix")
    s = require_finite(info["voxel_scale"], path, "voxel_scale")
    if m.shape != (4, 4) or s.shape != (3,):
        raise InputError(path, "voxel_matrix", "expected a 4x4 voxel_matrix and 3 voxel_scale values")
    R, t = m[:3, :3][:, [2, 1, 0]], m[:3, 3]
    corners = np.array([R @ (s * np.array(p, dtype=float)) + t for p in np.ndindex(2, 2, 2)])
    return Volume(tuple(corners.min(0)), tuple(corners.max(0)))


def source_at_volume_foot(volume: Volume | None, radius: float = DEFAULT_SOURCE_RADIUS) -> Source | None:
    """The inflow of a PINF capture: the bottom centre of its reconstruction box."""
    return None if volume is None else Source(tuple(float(x) for x in volume.bottom_center), radius)


def pinf_dict(scene: Scene, ground_truth: tuple[GroundTruth, ...]) -> dict:
    """A PINF info.json for a scene: views with footage are ``train_videos``, ground truth ``test_videos``."""

    def entry(name: str, camera: Camera, video: str) -> dict:
        nerf = camera.to_nerf()
        return {"file_name": video, "frame_rate": scene.fps, "frame_num": scene.frame_count,
                "camera_angle_x": nerf["camera_angle_x"], "camera_hw": [camera.height, camera.width],
                "transform_matrix": nerf["transform_matrix"]}

    out = {"train_videos": [entry(v.name, v.camera, v.video) for v in scene.usable_views()],
           "test_videos": [entry(g.name, g.camera, g.video) for g in ground_truth]}
    kept = dict(scene.extra.get("pinf", {}))
    if "voxel_matrix" not in kept and scene.volume is not None:
        lo, hi = np.asarray(scene.volume.min), np.asarray(scene.volume.max)
        m = np.eye(4)
        m[:3, :3] = np.eye(3)[:, [2, 1, 0]]  # columns swapped back, as the PINF loaders expect
        m[:3, 3] = lo
        kept.update(voxel_matrix=m.tolist(), voxel_scale=(hi - lo).tolist())
    out.update(kept)
    return out
