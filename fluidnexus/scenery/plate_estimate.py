"""The plates of a scene (``fluidnexus background``): per input view a user's image, or one estimated from its
video (read the footage at a working scale, estimate, bring the plate to full size)."""
from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..progress import progress
from ..scene import SCENE_FILE
from ..video import read_video
from .plate_sheet import contact_sheet
from .plate_store import FOLDER, read_plate_file, write_backgrounds
from .plates import NeverClear, PlateEstimate, clean_frames, estimate_plate

log = logging.getLogger("fluidnexus")

AUTO_PIXELS = 250_000  # --resolution auto: the working scale keeps a frame at most this many pixels


def working_scale(text: str, width: int, height: int) -> float:
    """``--resolution``: ``auto`` or a factor in (0, 1] of the videos' size for the estimate's analysis."""
    if text == "auto":
        return min(1.0, math.sqrt(AUTO_PIXELS / (width * height)))
    try:
        value = float(text)
    except ValueError:
        raise InputError(None, "--resolution", f"expected a number in (0, 1] or 'auto', got {text!r}") from None
    if not 0 < value <= 1:
        raise InputError(None, "--resolution", f"expected a number in (0, 1] or 'auto', got {text!r}")
    return value


def estimate_view(name: str, video_path: Path, width: int, height: int, scale: float,
                  color: np.ndarray | None) -> tuple[PlateEstimate, np.ndarray]:
    """The plate of view ``name`` at ``width x height`` and one frame from the middle of its video.

    The estimate runs on frames read at ``scale``; clean frames, once found, are re-read at full size so that
    such a plate keeps the footage's own detail.

    Raises:
        InputError: the smoke never leaves any pixel of the view and no colour is known.
    """
    video = read_video(video_path, scale=None if scale == 1 else scale, channels=3)
    try:
        estimate = estimate_plate(video, color)
    except NeverClear as err:
        raise InputError(video_path, None, f"view {name!r}: the smoke never leaves any pixel ({err}), so its "
                                           f"backdrop cannot be estimated; give --plate {name}=FILE (an image of "
                                           "the empty backdrop) or --color R,G,B (its colour)") from None
    middle = video[len(video) // 2]
    if estimate.source == "clean-frames" and scale != 1:
        start, stop = estimate.detail["clean_frames"]
        estimate = clean_frames(read_video(video_path, frames=slice(start, stop), channels=3))
    estimate = estimate.resized(width, height)
    return PlateEstimate(estimate.plate, estimate.confidence, estimate.source,
                         {**estimate.detail, "scale": round(scale, 4)}), middle


def given_plate(file: Path, image: np.ndarray, video_path: Path, frame_count: int) -> tuple[PlateEstimate, np.ndarray]:
    """A user's plate ``image`` [H, W, 3] read from ``file``, used as is (confidence 1, source ``plate``), and the
    middle frame of the view's video (for the contact sheet)."""
    estimate = PlateEstimate(image, np.ones(image.shape[:2], np.float32), "plate", {"file": str(file)})
    middle = read_video(video_path, frames=slice(frame_count // 2, frame_count // 2 + 1), channels=3)[0]
    return estimate, middle

def given_plates(items: tuple[str, ...], scene, views) -> dict[str, tuple[Path, np.ndarray]]:
    """``--plate NAME=FILE``: each names an input view with footage once, and its image has that camera's size."""
    by_name = {v.name: v for v in views}
    out = {}
    for item in items:
        name, sep, file = item.partition("=")
        if not sep or not name or not file:
            raise InputError(None, "--plate", f"expected NAME=FILE, got {item!r}")
        if name not in by_name:
            kind = "not an input view with a video" if name in scene.view_names() else "an unknown view"
            raise InputError(None, "--plate", f"{name!r} is {kind}; plates are for the input views "
                                              f"{sorted(by_name)}")
        if name in out:
            raise InputError(None, "--plate", f"view {name!r} is given two plates")
        cam = by_name[name].camera
        out[name] = (Path(file), read_plate_file(file, cam.width, cam.height, "--plate",
                                                 f"view {name!r}'s camera (and video)"))
    return out


def estimate_plates(scene, plates: tuple[str, ...], known: np.ndarray | None, resolution: str,
                    overwrite: bool = False) -> dict[str, PlateEstimate]:
    """A plate for every input view of ``scene`` with footage, written into ``SCENE/backgrounds/`` with the contact
    sheet and recorded in scene.json (``fluidnexus background``). Per view, in order: an image of ``plates``
    (``NAME=FILE``), frames before any smoke, the backdrop colour ``known`` (default the scene's), otherwise a
    per-pixel estimate at ``resolution`` (``working_scale``). Ground-truth videos are never read."""
    views = [v for v in scene.with_role("input") if v.video is not None]
    if not views:
        raise InputError(scene.root / SCENE_FILE, "views", "the scene has no input view with a video")
    given = given_plates(plates, scene, views)
    if known is None and scene.backdrop_color is not None:
        known = np.asarray(scene.backdrop_color, np.float32)
    if (scene.backgrounds or (scene.root / FOLDER).exists()) and not overwrite:
        raise InputError(scene.root / FOLDER, None, "the scene already has plates; pass --overwrite to replace them")
    cam = views[0].camera
    scale = working_scale(resolution, cam.width, cam.height)
    estimates, rows = {}, []
    with progress("background", len(views)) as bar:
        for view in views:
            path = scene.video_path(view)
            if view.name in given:
                est, middle = given_plate(*given[view.name], path, scene.frame_count)
            else:
                est, middle = estimate_view(view.name, path, view.camera.width, view.camera.height, scale, known)
            estimates[view.name] = est
            rows.append((view.name, middle, est))
            bar.advance()
    write_backgrounds(scene, estimates, contact_sheet(rows))
    for name, est in estimates.items():
        log.info("background %s: %s, mean confidence %.2f", name, est.source, est.confidence.mean())
    log.info("wrote %d plates and %s into %s", len(estimates), "sheet.png", scene.root / FOLDER)
    return estimates
