"""Closed-form checks of the splat renderer and its golden image."""
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from fluidnexus.camera import Camera
from reference.splat_reference import random_gaussians

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "splat_small.npz"


def f64(*values):
    return torch.tensor(values, dtype=torch.float64)


def test_isotropic_gaussian_straight_ahead_has_the_expected_footprint(ti_engine):
    """A sphere of std s at distance d projects to a 2D Gaussian of variance (f s / d)^2 + 0.3 px^2."""
    from fluidnexus.engine.splat import render

    f, s, d, opacity = 40.0, 0.05, 2.0, 0.8
    camera = Camera.look_at(31, 31, f, eye=(0.0, 0.0, -d), target=(0.0, 0.0, 0.0))  # centre on pixel (15, 15)
    image, alpha, depth = render(camera, f64(0.0, 0.0, 0.0)[None], f64(s, s, s)[None], f64(0.3, 0.1, -0.5, 0.2)[None],
                                 f64(opacity), f64(0.6)[None], return_depth=True)
    var = (f * s / d) ** 2 + 0.3
    r2 = (torch.arange(31, dtype=torch.float64) - 15.0) ** 2
    expected = opacity * torch.exp(-(r2[:, None] + r2[None, :]) / (2 * var))
    expected = torch.where(expected >= 1 / 255, expected, torch.zeros_like(expected))
    torch.testing.assert_close(alpha, expected, rtol=1e-12, atol=1e-14)
    assert float(alpha[15, 15]) == opacity and int((alpha > 0).sum()) < 31 * 31  # peak, and a finite footprint
    torch.testing.assert_close(image[..., 0], 0.6 * expected, rtol=1e-12, atol=1e-14)
    torch.testing.assert_close(depth, d * expected, rtol=1e-12, atol=1e-14)  # alpha-weighted depth


def test_opaque_gaussians_saturate_at_the_alpha_cap(ti_engine):
    """alpha = min(0.99, o G): a fully opaque Gaussian leaves 1 % of the Gaussian behind it."""
    from fluidnexus.engine.splat import render

    camera = Camera.look_at(9, 9, 20.0, eye=(0.0, 0.0, -2.0), target=(0.0, 0.0, 0.0))
    means = f64(0.0, 0.0, 0.0, 0.0, 0.0, 0.5).reshape(2, 3)
    quats = f64(1.0, 0.0, 0.0, 0.0).expand(2, 4)
    image, alpha, _ = render(camera, means, torch.full((2, 3), 0.5, dtype=torch.float64), quats, f64(1.0, 1.0),
                             f64(1.0, 0.0).reshape(2, 1))
    assert float(alpha[4, 4]) == pytest.approx(1 - 0.01 * 0.01, abs=1e-14)
    assert float(image[4, 4, 0]) == pytest.approx(0.99, abs=1e-14)


def test_one_and_three_channels_agree_channel_wise(ti_engine):
    from fluidnexus.engine.splat import render

    camera = Camera.look_at(20, 14, 24.0, eye=(0.4, -0.3, -3.0), target=(0.0, 0.0, 0.0))
    means, scales, quats, opacities, colors = random_gaussians(6, 3, seed=21)
    bg = f64(0.2, 0.5, 0.9)
    rgb, alpha_rgb, _ = render(camera, means, scales, quats, opacities, colors, bg)
    for c in range(3):
        gray, alpha, _ = render(camera, means, scales, quats, opacities, colors[:, c:c + 1], bg[c:c + 1])
        torch.testing.assert_close(gray[..., 0], rgb[..., c], rtol=0, atol=1e-15)
        torch.testing.assert_close(alpha, alpha_rgb, rtol=0, atol=0)


def test_background_shows_through_where_alpha_is_zero(ti_engine):
    from fluidnexus.engine.splat import render

    camera = Camera.look_at(24, 16, 30.0, eye=(0.0, 0.0, -3.0), target=(0.0, 0.0, 0.0))
    scene = random_gaussians(3, 3, seed=2, spread=0.2, scale=(0.02, 0.05))
    bg = f64(0.3, 0.6, 0.1)
    on_bg, alpha, _ = render(camera, *scene, bg)
    on_black, alpha_black, _ = render(camera, *scene)
    empty = alpha == 0
    assert 0 < int(empty.sum()) < empty.numel()
    assert torch.equal(on_bg[empty], bg.expand(int(empty.sum()), 3))
    torch.testing.assert_close(alpha, alpha_black, rtol=0, atol=0)
    torch.testing.assert_close(on_bg - on_black, (1 - alpha)[..., None] * bg, rtol=1e-12, atol=1e-14)


def golden_scene():
    camera = Camera.look_at(16, 12, 18.0, eye=(0.5, 0.4, -3.0), target=(0.0, 0.0, 0.0))
    return camera, random_gaussians(8, 3, seed=7), f64(0.05, 0.1, 0.15)


def test_golden_image(ti_engine, regen_golden):
    from fluidnexus.engine.splat import render

    camera, scene, bg = golden_scene()
    image, alpha, depth = (t.numpy() for t in render(camera, *scene, bg, return_depth=True))
    if regen_golden:
        GOLDEN.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(GOLDEN, image=image, alpha=alpha, depth=depth)
    golden = np.load(GOLDEN)
    assert math.isclose(float(alpha.max()), float(golden["alpha"].max()), rel_tol=1e-9)
    for name, value in (("image", image), ("alpha", alpha), ("depth", depth)):
        np.testing.assert_allclose(value, golden[name], rtol=1e-9, atol=1e-12, err_msg=name)
