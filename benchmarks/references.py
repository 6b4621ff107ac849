"""Scores of the trivial guesses a benchmark compares a run with (a flat image, the true frame 0 held still, ...)."""
from __future__ import annotations

import math

import numpy as np


def held_still_scores(video: np.ndarray, refs: dict) -> dict:
    """Per named reference image of ``refs`` (name -> [H, W, C]): PSNR and SSIM against every frame of ``video``
    [T, H, W, C], as eval averages them (per-frame means). The PSNR leaves out the frames the reference equals
    exactly (frame 0 against itself); inf where it equals every one."""
    from fluidnexus.metrics import psnr, ssim

    out = {}
    for name, ref in refs.items():
        scores = [psnr(ref, f) for f in video if not np.array_equal(ref, f)]
        out[name] = {"psnr": float(np.mean(scores)) if scores else math.inf,
                     "ssim": float(np.mean([ssim(ref, f) for f in video]))}
    return out
