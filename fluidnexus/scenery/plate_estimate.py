"""One view's plate: a user's image, or estimated from its video (read the footage at a working scale, estimate,
bring the plate to full size)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..video import read_video
from .plates import NeverClear, PlateEstimate, clean_frames, estimate_plate

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
