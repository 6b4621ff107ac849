"""When the source emits: the scene's declared emission window, or when new smoke starts and stops appearing at the
source in the footage (docs/diagnose.md, "Bursts: sources that stop").

The footage rule: in each view, the smoke in a small region around the projected source (the source disk's
column up to one source radius above it, as wide as the disk) is summed per frame and divided by its largest
value; the views' mean is the source signal. A source that keeps emitting keeps that region replenished; one that
stops lets it empty as the last smoke rises away. The source is taken to have stopped when the signal stays below
:data:`EMPTY` from some frame to the last one, for at least :data:`MIN_EMPTY_FRAMES` frames; the stop is where the
fall into that empty stretch begins in earnest (:func:`stop_from_footage`). Otherwise it emits to the end. In the
same way it starts late when the signal stays below :data:`EMPTY` from the first frame for at least
:data:`MIN_EMPTY_FRAMES` frames before it rises: the start is where that rise begins in earnest
(:func:`start_from_footage`). Otherwise it emits from the first observed frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluidnexus.scene import in_window

from .observe import Observed

#: The source region counts as emptied below this fraction of its peak smoke (a continuous plume's region holds
#: 0.8-1.0 of its peak once filled; a burst's falls below 0.5 within 4-6 frames of the stop, docs/diagnose.md).
EMPTY = 0.5
#: ... for at least this many frames up to the last one (a single dark frame at the end is not a stop).
MIN_EMPTY_FRAMES = 3
#: The stop is the first frame of the final decline that falls by at least this fraction of its steepest fall.
STEEP = 0.5


@dataclass(frozen=True)
class Emission:
    """The emission window [start, stop) in scene frames (stop None: to the end) and where it came from
    (``scene``: declared as ``source.window``; ``footage``: found by :func:`start_from_footage` and
    :func:`stop_from_footage`)."""

    start: int
    stop: int | None
    source: str

    def emits_at(self, frame: int) -> bool:
        """Whether the step into scene frame ``frame`` emits (scene.Source.emits_at's convention)."""
        return in_window((self.start, self.stop), frame)

    def to_dict(self) -> dict:
        return {"window": [self.start, self.stop], "from": self.source}


def emission_window(source, observed: Observed, center, radius: float) -> Emission:
    """The scene's declared window if ``source`` (scene.Source or None) has one, else the footage's: emitting from
    :func:`start_from_footage` until :func:`stop_from_footage`. ``center``, ``radius``: the source disk [m]."""
    if source is not None and source.window is not None:
        return Emission(source.window[0], source.window[1], "scene")
    direction = source.direction if source is not None else (0.0, 1.0, 0.0)
    signal = source_signal(observed, center, radius, direction)
    stop = stop_from_footage(signal)
    return Emission(observed.first + start_from_footage(signal), None if stop is None else observed.first + stop,
                    "footage")


def source_signal(observed: Observed, center, radius: float, direction=(0.0, 1.0, 0.0)) -> np.ndarray:
    """The smoke at the source per frame [T]: in each view the image sum over the pixels within the projected
    source radius of the source's column (from the disk's centre to one radius along ``direction``), divided by
    its largest value over the frames; the mean over views."""
    column = np.asarray(center, float) + np.outer(np.linspace(0.0, 1.0, 5), np.asarray(direction, float) * radius)
    signals = []
    for cam, images in zip(observed.cameras, observed.images):
        uv, depth = cam.project(column)
        r_px = max(1.0, cam.K[0, 0] * radius / float(np.mean(depth)))
        ys, xs = np.mgrid[0:cam.height, 0:cam.width] + 0.5
        near = np.min(np.hypot(xs[..., None] - uv[:, 0], ys[..., None] - uv[:, 1]), -1) <= r_px
        s = images[:, near].sum(-1)
        signals.append(s / max(float(s.max()), 1e-12))
    return np.mean(signals, 0)


def stop_from_footage(signal: np.ndarray) -> int | None:
    """Index of the first frame without new smoke from a source signal [T] (:func:`source_signal`), or None when
    the source emits to the end. The signal must stay below :data:`EMPTY` x its peak over the last
    :data:`MIN_EMPTY_FRAMES` frames at least. The fall into that empty stretch is the signal's last monotone
    decline; the stop is the first frame of it that falls by at least :data:`STEEP` x its steepest per-frame fall
    (a continuous plume's region also drains slowly once filled; a stopped source's falls fast)."""
    signal = np.asarray(signal, float)
    full = np.flatnonzero(signal >= EMPTY * max(float(signal.max()), 1e-12))
    if not len(full) or full[-1] > len(signal) - 1 - MIN_EMPTY_FRAMES:
        return None
    empty = int(full[-1]) + 1  # the first frame of the empty stretch
    falls = signal[:-1] - signal[1:]  # falls[t - 1]: the fall into frame t
    peak = empty
    while peak > 0 and falls[peak - 1] > 0:
        peak -= 1
    decline = falls[peak:empty]  # the falls into frames peak + 1 .. empty
    return peak + 1 + int(np.argmax(decline >= STEEP * decline.max()))


def start_from_footage(signal: np.ndarray) -> int:
    """Index of the first frame with new smoke from a source signal [T] (:func:`source_signal`). Up to the first
    frame at :data:`EMPTY` x the peak, the steep part of the rise is the steepest per-frame rise and the frames
    before it that rise by at least :data:`STEEP` x as much (smoke drifting in from elsewhere rises slowly, a
    source switching on fast); its first frame is the start when at least :data:`MIN_EMPTY_FRAMES` frames come
    before it, else 0 (a source on from the first frame rises at once, however long the region takes to fill)."""
    signal = np.asarray(signal, float)
    full = np.flatnonzero(signal >= EMPTY * max(float(signal.max()), 1e-12))
    if not len(full) or full[0] == 0:
        return 0
    rises = signal[1:int(full[0]) + 1] - signal[:int(full[0])]  # rises[t - 1]: the rise into frame t
    start = int(np.argmax(rises)) + 1
    while start > 1 and rises[start - 2] >= STEEP * rises.max():
        start -= 1
    return start if start >= MIN_EMPTY_FRAMES else 0
