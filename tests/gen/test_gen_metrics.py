import numpy as np
import pytest
import torch

from fluidnexus.metrics import flicker, psnr, ssim


def _pair(seed=0, shape=(24, 20, 2)):
    rng = np.random.default_rng(seed)
    a = rng.random(shape)
    return a, np.clip(a + 0.1 * rng.standard_normal(shape), 0, 1)


def test_psnr_known_value_numpy_and_torch():
    a = np.zeros((4, 4, 1))
    b = np.full((4, 4, 1), 0.1)
    assert psnr(a, b) == pytest.approx(20.0)
    assert float(psnr(torch.tensor(a), torch.tensor(b))) == pytest.approx(20.0)
    assert psnr(np.stack([a, a]), np.stack([b, a]))[0] == pytest.approx(20.0)


def _ssim_reference(a, b):
    """Direct per-window SSIM (Wang et al. 2004) with an explicit 11x11 Gaussian, valid windows only."""
    x = np.arange(11) - 5.0
    g = np.exp(-x ** 2 / (2 * 1.5 ** 2))
    w = np.outer(g, g) / np.outer(g, g).sum()
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    vals = []
    for ch in range(a.shape[-1]):
        for i in range(a.shape[0] - 10):
            for j in range(a.shape[1] - 10):
                pa, pb = a[i:i + 11, j:j + 11, ch], b[i:i + 11, j:j + 11, ch]
                ma, mb = (w * pa).sum(), (w * pb).sum()
                va, vb = (w * pa * pa).sum() - ma ** 2, (w * pb * pb).sum() - mb ** 2
                cov = (w * pa * pb).sum() - ma * mb
                vals.append((2 * ma * mb + c1) * (2 * cov + c2) / ((ma ** 2 + mb ** 2 + c1) * (va + vb + c2)))
    return float(np.mean(vals))


def test_ssim_matches_direct_definition_and_torch():
    a, b = _pair()
    ref = _ssim_reference(a, b)
    assert ssim(a, b) == pytest.approx(ref, abs=1e-10)
    assert float(ssim(torch.tensor(a), torch.tensor(b))) == pytest.approx(ref, abs=1e-10)
    assert ssim(a, a) == pytest.approx(1.0)


def test_ssim_matches_scikit_image():
    metrics = pytest.importorskip("skimage.metrics")
    a, b = _pair(1, (32, 30, 3))
    ref = metrics.structural_similarity(a, b, data_range=1.0, channel_axis=-1, gaussian_weights=True, sigma=1.5,
                                        use_sample_covariance=False)
    assert ssim(a, b) == pytest.approx(ref, abs=1e-8)


def test_ssim_torch_gradient_matches_finite_differences():
    a, b = _pair(2, (12, 13, 1))
    x = torch.tensor(a, requires_grad=True)
    assert torch.autograd.gradcheck(lambda t: ssim(t, torch.tensor(b)), (x,), eps=1e-6, atol=1e-6)


def test_flicker_ignores_motion_and_sees_noise():
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:48, 0:64]
    frames = np.stack([np.exp(-((xx - 20 - 2 * t) ** 2 + (yy - 24) ** 2) / 60.0) for t in range(6)])[..., None]
    frames = frames.astype(np.float32)
    moving = flicker(frames)
    naive = float(np.abs(np.diff(frames, axis=0)).mean())
    assert moving < 0.3 * naive
    noisy = np.clip(frames * (1 + 0.2 * rng.standard_normal((6, 1, 1, 1))), 0, 1).astype(np.float32)
    assert flicker(noisy, flow_from=frames) > 3 * moving
