"""PINF / HyFluid / ScalarFlow ``info.json``: read it into recordings, and write a scene back as one.

The file lists ``train_videos``, ``test_videos`` and ``val_videos``; each entry has ``file_name``,
``frame_rate``, ``frame_num``, ``camera_angle_x`` (horizontal FOV, radians), ``camera_hw`` = [H, W] and
``transform_matrix`` (camera-to-world, OpenGL axes), or ``transform_matrix_list`` (one such matrix per frame: a
camera that moves). The reconstruction box is ``world = R (voxel_scale * p) + t`` for p in [0, 1]^3, where
``R | t`` is ``voxel_matrix`` with its columns 0 and 2 swapped (the PINF loaders' convention) and ``voxel_scale``
is one number or three. ``rot`` names the world's up axis ("Y", the default, or "Z"); ``frame_bkg_color`` is the
backdrop colour. Import converts everything into the scene's world (metres, +y up) with one
:class:`~fluidnexus.world_frame.SourceFrame` (docs/calibration.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import read_json
from ..camera import Camera
from ..errors import InputError, require_finite
from ..scene import GroundTruth, Scene, Source, Volume
from ..scene_scale import SCALARFLOW_SOURCE_RADIUS, volume_factor
from ..world_frame import UP_AXES, SourceFrame
from .assemble import Recording

SPLITS = ("train_videos", "test_videos", "val_videos")
# fields of info.json kept verbatim in scene.json's extra["pinf"] so a scene converts back exactly
KEPT_FIELDS = ("voxel_matrix", "voxel_scale", "near", "far", "render_center", "phi", "rot")


@dataclass(frozen=True)
class PinfCapture:
    """An info.json converted into the scene's world (``frame`` maps the file's world onto it)."""

    recordings: dict[str, Recording]
    fps: float
    frame_count: int
    volume: Volume | None
    kept: dict
    frame: SourceFrame
    backdrop_color: tuple[float, float, float] | None


def read_pinf(info_path: str | Path, metres_per_unit: float = 1.0) -> PinfCapture:
    """Parse an info.json; videos are looked up next to it (a video is needed only once a role names it).

    Args:
        metres_per_unit: the length of one unit of the file's world, in metres.
    """
    info_path = Path(info_path)
    info = read_json(info_path)
    frame = SourceFrame.for_import(_up_axis(info, info_path), metres_per_unit)
    entries = []
    for split in SPLITS:
        items = info.get(split, [])
        if not isinstance(items, list):
            raise InputError(info_path, split, "expected a list of video entries")
        entries += [(f"{split}[{i}]", e) for i, e in enumerate(items)]
    if not entries:
        raise InputError(info_path, "train_videos", "no video entries")
    recordings, rates, counts = {}, set(), set()
    for fld, entry in entries:
        try:
            name, cam, poses, rate, count = _entry(entry)
        except InputError as err:
            raise err.at(info_path, fld) from None
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(info_path, fld, f"malformed entry ({err!r})") from None
        if name in recordings:
            raise InputError(info_path, f"{fld}.file_name", f"a second video named {name!r}")
        if poses is not None:
            poses = np.stack([frame.pose_to_scene(p) for p in poses])
        recordings[name] = Recording(name, frame.camera_to_scene(cam), info_path.parent / entry["file_name"], poses)
        rates.add(rate)
        counts.add(count)
    if len(rates) != 1:
        raise InputError(info_path, "frame_rate", f"videos disagree on the frame rate: {sorted(rates)}")
    if len(counts) != 1:
        raise InputError(info_path, "frame_num", f"videos disagree on the frame count: {sorted(counts)}")
    kept = {k: info[k] for k in KEPT_FIELDS if k in info}
    return PinfCapture(recordings, rates.pop(), counts.pop(), _volume(info, info_path, frame), kept, frame,
                       _backdrop(info, info_path))


def _up_axis(info: dict, path: Path) -> str:
    rot = info.get("rot", "Y")
    if not isinstance(rot, str) or rot.upper() not in UP_AXES:
        raise InputError(path, "rot", f"unknown up axis {rot!r}; expected one of {sorted(UP_AXES)} (absent: Y)")
    return rot.upper()


def _entry(entry: dict) -> tuple[str, Camera, np.ndarray | None, float, int]:
    """One video entry in the file's own world: name, camera (frame 0), per-frame poses or None, fps, frames."""
    h, w = (int(x) for x in entry["camera_hw"])
    fov = float(require_finite(entry["camera_angle_x"], None, "camera_angle_x"))
    count = int(entry["frame_num"])
    poses = None
    if "transform_matrix_list" in entry:  # a moving camera: one pose per frame (PINF's loaders prefer it)
        mats = require_finite(entry["transform_matrix_list"], None, "transform_matrix_list")
        if mats.ndim != 3 or len(mats) != count:
            raise InputError(None, "transform_matrix_list",
                             f"expected frame_num = {count} camera-to-world matrices, got shape {mats.shape}")
        cams = []
        for t, m in enumerate(mats):
            try:
                cams.append(Camera.from_nerf(m, w, h, fov))
            except InputError as err:
                raise err.at(None, f"transform_matrix_list[{t}]") from None
        cam, poses = cams[0], np.stack([c.w2c for c in cams])
    else:
        cam = Camera.from_nerf(require_finite(entry["transform_matrix"], None, "transform_matrix"), w, h, fov)
    return Path(entry["file_name"]).stem, cam, poses, float(entry["frame_rate"]), count


def _voxel_scale(info: dict, path: Path) -> np.ndarray:
    """``voxel_scale``: one number (the same on every axis) or three, all > 0."""
    value = info["voxel_scale"]
    s = require_finite(value, path, "voxel_scale")
    if s.shape not in ((), (1,), (3,)) or not np.all(s > 0):
        raise InputError(path, "voxel_scale", f"expected one number or three, all > 0, got {value!r}")
    return np.broadcast_to(s.reshape(-1), (3,)).astype(np.float64)


def _volume(info: dict, path: Path, frame: SourceFrame) -> Volume | None:
    if "voxel_matrix" not in info or "voxel_scale" not in info:
        return None
    m = require_finite(info["voxel_matrix"], path, "voxel_matrix")
    if m.shape != (4, 4):
        raise InputError(path, "voxel_matrix", f"expected a 4x4 matrix, got shape {m.shape}")
    s = _voxel_scale(info, path)
    R, t = m[:3, :3][:, [2, 1, 0]], m[:3, 3]
    corners = frame.to_scene([R @ (s * np.array(p, dtype=float)) + t for p in np.ndindex(2, 2, 2)])
    return Volume(tuple(float(v) for v in corners.min(0)), tuple(float(v) for v in corners.max(0)))


def _backdrop(info: dict, path: Path) -> tuple[float, float, float] | None:
    if info.get("frame_bkg_color") is None:
        return None
    c = require_finite(info["frame_bkg_color"], path, "frame_bkg_color")
    if c.shape != (3,) or not np.all((c >= 0) & (c <= 1)):
        raise InputError(path, "frame_bkg_color", f"expected 3 values in [0, 1], got {info['frame_bkg_color']!r}")
    return tuple(float(v) for v in c)


def source_at_volume_foot(volume: Volume | None, radius: float | None = None) -> Source | None:
    """The inflow of a PINF capture: the bottom centre of its reconstruction box, with ``radius`` metres or, without
    one, ScalarFlow's inflow radius (0.025 m, about 4.5 cm wide in every view) times the box's length scale
    (docs/scale.md: exactly 0.025 m on ScalarFlow)."""
    if volume is None:
        return None
    if radius is None:
        radius = SCALARFLOW_SOURCE_RADIUS * volume_factor(volume)
    return Source(tuple(float(x) for x in volume.bottom_center), radius)


def pinf_dict(scene: Scene, ground_truth: tuple[GroundTruth, ...]) -> dict:
    """A PINF info.json for a scene, in the scene's source frame (its ``source_frame``): views with footage are
    ``train_videos``, ground truth ``test_videos`` (a moving camera with ``transform_matrix_list``)."""
    frame = scene.source_frame or SourceFrame.identity()

    def entry(camera: Camera, video: str, poses=None) -> dict:
        nerf = frame.camera_from_scene(camera).to_nerf()
        out = {"file_name": video, "frame_rate": scene.fps, "frame_num": scene.frame_count,
               "camera_angle_x": nerf["camera_angle_x"], "camera_hw": [camera.height, camera.width],
               "transform_matrix": nerf["transform_matrix"]}
        if poses is not None:
            out["transform_matrix_list"] = [
                frame.camera_from_scene(Camera(camera.width, camera.height, camera.K, p)).to_nerf()["transform_matrix"]
                for p in poses]
        return out

    out = {"train_videos": [entry(v.camera, v.video) for v in scene.usable_views()],
           "test_videos": [entry(g.camera, g.video, g.poses) for g in ground_truth]}
    kept = dict(scene.extra.get("pinf", {}))
    if "voxel_matrix" not in kept and scene.volume is not None:
        corners = frame.from_scene([np.where(np.array(p, bool), scene.volume.max, scene.volume.min)
                                    for p in np.ndindex(2, 2, 2)])
        lo, hi = corners.min(0), corners.max(0)
        m = np.eye(4)
        m[:3, :3] = np.eye(3)[:, [2, 1, 0]]  # columns swapped back, as the PINF loaders expect
        m[:3, 3] = lo
        kept.update(voxel_matrix=m.tolist(), voxel_scale=(hi - lo).tolist())
    if scene.backdrop_color is not None:
        kept["frame_bkg_color"] = list(scene.backdrop_color)
    out.update(kept)
    return out
