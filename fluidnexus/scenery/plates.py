"""Clean-plate estimators: the static backdrop of a fixed camera from its own footage.

A video is [T, H, W, 3] float32 in [0, 1] (docs/conventions.md). Every estimator returns a :class:`PlateEstimate`:
the plate [H, W, 3], a confidence [H, W] in [0, 1] and the name of the source used. :func:`estimate_plate` tries
the sources in order:

1. ``clean-frames``: the leading frames before the first significant change, if they agree with the backdrop the
   rest of the video shows (the per-pixel median of those frames).
2. ``color``: a known backdrop colour (PINF's ``frame_bkg_color``, ``--color``), kept wherever the pixel shows that
   colour at a quiet moment; elsewhere (static objects in front of the backdrop) the temporal estimate.
3. ``temporal``: per pixel, the mode of the values at quiet moments (Okabe, Anjyo, Onai 2011, "Extracting fluid
   from a video for efficient post-production": the background is seen where a pixel shows little temporal
   change). The mode is symmetric in brightness, so smoke brighter or darker than the backdrop is the same case.
   Where smoke arrives after frame 0 and stays (a plume's foot), the mode is the smoke; frame 0 is kept there
   when it is the less smoky of the two (:func:`first_frame_where_smoke_stays`). The sources above use this
   corrected estimate too (the colour source for its static objects).

Nothing here assumes bright smoke on a dark backdrop or the reverse; thresholds follow the video's own noise.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

MIN_CHANGE = 0.02  # smallest temporal change (per channel, [0, 1] units) ever counted as motion
MIN_DIFFERENCE = 0.05  # smallest colour difference ever counted as "not the backdrop"
NOISE_FACTOR = 3.0  # thresholds are at least this many times the video's frame-to-frame noise
MAX_NOISE = 0.015  # about 4 levels of 8-bit footage: larger typical changes are motion, not noise
MODE_BINS = 32  # brightness histogram bins for the per-pixel mode
MEAN_SHIFT_STEPS = 3
FULL_SUPPORT = 0.2  # a pixel seen quiet and consistent in this share of the frames is fully confident
MIN_SAMPLES = 3  # ... and in at least this many frames
CONFIDENT = 0.5  # confidence from which a pixel counts as "seen"
MIN_SEEN_FRACTION = 0.01  # below this share of seen pixels a view has no usable temporal estimate
CHANGED_FRACTION = 0.002  # a frame with this share of pixels changed from frame 0 ends the clean prefix
MAX_DISAGREEMENT = 0.02  # clean frames may disagree with the seen backdrop at this share of its pixels
MIN_CLEAN_FRAMES = 2  # fewer leading still frames are no evidence of an empty backdrop
MAX_MOVING = 0.01  # clean frames (but the last, which sees the smoke arrive) are still at all but this share
CLEAR_RING = 0.99  # an object is clear in frame 0 when frame 0 shows the backdrop's colour on this share around it
SIGN_AGREEMENT = 2 / 3  # smoke brightens (or darkens) the backdrop when this share of its pixels agree on it


@dataclass(frozen=True)
class PlateEstimate:
    """A view's backdrop.

    Attributes:
        plate: [H, W, 3] float32 in [0, 1].
        confidence: [H, W] float32 in [0, 1]: 1 where the backdrop is known (given, seen clean), low where the
            pixel was never seen unoccluded.
        source: ``plate``, ``clean-frames``, ``color`` or ``temporal``.
        detail: facts about the estimate for the scene record (e.g. the clean frame range).
    """

    plate: np.ndarray
    confidence: np.ndarray
    source: str
    detail: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """Confidence statistics and the estimate's facts, for scene.json."""
        return {"mean_confidence": round(float(self.confidence.mean()), 4),
                "seen_fraction": round(float((self.confidence >= CONFIDENT).mean()), 4), **self.detail}

    def resized(self, width: int, height: int) -> "PlateEstimate":
        if self.plate.shape[:2] == (height, width):
            return self
        plate = cv2.resize(self.plate, (width, height), interpolation=cv2.INTER_LINEAR)
        conf = cv2.resize(self.confidence, (width, height), interpolation=cv2.INTER_LINEAR)
        return PlateEstimate(np.clip(plate, 0, 1), np.clip(conf, 0, 1), self.source, self.detail)


class NeverClear(Exception):
    """No pixel of the video is quiet and consistent often enough to show its backdrop."""


# ---- the sources, in order -------------------------------------------------------------------------------
def estimate_plate(video: np.ndarray, color: np.ndarray | None = None) -> PlateEstimate:
    """The backdrop of one fixed camera's video: clean frames, else a known colour, else the temporal mode.

    Args:
        video: [T, H, W, 3] float32 in [0, 1].
        color: [3] the known backdrop colour in [0, 1], or None.

    Raises:
        NeverClear: no clean frames, no colour, and the smoke never leaves any pixel (too few seen pixels).
    """
    noise = noise_level(video)
    quiet = quiet_mask(video, noise)
    temporal = first_frame_where_smoke_stays(video, temporal_mode(video, quiet, noise), noise)
    first_change = clean_prefix(video, noise)
    still = quiet[:first_change] if first_change == len(video) else quiet[:first_change - 1]
    if _is_clean(video[:first_change], still, temporal, noise):
        return clean_frames(video[:first_change], noise)
    if color is not None:
        return color_plate(video, quiet, temporal, np.asarray(color, np.float32), noise)
    if float((temporal.confidence >= CONFIDENT).mean()) < MIN_SEEN_FRACTION:
        raise NeverClear(f"{(temporal.confidence >= CONFIDENT).mean():.2%} of the pixels are ever seen clear")
    return temporal


def clean_frames(frames: np.ndarray, noise: float | None = None) -> PlateEstimate:
    """The per-pixel median of frames known to show no smoke; confidence 1 where they agree with it."""
    noise = noise_level(frames) if noise is None else noise
    plate = np.median(frames, axis=0).astype(np.float32)
    spread = np.abs(frames - plate).max(axis=3).mean(axis=0)
    conf = (spread < _difference(noise)).astype(np.float32)
    return PlateEstimate(plate, conf, "clean-frames", {"clean_frames": [0, len(frames)]})


def color_plate(video: np.ndarray, quiet: np.ndarray, temporal: PlateEstimate, color: np.ndarray,
                noise: float) -> PlateEstimate:
    """A known backdrop colour where the pixel shows it at quiet moments or in the first frame; the temporal
    mode where it never does and is a static object: confidently something else, or an unsure pixel inside the
    convex hull of such a region (smoke that often passes in front of an object leaves holes in it; those take
    the object's values from its confident pixels around them); the colour, with the temporal confidence,
    elsewhere.

    The first frame counts on its own: a static object stands in every frame, so a pixel that shows the
    backdrop's colour in frame 0, and most of its 8 neighbours with it, has the backdrop behind whatever covers it
    later. Steady smoke that arrives in frame 1 or 2 (a plume from frame 0) is quiet and confident for the rest
    of the video, and without this rule it became a static object in the plate. For the same reason an object
    that frame 0 shows clear of smoke (:func:`clear_in_first_frame`) takes frame 0's value where the temporal mode
    differs from it (smoke that covers the object in most frames)."""
    tol = _difference(noise)
    shown = np.zeros(video.shape[1:3], np.int32)
    for t in range(len(video)):
        shown += quiet[t] & (np.abs(video[t] - color).max(axis=2) < tol)
    color_first = np.abs(video[0] - color).max(axis=2) < tol
    around = cv2.boxFilter(color_first.astype(np.float32), -1, (3, 3), normalize=False,
                           borderType=cv2.BORDER_REPLICATE)
    first = color_first & (around >= 5)  # with most of its 3 x 3 window: not a lone pixel, but an object's rim too
    seen_color = (shown >= max(2, round(0.02 * len(video)))) | first
    core = ~seen_color & (temporal.confidence >= CONFIDENT)
    obj = core | (~seen_color & hulls(core))
    inside = fill_unseen(temporal.plate, core, video) if core.any() else temporal.plate  # unsure: from the core
    plate = np.where(core[..., None], temporal.plate, np.where(obj[..., None], inside, color[None, None, :]))
    # where frame 0 agrees with the temporal mode, the mode (a mean over many frames) is the quieter value
    clear = clear_in_first_frame(obj, color_first) & (np.abs(video[0] - plate).max(axis=2) >= tol)
    plate = np.where(clear[..., None], video[0], plate).astype(np.float32)
    conf = np.where(seen_color | clear, 1.0, temporal.confidence).astype(np.float32)
    detail = {"color": [round(float(c), 6) for c in color], "object_fraction": round(float(obj.mean()), 4),
              "objects_from_first_frame": round(float(clear.mean()), 4)}
    return PlateEstimate(plate, conf, "color", detail)


def first_frame_where_smoke_stays(video: np.ndarray, temporal: PlateEstimate, noise: float) -> PlateEstimate:
    """The temporal estimate with frame 0's value (confidence 1) where the mode is smokier than frame 0.

    Smoke that reaches a pixel after frame 0 and stays there (a continuous plume's foot, a jet's core) is quiet and
    consistent for most of the video, so the mode takes it for the backdrop; the backdrop was seen once, in frame 0.
    Smoke changes the backdrop one way, measured on the pixels that depart from the mode in frames 1 on (outside
    the pixels where frame 0 and the mode disagree): absorbing smoke over a bright backdrop darkens it, glowing smoke
    brightens it, trusted when ``SIGN_AGREEMENT`` of those pixels agree. Coloured smoke may brighten one backdrop
    and darken another; then the way is towards the smoke's colour (:func:`_smoke_colour`: where the lines along
    which those pixels depart meet), trusted when ``SIGN_AGREEMENT`` of them depart towards it. Where frame 0 and
    the mode disagree and the mode is the one changed that way (the brighter, the darker, or the nearer the
    smoke's colour), frame 0 is the backdrop. Where frame 0 holds smoke that leaves later, it is frame 0 that is
    changed that way and the mode is kept."""
    tol = _difference(noise)
    plate = temporal.plate
    differs = np.abs(video[0] - plate).max(axis=2) >= tol
    brightness = plate.mean(axis=2)
    brighter = darker = 0
    for frame in video[1:]:
        departs = (np.abs(frame - plate).max(axis=2) >= tol) & ~differs
        change = frame.mean(axis=2)[departs] - brightness[departs]
        brighter += int((change > 0).sum())
        darker += int((change < 0).sum())
    if max(brighter, darker) >= SIGN_AGREEMENT * max(brighter + darker, 1):
        sign = 1.0 if brighter > darker else -1.0
        take = differs & (sign * (brightness - video[0].mean(axis=2)) > 0)
        way = "brightness"
    else:
        colour = _smoke_colour(video, plate, differs, tol)
        if colour is None:
            return temporal
        take = differs & (np.linalg.norm(plate - colour, axis=2) < np.linalg.norm(video[0] - colour, axis=2))
        way = "colour"
    if not take.any():
        return temporal
    return PlateEstimate(np.where(take[..., None], video[0], plate).astype(np.float32),
                         np.where(take, 1.0, temporal.confidence).astype(np.float32), "temporal",
                         {**temporal.detail, "first_frame_fraction": round(float(take.mean()), 4),
                          "smoke_changes": way})


def _smoke_colour(video: np.ndarray, plate: np.ndarray, differs: np.ndarray, tol: float) -> np.ndarray | None:
    """[3] the colour smoke pulls a pixel towards, from the pixels that depart from the backdrop ``plate`` in frames
    1 on (outside ``differs``): in the haze model ``I = B (1 - a) + A a`` every departure lies on the line from its
    backdrop towards the smoke's colour A, so A is the point nearest all those lines (least squares: the sum over
    lines of the projections across them, accumulated frame by frame). None where the lines do not fix a point (all
    parallel: smoke and backdrops of one hue), under ``SIGN_AGREEMENT`` of the pixels depart towards it, or the
    video is not RGB."""
    if video.shape[-1] != 3:
        return None
    def departures(frame):
        departs = (np.abs(frame - plate).max(axis=2) >= tol) & ~differs
        b = plate[departs].astype(np.float64)
        step = frame[departs].astype(np.float64) - b
        length = np.linalg.norm(step, axis=1)
        ok = length > 0
        return b[ok], step[ok] / length[ok, None]

    m, rhs = np.zeros((3, 3)), np.zeros(3)
    for frame in video[1:]:  # sum of (I - u u^T) and of (I - u u^T) b over every departing pixel
        b, u = departures(frame)
        m += len(u) * np.eye(3) - u.T @ u
        rhs += b.sum(axis=0) - ((u * b).sum(axis=1)[:, None] * u).sum(axis=0)
    eig = np.linalg.eigvalsh(m)
    if eig[-1] <= 0 or eig[0] < 1e-3 * eig[-1]:
        return None
    colour = np.linalg.solve(m, rhs)
    towards = total = 0
    for frame in video[1:]:
        b, u = departures(frame)
        towards += int((((colour - b) * u).sum(axis=1) > 0).sum())
        total += len(u)
    return colour if towards >= SIGN_AGREEMENT * max(total, 1) else None


def clear_in_first_frame(obj: np.ndarray, color_first: np.ndarray) -> np.ndarray:
    """[H, W] bool: the static objects (connected parts of ``obj``) that frame 0 shows clear of smoke, because
    frame 0 shows the backdrop's colour (``color_first``) on at least ``CLEAR_RING`` of a ring two to three pixels
    out from them (the pixel next to an object is its rim, blurred by the codec). Smoke that covers an object in
    most frames (a jet blown at it) would otherwise give the object the smoke's colour in the plate; in frame 0
    nothing is near it yet. Smoke over the object in frame 0 reaches past it, into the ring."""
    count, labels = cv2.connectedComponents(obj.astype(np.uint8), connectivity=8)
    out = np.zeros(obj.shape, bool)
    near = cv2.dilate(obj.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    for k in range(1, count):
        part = labels == k
        ring = cv2.dilate(part.astype(np.uint8), kernel).astype(bool) & ~near
        if ring.any() and color_first[ring].mean() >= CLEAR_RING:
            out |= part
    return out


def temporal_mode(video: np.ndarray, quiet: np.ndarray, noise: float) -> PlateEstimate:
    """Per pixel, the mode of the values at quiet moments (a brightness histogram's peak, refined by a few
    mean-shift steps in RGB); confidence = support x agreement, where support is the share of frames in the
    mode (full at ``FULL_SUPPORT`` of the frames, at least ``MIN_SAMPLES``) and agreement the share of the quiet
    samples that lie in it. Pixels never quiet are filled from their neighbours with confidence 0."""
    t_count = len(video)
    bins = _mode_bins(video, quiet)
    centre = _masked_mean(video, lambda t: quiet[t] & (np.abs(_brightness_bin(video[t]) - bins) <= 1))
    radius = _difference(noise)
    for _ in range(MEAN_SHIFT_STEPS):
        centre = _masked_mean(video, lambda t: quiet[t] & (np.abs(video[t] - centre).max(axis=2) < radius),
                              fallback=centre)
    in_mode = np.zeros(video.shape[1:3], np.float32)
    for t in range(t_count):
        in_mode += quiet[t] & (np.abs(video[t] - centre).max(axis=2) < radius)
    n_quiet = quiet.sum(axis=0).astype(np.float32)
    support = np.clip(in_mode / max(MIN_SAMPLES, FULL_SUPPORT * t_count), 0, 1)
    agreement = np.where(n_quiet > 0, in_mode / np.maximum(n_quiet, 1), 0)
    conf = (support * agreement).astype(np.float32)
    plate = fill_unseen(np.nan_to_num(centre), in_mode > 0, video)
    return PlateEstimate(plate, conf, "temporal", {"frames": t_count})


# ---- helpers ---------------------------------------------------------------------------------------------
def noise_level(video: np.ndarray) -> float:
    """The typical frame-to-frame change of a still pixel (codec and sensor noise): the 20th percentile over
    pixels and frames of the largest channel's absolute difference, times 1.5 (for pure Gaussian noise that is
    about its median), at most ``MAX_NOISE``. A low percentile stays a noise measure while smoke moves over most
    of the frame; the cap keeps footage whose every pixel moves from calling its motion noise."""
    if len(video) < 2:
        return 0.0
    step = max(1, int(np.sqrt(video.shape[1] * video.shape[2] / 20000)))  # about 20k pixels suffice
    sub = video[:, ::step, ::step]
    return min(MAX_NOISE, 1.5 * float(np.percentile(np.abs(np.diff(sub, axis=0)).max(axis=3), 20)))


def quiet_mask(video: np.ndarray, noise: float) -> np.ndarray:
    """[T, H, W] bool: the pixel changes less than the motion threshold from the previous and to the next frame,
    and so do its 8 neighbours (a smoke front's interior next to its moving edge is not taken as still)."""
    t_count = len(video)
    if t_count < 2:
        return np.ones(video.shape[:3], bool)
    change = np.abs(np.diff(video, axis=0)).max(axis=3)  # [T-1, H, W]
    kernel = np.ones((3, 3), np.uint8)
    threshold = max(MIN_CHANGE, NOISE_FACTOR * noise)
    out = np.empty(video.shape[:3], bool)
    for t in range(t_count):
        g = np.maximum(change[max(t - 1, 0)], change[min(t, t_count - 2)])
        out[t] = cv2.dilate(g, kernel) < threshold
    return out


def clean_prefix(video: np.ndarray, noise: float) -> int:
    """Number of leading frames before the first significant change: the first frame in which more than
    ``CHANGED_FRACTION`` of the pixels differ from frame 0 by more than the difference threshold (at least 1;
    T: the video never changes). Whether those frames are clean is for the caller to check."""
    tol = _difference(noise)
    for t in range(1, len(video)):
        if float((np.abs(video[t] - video[0]).max(axis=2) > tol).mean()) > CHANGED_FRACTION:
            return t
    return len(video)


def fill_unseen(plate: np.ndarray, seen: np.ndarray, video: np.ndarray) -> np.ndarray:
    """Fill pixels not ``seen`` from seen neighbours (normalised Gaussian blurs of growing width); where none is
    near, the pixel's median over the video."""
    out = plate.copy()
    todo = ~seen
    weight = seen.astype(np.float32)
    sigma = 2.0
    while todo.any() and sigma < 4 * max(plate.shape[:2]):
        den = cv2.GaussianBlur(weight, (0, 0), sigma)
        num = cv2.GaussianBlur(plate * weight[..., None], (0, 0), sigma)
        ok = todo & (den > 1e-3)
        out[ok] = num[ok] / den[ok][:, None]
        todo &= ~ok
        sigma *= 2
    if todo.any():
        out[todo] = np.median(video[:, todo], axis=0)
    return out.astype(np.float32)


def hulls(mask: np.ndarray) -> np.ndarray:
    """[H, W] bool: the convex hull of each group of ``mask`` pixels, a group being the pixels less than about
    8 % of the image size apart (unsure stripes split an object's confident part into pieces)."""
    h, w = mask.shape
    r = max(1, round(0.04 * max(h, w)))
    near = cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    count, labels = cv2.connectedComponents(near, connectivity=8)
    out = np.zeros(mask.shape, np.uint8)
    for k in range(1, count):
        ys, xs = np.nonzero((labels == k) & mask)
        if len(xs) >= 4:
            cv2.fillConvexPoly(out, cv2.convexHull(np.stack([xs, ys], 1).astype(np.int32)), 1)
    return out.astype(bool)


def _is_clean(frames: np.ndarray, still: np.ndarray, temporal: PlateEstimate, noise: float) -> bool:
    """Leading frames are clean if there are at least ``MIN_CLEAN_FRAMES``, nothing moves in them (``still``:
    their quiet masks, without the last frame's where smoke arrives after it; smoke present from frame 0 moves),
    and their median matches the backdrop the rest of the video shows wherever that backdrop is seen."""
    if len(frames) < MIN_CLEAN_FRAMES or (1.0 - still.mean(axis=(1, 2))).max() > MAX_MOVING:
        return False
    seen = temporal.confidence >= CONFIDENT
    if seen.mean() < MIN_SEEN_FRACTION:
        return False
    differs = np.abs(np.median(frames, axis=0) - temporal.plate).max(axis=2) >= _difference(noise)
    return float(differs[seen].mean()) <= MAX_DISAGREEMENT


def _difference(noise: float) -> float:
    return max(MIN_DIFFERENCE, 2 * NOISE_FACTOR * noise)


def _brightness_bin(frame: np.ndarray) -> np.ndarray:
    return np.minimum((frame.mean(axis=2) * MODE_BINS).astype(np.int32), MODE_BINS - 1)


def _mode_bins(video: np.ndarray, quiet: np.ndarray) -> np.ndarray:
    """[H, W] the brightness bin holding most quiet samples (histogram smoothed with 1-2-1)."""
    h, w = video.shape[1:3]
    pixels = np.arange(h * w)
    counts = np.zeros(MODE_BINS * h * w, np.float32)
    for t in range(len(video)):
        counts[_brightness_bin(video[t]).ravel() * h * w + pixels] += quiet[t].ravel()  # one bin per pixel
    counts = counts.reshape(MODE_BINS, h, w)
    padded = np.pad(counts, ((1, 1), (0, 0), (0, 0)))
    smooth = padded[:-2] + 2 * padded[1:-1] + padded[2:]
    return smooth.argmax(axis=0)


def _masked_mean(video: np.ndarray, mask_at, fallback: np.ndarray | None = None) -> np.ndarray:
    """[H, W, 3] mean over frames of ``video[t]`` where ``mask_at(t)``; NaN (or ``fallback``) where never."""
    acc = np.zeros(video.shape[1:], np.float32)
    cnt = np.zeros(video.shape[1:3], np.float32)
    for t in range(len(video)):
        m = mask_at(t)
        np.add(acc, video[t], out=acc, where=m[..., None])
        cnt += m
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (acc / cnt[..., None]).astype(np.float32)
    if fallback is not None:
        mean = np.where(cnt[..., None] > 0, mean, fallback)
    return mean
