import numpy as np

from fluidnexus.gen.refiner import make_refiner
from fluidnexus.gen.temporal import TemporalConfig, temporal_filter
from fluidnexus.metrics import flicker, mean_psnr_db


def moving_puffs(frames=12, h=48, w=40):
    """A clean video: two soft puffs rising and spreading, like smoke."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    out = []
    for t in range(frames):
        a = 0.7 * np.exp(-((xx - 14) ** 2 + (yy - 36 + 1.5 * t) ** 2) / (30 + 2 * t))
        b = 0.5 * np.exp(-((xx - 27 - 0.5 * t) ** 2 + (yy - 30 + 1.0 * t) ** 2) / 40)
        out.append(a + b)
    return np.clip(np.stack(out)[..., None], 0, 1).astype(np.float32)


def test_temporal_lowers_flicker_without_lowering_psnr():
    rng = np.random.default_rng(0)
    clean = moving_puffs()
    gains = 1 + 0.15 * rng.standard_normal((clean.shape[0], 1, 1, 1))
    noisy = np.clip(clean * gains + 0.02 * rng.standard_normal(clean.shape), 0, 1).astype(np.float32)
    refined = make_refiner("temporal").refine(noisy)
    assert refined.shape == noisy.shape and refined.dtype == np.float32
    assert 0.0 <= refined.min() and refined.max() <= 1.0
    assert flicker(refined, flow_from=clean) < 0.5 * flicker(noisy, flow_from=clean)
    assert mean_psnr_db(refined, clean) > mean_psnr_db(noisy, clean) + 1.0


def test_temporal_keeps_a_clean_video():
    clean = moving_puffs()
    assert mean_psnr_db(temporal_filter(clean), clean) > 38.0
    # a sudden real change (a puff appearing) is kept, not smeared into the frames before it
    jump = clean.copy()
    jump[6:, 5:15, 25:35] = 0.9
    out = temporal_filter(jump, TemporalConfig())
    assert out[6:, 7:13, 27:33].min() > 0.8
    assert out[:6, 7:13, 27:33].max() < clean[:6, 7:13, 27:33].max() + 0.1
