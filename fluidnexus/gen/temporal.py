"""``temporal``: a non-learned video refiner, an optical-flow-guided temporal filter (OpenCV).

Each frame is replaced by a weighted mean of itself and its neighbours within ``radius`` frames, every
neighbour first warped onto it along the dense optical flow between the two frames (Farneback). The weight of
a neighbour pixel is a Gaussian in the time offset times a Gaussian in the difference between the locally
averaged (``detail_sigma_px``) warped neighbour and the frame: where the flow explains the motion the
neighbours agree up to flicker, which averages out; where they disagree (occlusion, a flow failure, a real
change) the frame keeps its own value. Frame-to-frame flicker is independent between frames, so averaging n
aligned frames divides its amplitude by about sqrt(n) while the content, moved along the flow, stays.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..metrics import optical_flow, warp_by_flow
from ..progress import progress
from .refiner import VideoRefiner


@dataclass(frozen=True)
class TemporalConfig:
    """Settings of the temporal filter.

    Attributes:
        radius: neighbours on each side, frames.
        sigma_frames: Gaussian weight over the time offset, frames.
        tolerance: intensity difference (of local means) at which a neighbour's weight drops to exp(-1/2).
        detail_sigma_px: Gaussian blur, pixels, applied before comparing a neighbour with the frame.
    """

    radius: int = 3
    sigma_frames: float = 2.0
    tolerance: float = 0.05
    detail_sigma_px: float = 1.5


def _local_mean(image: np.ndarray, sigma: float) -> np.ndarray:
    import cv2

    return cv2.GaussianBlur(image, (0, 0), sigma).reshape(image.shape) if sigma > 0 else image


def temporal_filter(video: np.ndarray, config: TemporalConfig = TemporalConfig()) -> np.ndarray:
    """Flow-guided temporal filtering of a video (module docstring).

    Args:
        video: [T, H, W, C] float32 in [0, 1].
        config: the filter's settings.
    Returns:
        [T, H, W, C] float32 in [0, 1].
    """
    video = np.ascontiguousarray(video, np.float32)
    frames = video.shape[0]
    out = np.empty_like(video)
    smooth = np.stack([_local_mean(f, config.detail_sigma_px) for f in video])
    with progress("temporal filter", frames) as bar:
        for t in range(frames):
            acc, wsum = video[t].copy(), np.ones(video.shape[1:], np.float32)
            for k in range(-config.radius, config.radius + 1):
                s = t + k
                if k == 0 or not 0 <= s < frames:
                    continue
                flow = optical_flow(smooth[t], smooth[s])
                warped = warp_by_flow(video[s], flow)
                diff = warp_by_flow(smooth[s], flow) - smooth[t]
                w = np.exp(-0.5 * (k / config.sigma_frames) ** 2 - 0.5 * (diff / config.tolerance) ** 2)
                acc += w * warped
                wsum += w
            out[t] = np.clip(acc / wsum, 0.0, 1.0)
            bar.advance()
    return out


class TemporalRefiner(VideoRefiner):
    """The ``temporal`` backend (:func:`temporal_filter`)."""

    name = "temporal"

    def __init__(self, config: TemporalConfig = TemporalConfig()):
        self.config = config

    def refine(self, video: np.ndarray) -> np.ndarray:
        return temporal_filter(video, self.config)

    def provenance(self) -> dict:
        return {"method": self.name, **asdict(self.config)}
