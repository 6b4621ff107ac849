"""eval's per-frame scores: a frame the render matches exactly scores the 8-bit footage's quantization limit, so
the mean over frames stays finite and still ranks the renders."""
import math

import numpy as np


def test_an_exact_frame_scores_the_quantization_limit_not_infinity():
    from fluidnexus.evaluation import PSNR_CAP_DB, _score
    from fluidnexus.metrics import psnr

    rng = np.random.default_rng(0)
    truth = np.ones((3, 16, 16, 1))  # a white backdrop; smoke in the last two frames
    truth[1:, 2:5, 3:6] = 0.4
    close = truth.copy()
    close[1:] += rng.normal(0.0, 0.02, truth[1:].shape)
    far = truth.copy()
    far[1:] += rng.normal(0.0, 0.2, truth[1:].shape)
    a, b = _score(list(close), truth, None).psnr, _score(list(far), truth, None).psnr
    assert math.isfinite(a) and math.isfinite(b) and a > b
    assert math.isclose(PSNR_CAP_DB, 58.92, abs_tol=0.01)
    assert math.isclose(a, (PSNR_CAP_DB + psnr(close[1], truth[1]) + psnr(close[2], truth[2])) / 3)
