"""The Taichi splat renderer against the dense torch reference and float64 central finite differences."""
import numpy as np
import pytest
import taichi as ti
import torch

from fluidnexus.camera import Camera
from reference.splat_reference import random_gaussians, render_reference

FWD_TOL = dict(rtol=1e-10, atol=1e-12)
GRAD_TOL = dict(rtol=1e-8, atol=1e-10)


def front_camera(width: int, height: int, fx: float | None = None, eye=(0.3, 0.2, -3.0)) -> Camera:
    """A camera 3 m from the origin whose view holds the random scenes (about +-0.6 m)."""
    return Camera.look_at(width, height, fx or 1.2 * max(width, height), eye=eye, target=(0.0, 0.0, 0.0))


def both_renders(ti_engine, camera, inputs, background, tile=16):
    """(Taichi outputs, reference outputs) with depth, for the same leaf tensors."""
    from fluidnexus.engine.splat import render

    ours = render(camera, *inputs, background, return_depth=True, tile=tile)
    ref = render_reference(camera, *inputs, background)
    return ours, ref


def leaves(*tensors):
    return [t.detach().clone().requires_grad_(True) for t in tensors]


def assert_grads_match(ours, ref, inputs):
    gen = torch.Generator().manual_seed(1)
    cots = [torch.randn(o.shape, generator=gen, dtype=o.dtype) for o in ref]
    g_ours = torch.autograd.grad(sum((o * c).sum() for o, c in zip(ours, cots)), inputs)
    g_ref = torch.autograd.grad(sum((o * c).sum() for o, c in zip(ref, cots)), inputs)
    names = ["means", "scales", "quats", "opacities", "colors", "background"]
    for name, a, b in zip(names, g_ours, g_ref):
        assert torch.isfinite(a).all(), name
        torch.testing.assert_close(a, b, **GRAD_TOL, msg=lambda m, name=name: f"d/d{name}: {m}")
    return g_ours


@pytest.mark.parametrize("width, height, n, channels, tile", [
    (8, 8, 3, 1, 16), (13, 9, 4, 3, 4), (32, 32, 6, 3, 8), (24, 17, 5, 1, 16),
])
def test_forward_and_gradients_match_dense_reference(ti_engine, width, height, n, channels, tile):
    camera = front_camera(width, height)
    inputs = leaves(*random_gaussians(n, channels, seed=width + n), torch.rand(channels, dtype=torch.float64))
    ours, ref = both_renders(ti_engine, camera, inputs[:5], inputs[5], tile)
    assert ours[0].shape == (height, width, channels) and ours[1].shape == ours[2].shape == (height, width)
    assert ref[1].max() > 0.5, "the scene must be visible for the test to mean anything"
    for a, b in zip(ours, ref):
        torch.testing.assert_close(a, b, **FWD_TOL)
    assert_grads_match(ours, ref, inputs)


def test_gradients_match_central_finite_differences(ti_engine):
    from fluidnexus.engine.splat import render

    camera = front_camera(12, 10)
    inputs = list(random_gaussians(3, 3, seed=5)) + [torch.tensor([0.2, 0.1, 0.3], dtype=torch.float64)]
    gen = torch.Generator().manual_seed(2)
    cots = [torch.randn(s, generator=gen, dtype=torch.float64) for s in ((10, 12, 3), (10, 12), (10, 12))]

    def loss(*args):
        return sum((o * c).sum() for o, c in zip(render(camera, *args[:5], args[5], return_depth=True), cots))

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


def test_renders_between_forward_and_backward_do_not_mix(ti_engine):
    """Two views rendered before one backward (as a multi-view loss does) give the sum of separate gradients."""
    from fluidnexus.engine.splat import render

    cams = [front_camera(16, 12), front_camera(16, 12, eye=(-2.0, 0.5, -2.0))]
    base = random_gaussians(5, 1, seed=3)

    def grads(views):
        params = leaves(*base)
        loss = sum((render(cams[v], *params)[0] ** 2).sum() for v in views)
        return torch.autograd.grad(loss, params)

    together = grads([0, 1])
    for a, b, c in zip(together, grads([0]), grads([1])):
        torch.testing.assert_close(a, b + c, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("case", ["zero_opacity", "tiny_scale", "huge_scale", "behind_camera", "near_plane",
                                  "off_screen", "border_and_many_tiles"])
def test_degenerate_inputs_match_reference(ti_engine, case):
    camera = front_camera(20, 16)
    means, scales, quats, opacities, colors = random_gaussians(4, 3, seed=11)
    if case == "zero_opacity":
        opacities[1] = 0.0
    elif case == "tiny_scale":
        scales[1] = 1e-9
    elif case == "huge_scale":
        scales[1] = torch.tensor([1e3, 2e3, 5e2])
        opacities[1] = 0.3
    elif case == "behind_camera":
        means[1] = torch.tensor([0.3, 0.2, -5.0])  # 2 m behind the camera at z = -3
    elif case == "near_plane":
        means[1] = torch.tensor([0.3, 0.2, -2.995])  # 5 mm in front of the camera, inside the near plane
    elif case == "off_screen":
        means[1] = torch.tensor([4.0, 0.0, 0.0])  # beyond the right edge, within the Jacobian clamp region
    else:
        means[1] = torch.tensor([1.0, 0.0, 0.0])  # straddles the left border
        scales[1] = torch.tensor([0.6, 0.4, 0.5])
    inputs = leaves(means, scales, quats, opacities, colors, torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64))
    ours, ref = both_renders(ti_engine, camera, inputs[:5], inputs[5], tile=4)
    for a, b in zip(ours, ref):
        assert torch.isfinite(a).all()
        torch.testing.assert_close(a, b, **FWD_TOL)
    grads = assert_grads_match(ours, ref, inputs)
    if case in ("zero_opacity", "behind_camera", "near_plane"):
        assert all(float(g[1].abs().max()) == 0.0 for g in grads[:5]), "a culled Gaussian gets no gradient"


def test_empty_set_gives_background(ti_engine):
    from fluidnexus.engine.splat import render

    inputs = leaves(*(t[:0] for t in random_gaussians(1, 3)))
    bg = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64, requires_grad=True)
    image, alpha, depth = render(front_camera(9, 7), *inputs, bg, return_depth=True)
    assert torch.equal(image, bg.detach().expand(7, 9, 3))
    assert torch.equal(alpha, torch.zeros(7, 9, dtype=torch.float64)) and torch.equal(depth, alpha)
    grads = torch.autograd.grad(image.sum() + alpha.sum(), inputs + [bg])
    assert [tuple(g.shape) for g in grads[:5]] == [(0, 3), (0, 3), (0, 4), (0,), (0, 3)]
    torch.testing.assert_close(grads[5], torch.full((3,), 63.0, dtype=torch.float64))


def test_buffers_grow_for_more_gaussians_and_pixels(ti_engine):
    """More Gaussians and pixels than the initial capacities (1024, 64 x 64): same result as the reference."""
    from fluidnexus.engine import splat_buffers
    from fluidnexus.engine.splat import render

    fields = splat_buffers.splat_fields()
    saved = fields.gauss, fields.pixels
    try:
        inputs = random_gaussians(1100, 1, seed=4, scale=(0.01, 0.03), opacity=(0.05, 0.2))
        camera = front_camera(72, 64)
        bg = torch.tensor([0.25], dtype=torch.float64)
        ours = render(camera, *inputs, bg, return_depth=True)
        assert fields.gauss.cap >= 1100 and fields.pixels.cap >= 72 * 64
        ref = render_reference(camera, *inputs, bg)
        for a, b in zip(ours, ref):
            torch.testing.assert_close(a, b, **FWD_TOL)
    finally:  # later tests keep the kernels already compiled for the initial fields
        fields.gauss, fields.pixels = saved
        fields.owner = None


def test_reserved_capacity_is_kept_by_later_renders(ti_engine):
    """reserve_gaussians sizes the fields once: a render within the reserved count keeps them (so the render
    kernels are not re-instantiated for new fields), and its image is the reference's."""
    from fluidnexus.engine import reserve_gaussians, splat_buffers
    from fluidnexus.engine.splat import render

    fields = splat_buffers.splat_fields()
    saved = fields.gauss, fields.pixels
    try:
        reserve_gaussians(3000)
        reserved = fields.gauss
        assert reserved.cap >= 3000
        inputs = random_gaussians(1100, 1, seed=5, scale=(0.01, 0.03), opacity=(0.05, 0.2))
        camera, bg = front_camera(24, 16), torch.tensor([0.25], dtype=torch.float64)
        image = render(camera, *inputs, bg)[0]
        assert fields.gauss is reserved
        torch.testing.assert_close(image, render_reference(camera, *inputs, bg)[0], **FWD_TOL)
        reserve_gaussians(10)  # a smaller reservation never shrinks the fields
        assert fields.gauss is reserved
    finally:  # later tests keep the kernels already compiled for the initial fields
        fields.gauss, fields.pixels = saved
        fields.owner = None


def test_bad_shapes_raise(ti_engine):
    from fluidnexus.engine.splat import render

    means, scales, quats, opacities, colors = random_gaussians(2, 3)
    camera = front_camera(8, 8)
    with pytest.raises(ValueError, match="scales"):
        render(camera, means, scales[:, :2], quats, opacities, colors)
    with pytest.raises(ValueError, match="background"):
        render(camera, means, scales, quats, opacities, colors, torch.zeros(2, dtype=torch.float64))
    with pytest.raises(ValueError, match="zero quaternion"):
        render(camera, means, scales, torch.zeros_like(quats), opacities, colors)


def test_float32_inputs_follow_engine_precision(ti_engine):
    from fluidnexus.engine.splat import render

    inputs = [t.float() for t in random_gaussians(3, 1, seed=8)]
    image, alpha, _ = render(front_camera(8, 8), *inputs)
    assert image.dtype == torch.float64  # the tests run Taichi in float64
    ref = render_reference(front_camera(8, 8), *(t.double() for t in inputs), torch.zeros(1, dtype=torch.float64))
    np.testing.assert_allclose(image.numpy(), ref[0].numpy(), atol=1e-12)


@ti.kernel
def weighted_image_sum(pix: ti.template(), weights: ti.types.ndarray(), n: ti.i32, loss: ti.template()):
    for i in range(n):
        loss[None] += weights[i] * pix.image[i]


def test_kernels_compose_under_ti_ad_tape(ti_engine):
    """Inside ``ti.ad.Tape`` the projection and the (grad-replaced) rasterizer give the torch bridge's gradients."""
    from fluidnexus.engine.splat import prepare_frame, render
    from fluidnexus.engine.splat_project import project_gaussians
    from fluidnexus.engine.splat_raster import rasterize

    camera = front_camera(14, 11)
    scene = random_gaussians(4, 3, seed=6)
    bg = torch.tensor([0.1, 0.0, 0.2], dtype=torch.float64)
    weights = torch.randn(11 * 14 * 3, generator=torch.Generator().manual_seed(3), dtype=torch.float64)
    params = leaves(*scene)
    image, _, _ = render(camera, *params, bg)
    expected = torch.autograd.grad((image.reshape(-1) * weights).sum(), params)

    fields, frame = prepare_frame(camera, *scene, bg, 0.01, 16, False)
    loss = ti.field(ti_engine.real(), shape=(), needs_grad=True)
    with ti.ad.Tape(loss=loss):
        project_gaussians(fields.gauss, fields.camera, 4)
        rasterize(*frame.raster_args(fields))
        weighted_image_sum(fields.pixels, weights, weights.shape[0], loss)
    g = fields.gauss
    got = [g.means.grad.to_torch()[:4], g.scales.grad.to_torch()[:4], g.quats.grad.to_torch()[:4],
           g.opacities.grad.to_torch()[:4], g.colors.grad.to_torch()[:12].reshape(4, 3)]
    for a, b in zip(got, expected):
        torch.testing.assert_close(a, b, rtol=1e-10, atol=1e-12)
