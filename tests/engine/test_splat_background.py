"""The splat renderer over a per-pixel background and with a static Gaussian set in the same depth sort.

Both against the dense torch reference (float64) and float64 central finite differences.
"""
import pytest
import torch

from reference.splat_reference import random_gaussians, render_reference

from .test_splat_render import FWD_TOL, assert_grads_match, front_camera, leaves


def plate(height: int, width: int, channels: int, seed: int) -> torch.Tensor:
    """A random per-pixel background [H, W, C] in [0, 1]."""
    return torch.rand(height, width, channels, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


@pytest.mark.parametrize("width, height, n, channels, tile", [(13, 9, 4, 3, 4), (24, 17, 5, 1, 16)])
def test_per_pixel_background_matches_dense_reference(ti_engine, width, height, n, channels, tile):
    from fluidnexus.engine.splat import render

    camera = front_camera(width, height)
    inputs = leaves(*random_gaussians(n, channels, seed=width + n), plate(height, width, channels, seed=n))
    ours = render(camera, *inputs, return_depth=True, tile=tile)
    ref = render_reference(camera, *inputs)
    matte = ref[1].detach()
    assert float(matte.max()) > 0.5 and float(matte.min()) < 0.5, "smoke and background must both show"
    for a, b in zip(ours, ref):
        torch.testing.assert_close(a, b, **FWD_TOL)
    grads = assert_grads_match(ours, ref, inputs)
    cotangent = torch.randn(ref[0].shape, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    # dL/dB = T_N dL/dC, pixel by pixel (assert_grads_match drew the same image cotangent first)
    torch.testing.assert_close(grads[5], (1 - ours[1].detach())[..., None] * cotangent, rtol=1e-12, atol=1e-14)


def test_per_pixel_background_gradients_match_central_finite_differences(ti_engine):
    from fluidnexus.engine.splat import render

    camera = front_camera(7, 6)
    inputs = list(random_gaussians(3, 2, seed=5)) + [plate(6, 7, 2, seed=3)]
    gen = torch.Generator().manual_seed(2)
    cots = [torch.randn(s, generator=gen, dtype=torch.float64) for s in ((6, 7, 2), (6, 7), (6, 7))]

    def loss(*args):
        return sum((o * c).sum() for o, c in zip(render(camera, *args, return_depth=True), cots))

    params = leaves(*inputs)
    grads = torch.autograd.grad(loss(*params), params)
    eps = 1e-6
    for idx, (x, g) in enumerate(zip(inputs, grads)):
        numeric = torch.zeros_like(x)
        for j in range(x.numel()):
            plus, minus = [t.clone() for t in inputs], [t.clone() for t in inputs]
            plus[idx].view(-1)[j] += eps
            minus[idx].view(-1)[j] -= eps
            numeric.view(-1)[j] = (loss(*plus) - loss(*minus)) / (2 * eps)
        assert g.abs().max() > 1e-3, f"input {idx}: gradient vanishes, the check would be vacuous"
        torch.testing.assert_close(g, numeric, rtol=1e-5, atol=1e-6, msg=lambda m, idx=idx: f"input {idx}: {m}")


def test_constant_background_equals_per_pixel_background_of_that_colour(ti_engine):
    from fluidnexus.engine.splat import render

    camera = front_camera(20, 14)
    colour = torch.tensor([0.2, 0.5, 0.9], dtype=torch.float64)
    scene = random_gaussians(6, 3, seed=21)
    cotangent = torch.randn(14, 20, 3, generator=torch.Generator().manual_seed(5), dtype=torch.float64)
    results = []
    for background in (colour, colour.expand(14, 20, 3).clone()):
        params = leaves(*scene, background)
        image, alpha, depth = render(camera, *params, return_depth=True)
        grads = torch.autograd.grad((image * cotangent).sum() + alpha.sum() + depth.sum(), params)
        results.append(((image, alpha, depth), grads))
    (outs_c, grads_c), (outs_p, grads_p) = results
    for a, b in zip(outs_c, outs_p):
        assert torch.equal(a, b), "the same arithmetic: bit-identical outputs"
    for a, b in zip(grads_c[:5], grads_p[:5]):
        assert torch.equal(a, b), "the same arithmetic: bit-identical Gaussian gradients"
    torch.testing.assert_close(grads_p[5].sum(dim=(0, 1)), grads_c[5], rtol=1e-12, atol=1e-12)


def interleaved_sets(channels: int = 3):
    """A smoke set and a static set spread over the same volume, so their depths interleave."""
    smoke = random_gaussians(5, channels, seed=31, spread=0.4)
    static = random_gaussians(4, channels, seed=32, spread=0.4, opacity=(0.5, 0.9))
    return smoke, static


def test_static_and_smoke_in_one_render_equal_the_reference_composite_of_the_union(ti_engine):
    from fluidnexus.engine import Gaussians
    from fluidnexus.engine.splat import render

    camera = front_camera(18, 14)
    smoke, static = interleaved_sets()
    z_smoke, z_static = smoke[0][:, 2], static[0][:, 2]  # the camera looks along +z
    assert z_static.min() < z_smoke.max() and z_smoke.min() < z_static.max(), "the depths must interleave"
    inputs = leaves(*smoke, *static, plate(14, 18, 3, seed=7))
    ours = render(camera, *inputs[:5], inputs[10], return_depth=True, tile=4, static=Gaussians(*inputs[5:10]))
    union = [torch.cat([a, b]) for a, b in zip(inputs[:5], inputs[5:10])]
    ref = render_reference(camera, *union, inputs[10])
    for a, b in zip(ours, ref):
        torch.testing.assert_close(a, b, **FWD_TOL)
    # not the same as the smoke drawn over the static layer's image: the sort really mixes the two sets
    static_image = render_reference(camera, *(t.detach() for t in inputs[5:10]), inputs[10].detach())[0]
    layered = render_reference(camera, *(t.detach() for t in inputs[:5]), static_image)[0]
    assert (layered - ref[0].detach()).abs().max() > 1e-2
    gen = torch.Generator().manual_seed(1)
    cots = [torch.randn(o.shape, generator=gen, dtype=o.dtype) for o in ref]
    g_ours = torch.autograd.grad(sum((o * c).sum() for o, c in zip(ours, cots)), inputs)
    g_ref = torch.autograd.grad(sum((o * c).sum() for o, c in zip(ref, cots)), inputs)
    for i, (a, b) in enumerate(zip(g_ours, g_ref)):
        assert float(b.abs().max()) > 1e-3, f"input {i}: gradient vanishes, the check would be vacuous"
        torch.testing.assert_close(a, b, rtol=1e-8, atol=1e-10, msg=lambda m, i=i: f"input {i}: {m}")


def test_frozen_static_gets_no_gradient_and_leaves_the_smoke_gradient_unchanged(ti_engine):
    from fluidnexus.engine import Gaussians
    from fluidnexus.engine.splat import render

    camera = front_camera(18, 14)
    smoke, static = interleaved_sets()
    cotangent = torch.randn(14, 18, 3, generator=torch.Generator().manual_seed(8), dtype=torch.float64)

    def smoke_grads(static_params):
        params = leaves(*smoke)
        image, alpha, _ = render(camera, *params, static=Gaussians(*static_params))
        ((image * cotangent).sum() + alpha.sum()).backward()
        return [p.grad for p in params]

    frozen = [t.clone() for t in static]
    with_frozen = smoke_grads(frozen)
    assert all(t.grad is None for t in frozen)
    optimised = leaves(*static)
    with_optimised = smoke_grads(optimised)
    assert all(float(t.grad.abs().max()) > 0.0 for t in optimised)
    for a, b in zip(with_frozen, with_optimised):
        assert torch.equal(a, b)
    union = leaves(*(torch.cat([a, b]) for a, b in zip(smoke, static)))
    image, alpha, _ = render_reference(camera, *union, torch.zeros(3, dtype=torch.float64))
    ref = torch.autograd.grad((image * cotangent).sum() + alpha.sum(), union)
    for a, b in zip(with_frozen, ref):
        torch.testing.assert_close(a, b[:5], rtol=1e-8, atol=1e-10)


def test_static_alone_with_no_smoke(ti_engine):
    from fluidnexus.engine import Gaussians
    from fluidnexus.engine.splat import render

    camera = front_camera(12, 10)
    _, static = interleaved_sets(1)
    empty = [t[:0] for t in static]
    background = plate(10, 12, 1, seed=9)
    ours = render(camera, *empty, background, return_depth=True, static=Gaussians(*static))
    ref = render_reference(camera, *static, background)
    for a, b in zip(ours, ref):
        torch.testing.assert_close(a, b, **FWD_TOL)


def test_bad_background_and_static_raise(ti_engine):
    from fluidnexus.engine import Gaussians
    from fluidnexus.engine.splat import render

    camera = front_camera(8, 6)
    smoke, static = interleaved_sets()
    with pytest.raises(ValueError, match=r"background must have shape \(3,\) or \(H, W, C\) = \(6, 8, 3\)"):
        render(camera, *smoke, plate(8, 6, 3, seed=0))
    with pytest.raises(ValueError, match="static.colors has 1 channels"):
        render(camera, *smoke, static=Gaussians(*static[:4], static[4][:, :1]))
    with pytest.raises(ValueError, match="static.scales"):
        render(camera, *smoke, static=Gaussians(static[0], static[1][:, :2], *static[2:]))
