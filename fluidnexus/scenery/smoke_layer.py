"""The smoke layer of a fixed camera's video, given its clean plate (docs/background.md, "Smoke layer for a single
video").

A frame is the smoke composited over the plate, ``I = A a + B (1 - a)`` per pixel (the haze model): ``B`` the plate
[H, W, C], ``a`` the smoke's opacity per pixel and frame, ``A`` the smoke's colour [C]. Per pixel these are C
equations in C + 1 unknowns, so one assumption is needed: **one smoke colour A for the whole video**. Given A, the
opacity is the least-squares solution over the channels, ``a = (I - B).(A - B) / |A - B|^2``, clipped to [0, 1],
and the smoke layer is what the smoke alone shows over black, premultiplied: ``S = A a``.

**The colour** is that of the densest smoke, taken as opaque (like the atmospheric light of dehazing, read off the
haziest pixels): among the samples (pixel, frame) that differ from a confident plate pixel (confidence >= 0.5) by
more than the noise floor, A is the per-channel median colour of the ``DENSE_FRACTION`` with the largest opacity
under A itself, found by a fixed-point iteration that starts from the samples farthest from their plate. The
samples farthest from the plate are not simply the densest (a sample over a backdrop far from A differs more at
the same opacity); the fixed point picks the samples that lie beyond all others along their line from B through A.
**Then no sample may be more than opaque**: a sample lies between its plate and A (``0 <= a <= 1``), so in gray
A is at least every sample that is brighter than its plate and at most every one that is darker. The gray of A is
moved out to the ``BEYOND`` quantile of the samples on each side (those differing from their plate by more than
``MIN_CHANGE`` in gray; quantiles for codec noise and plate errors; where the two bounds contradict each other the
side with more samples wins), along the line from the plate behind the densest smoke through the median: the
median of smoke that is never opaque is a mix of A and that plate, so A lies on that line, and the hue comes from
the median, not from a channel's extreme samples (which take a codec's chroma error). For smoke opaque somewhere
the bound is the median itself; for smoke that is never opaque it moves the colour towards A as far as the
footage proves (the brightest smoke over the brightest backdrop it crosses). What is left between
the bound and A is not identifiable from one video over a smooth backdrop: ``a (A - B)`` is what the footage
fixes; the layer then carries some of the backdrop's texture and is too bright or too dark. A user who knows the
smoke's colour (white steam) gives it instead (``color``; ``synth --smoke-color``).

**Ill-conditioned pixels**, where the plate is close to the smoke's colour (``|A - B| < MIN_CONTRAST``), do not
show the smoke: there the denominator is held at ``MIN_CONTRAST^2``, so noise is amplified at most
``1 / MIN_CONTRAST`` times and the opacity fades to 0 as B approaches A (such smoke is invisible in the footage and
stays faint in the layer). **Samples that barely differ from the plate** (no channel by more than the noise floor,
``max(MIN_CHANGE, NOISE_FACTOR x`` the video's frame-to-frame noise``)``) get opacity 0, so codec noise and small
plate errors leave no haze of the backdrop's texture in the layer.

Nothing assumes smoke brighter or darker than the backdrop: A above or below B is the same formula. Everything is
numpy, over chunks of frames (about ``CHUNK_VALUES`` values each) besides the returned arrays.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..images import resize_image, to_channels
from .plate_store import read_plate
from .plates import CONFIDENT, MIN_CHANGE, NOISE_FACTOR, noise_level

log = logging.getLogger("fluidnexus")

MIN_CONTRAST = 0.1  # |A - B| (Euclidean over the channels, [0, 1] units) below which a pixel is ill-conditioned
DENSE_FRACTION = 0.01  # share of the smoke samples taken as the densest smoke
MIN_DENSE = 16  # ... and at least this many
POOL = 200_000  # smoke samples kept (evenly spread over the video) to estimate the colour
ITERATIONS = 20  # fixed-point iterations for the colour, at most
TOLERANCE = 1e-4  # ... stopping once no channel moves by more
BEYOND = 0.999  # in gray, the colour lies beyond this share of the samples on its side of their plate
CHUNK_VALUES = 1 << 24  # float32 values per chunk of frames (64 MB)


class NoSmoke(Exception):
    """No sample of the video differs from the plate by more than the noise floor."""


@dataclass(frozen=True)
class SmokeLayer:
    """The smoke of a video, separated from its plate.

    Attributes:
        layer: [T, H, W, C] float32 in [0, 1], the smoke over black, premultiplied: ``S = A a``.
        alpha: [T, H, W] float32 in [0, 1], the smoke's opacity ``a``.
        color: [C] float32 in [0, 1], the smoke's colour ``A``.
        ill_conditioned: share of the pixels whose plate is within ``MIN_CONTRAST`` of ``A``.
        noise_floor: a sample differing from the plate by less than this in every channel has opacity 0.
    """

    layer: np.ndarray
    alpha: np.ndarray
    color: np.ndarray
    ill_conditioned: float
    noise_floor: float

    def summary(self) -> dict:
        """The colour and the two facts above, for scene.json."""
        return {"smoke_color": [round(float(c), 4) for c in self.color],
                "ill_conditioned_fraction": round(self.ill_conditioned, 4), "noise_floor": round(self.noise_floor, 4)}


def smoke_layer(video: np.ndarray, plate: np.ndarray, confidence: np.ndarray,
                color: np.ndarray | None = None) -> SmokeLayer:
    """Separate the smoke of ``video`` from its clean plate (module docstring).

    Args:
        video: [T, H, W, C] float32 in [0, 1], a fixed camera's frames.
        plate: [H, W, C] float32 in [0, 1], its clean plate.
        confidence: [H, W] in [0, 1], the plate's confidence; only confident pixels (>= 0.5) estimate the colour,
            unless too few of them show smoke.
        color: [C] the smoke's colour A when the user knows it (white steam: 1); None: the densest smoke's.

    Raises:
        NoSmoke: the video never differs from the plate by more than the noise floor.
    """
    if video.shape[1:] != plate.shape or confidence.shape != plate.shape[:2]:
        raise ValueError(f"video {video.shape}, plate {plate.shape} and confidence {confidence.shape} do not match")
    plate = np.asarray(plate, np.float32)
    floor, chunk = _floor(video), _chunk(plate)
    samples = _smoke_samples(video, plate, confidence >= CONFIDENT, floor, chunk)  # NoSmoke when there is none
    color = _dense_color(*samples) if color is None else np.asarray(color, np.float32).reshape(plate.shape[-1])
    step = color - plate  # [H, W, C]
    contrast2 = (step * step).sum(axis=-1)
    weight = step / np.maximum(contrast2, MIN_CONTRAST ** 2)[..., None]
    alpha = np.empty(video.shape[:3], np.float32)
    layer = np.empty(video.shape, np.float32)
    for start in range(0, len(video), chunk):
        diff = video[start:start + chunk] - plate
        a = (diff * weight).sum(axis=-1)
        a[np.abs(diff).max(axis=-1) < floor] = 0
        alpha[start:start + chunk] = np.clip(a, 0, 1)
        layer[start:start + chunk] = alpha[start:start + chunk, ..., None] * color
    return SmokeLayer(layer, alpha, color, float((contrast2 < MIN_CONTRAST ** 2).mean()), floor)


def smoke_color(videos: list[np.ndarray], plates: list[np.ndarray], confidences: list[np.ndarray]) -> np.ndarray:
    """[C] the colour of the densest smoke over several views of one smoke (module docstring; the views' smoke
    samples pooled, so every view gets the one colour): arguments as :func:`smoke_layer`'s, a list each.

    Raises:
        NoSmoke: no view differs from its plate by more than its noise floor.
    """
    images, backs = [], []
    for video, plate, confidence in zip(videos, plates, confidences):
        try:
            image, back = _smoke_samples(video, np.asarray(plate, np.float32), confidence >= CONFIDENT,
                                         _floor(video), _chunk(plate))
        except NoSmoke:
            continue
        images.append(image)
        backs.append(back)
    if not images:
        raise NoSmoke("no view differs from its plate by more than its noise floor in any frame")
    return _dense_color(np.concatenate(images), np.concatenate(backs))


def _floor(video: np.ndarray) -> float:
    """A sample differing from its plate by less than this in every channel shows no smoke (module docstring)."""
    return max(MIN_CHANGE, NOISE_FACTOR * noise_level(video))


def _chunk(plate: np.ndarray) -> int:
    """Frames per chunk: about ``CHUNK_VALUES`` values of a video of ``plate``'s size."""
    return max(1, CHUNK_VALUES // plate.size)


def _smoke_samples(video: np.ndarray, plate: np.ndarray, confident: np.ndarray, floor: float,
                   chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """Samples (I, B), each [N, C], that differ from the plate by at least ``floor`` in some channel: up to
    ``POOL`` of them, evenly spread over each chunk of frames; only those at ``confident`` pixels unless fewer than
    ``MIN_DENSE`` of them are."""
    pixels = plate.shape[0] * plate.shape[1]
    flat_plate, flat_confident = plate.reshape(pixels, -1), confident.ravel()
    images, kept = [], []
    for start in range(0, len(video), chunk):
        frames = video[start:start + chunk]
        idx = np.flatnonzero(np.abs(frames - plate).max(axis=-1) >= floor)
        idx = idx[::max(1, math.ceil(len(idx) * len(video) / (POOL * len(frames))))]
        images.append(frames.reshape(-1, plate.shape[-1])[idx])
        kept.append(idx % pixels)
    image, pixel = np.concatenate(images), np.concatenate(kept)
    if not len(image):
        raise NoSmoke(f"no pixel differs from the plate by {floor:.3f} or more in any frame")
    sure = flat_confident[pixel]
    if sure.sum() >= MIN_DENSE:
        image, pixel = image[sure], pixel[sure]
    return image, flat_plate[pixel]


def _dense_color(image: np.ndarray, back: np.ndarray) -> np.ndarray:
    """[C] the colour of the densest smoke among samples ``image`` over ``back`` ([N, C] each): the fixed point of
    "the median of the ``DENSE_FRACTION`` samples with the largest opacity under this colour" (module docstring),
    started from the samples farthest from their plate, then moved out to the samples' bound
    (:func:`_beyond_samples`)."""
    count = min(len(image), max(MIN_DENSE, math.ceil(DENSE_FRACTION * len(image))))
    dense = np.argpartition(-np.linalg.norm(image - back, axis=1), count - 1)[:count]
    color, behind = np.median(image[dense], axis=0), np.median(back[dense], axis=0)
    for _ in range(ITERATIONS):
        step = color - back
        contrast2 = (step * step).sum(axis=1)
        usable = np.flatnonzero(contrast2 >= MIN_CONTRAST ** 2)
        if len(usable) < count:
            break
        alpha = ((image[usable] - back[usable]) * step[usable]).sum(axis=1) / contrast2[usable]
        dense = usable[np.argpartition(-alpha, count - 1)[:count]]
        new = np.median(image[dense], axis=0)
        moved = float(np.abs(new - color).max())
        color, behind = new, np.median(back[dense], axis=0)
        if moved < TOLERANCE:
            break
    return _beyond_samples(color, behind, image, back).astype(np.float32)


def _beyond_samples(color: np.ndarray, behind: np.ndarray, image: np.ndarray, back: np.ndarray) -> np.ndarray:
    """[C] ``color`` (the densest smoke's, over the plate colour ``behind``) moved out along the line from
    ``behind`` through it, so that all but ``1 - BEYOND`` of the samples lie between their plate and it in gray
    (module docstring): its gray at least the ``BEYOND`` quantile of the samples brighter than their plate by more
    than ``MIN_CHANGE`` and at most the ``1 - BEYOND`` quantile of those darker; contradicting bounds: the side
    with more samples. Clipped to [0, 1]."""
    gray, plate = to_channels(image, 1)[:, 0], to_channels(back, 1)[:, 0]
    above, below = gray[gray - plate > MIN_CHANGE], gray[gray - plate < -MIN_CHANGE]
    low = np.quantile(above, BEYOND) if len(above) >= MIN_DENSE else -np.inf
    high = np.quantile(below, 1 - BEYOND) if len(below) >= MIN_DENSE else np.inf
    now, base = float(to_channels(color, 1)[0]), float(to_channels(behind, 1)[0])
    if low <= high:
        target = min(max(now, low), high)
    else:
        target = low if len(above) >= len(below) else high
    if target == now or abs(now - base) < MIN_CHANGE:  # within the bounds, or no gray to scale along
        return np.asarray(color, np.float64)
    return np.clip(behind + (color - behind) * (target - base) / (now - base), 0.0, 1.0)


def view_smoke_layer(scene, view, footage: np.ndarray, color: np.ndarray | None) -> tuple[np.ndarray, dict]:
    """The smoke layer of ``view``'s footage [T, h, w, C] over its plate (docs/background.md, "Smoke layer for a
    single video"), premultiplied over black, and its provenance record; ``color`` [3]: the smoke's colour as the
    user gives it (None: estimated). InputError naming the video when it shows no smoke over its plate."""
    plate, confidence = read_plate(scene, view.name)
    height, width = footage.shape[1:3]
    plate = to_channels(resize_image(plate, width, height), footage.shape[-1])
    confidence = resize_image(confidence[..., None], width, height)[..., 0]
    record = scene.backgrounds[view.name].plate
    known = None if color is None else to_channels(color, footage.shape[-1])
    try:
        smoke = smoke_layer(footage, plate, confidence, known)
    except NoSmoke as err:
        raise InputError(scene.video_path(view), None, f"shows no smoke over its plate {record} ({err})") from None
    log.info("synth: smoke layer of %s over %s: colour %s, ill-conditioned pixels %.1f%%", view.name, record,
             smoke.summary()["smoke_color"], 100 * smoke.ill_conditioned)
    return smoke.layer, {"over": "black", "input_plate": record, **smoke.summary(),
                         "smoke_color_from": "estimated" if color is None else "--smoke-color"}
