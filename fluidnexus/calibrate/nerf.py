"""NeRF ``transforms.json`` (Blender / instant-ngp / nerfstudio keys): one view per ``frames`` entry.

Each entry's ``file_path`` (relative to the JSON file, extension optional) is that view's footage: a video file
or a folder of frames. Intrinsics come from ``fl_x``/``fl_y``/``cx``/``cy`` when present, else from
``camera_angle_x``; per-frame values win over top-level ones. ``w``/``h`` default to the footage's size.
"""
from __future__ import annotations

from pathlib import Path

from ..atomic import read_json
from ..errors import InputError
from ..camera import Camera
from ..video import VIDEO_SUFFIXES, probe_video
from .assemble import Recording

MEDIA_SUFFIXES = ("",) + VIDEO_SUFFIXES
INTRINSIC_KEYS = ("camera_angle_x", "fl_x", "fl_y", "cx", "cy", "w", "h")


def find_media(base: Path) -> Path | None:
    """``base`` itself (a video file or a frame folder), or ``base`` with a video suffix, if it exists."""
    for suffix in MEDIA_SUFFIXES:
        candidate = base.with_name(base.name + suffix) if suffix else base
        if candidate.exists():
            return candidate
    return None


def read_nerf(path: str | Path) -> tuple[dict[str, Recording], float | None]:
    """Parse a transforms.json into recordings; also return its ``fps`` if it states one."""
    path = Path(path)
    data = read_json(path)
    frames = data.get("frames")
    if not isinstance(frames, list) or not frames:
        raise InputError(path, "frames", "missing or empty")
    recordings = {}
    for i, frame in enumerate(frames):
        fld = f"frames[{i}]"
        if not isinstance(frame, dict) or "file_path" not in frame or "transform_matrix" not in frame:
            raise InputError(path, fld, "needs file_path and transform_matrix")
        media = find_media(path.parent / frame["file_path"])
        name = Path(frame["file_path"]).stem
        if name in recordings:
            name = f"{name}_{i}"
        intr = {k: frame.get(k, data.get(k)) for k in INTRINSIC_KEYS}
        if intr["w"] is None or intr["h"] is None:
            if media is None:
                raise InputError(path, f"{fld}.file_path", f"{frame['file_path']!r} not found, and no w/h given")
            info = probe_video(media)
            intr["w"], intr["h"] = info.width, info.height
        try:
            camera = Camera.from_nerf(frame["transform_matrix"], int(intr["w"]), int(intr["h"]),
                                      intr["camera_angle_x"], intr["fl_x"], intr["fl_y"], intr["cx"], intr["cy"])
        except InputError as err:
            raise err.at(path, fld) from None
        recordings[name] = Recording(name, camera, media)
    fps = data.get("fps")
    return recordings, (float(fps) if fps is not None else None)
