"""Bit-identical reruns: the renderer's and the field queries' backward passes sum in a fixed order.

Both run on Taichi's default thread count (all cores). Before the gradients were gathered in a fixed order, a
Gaussian spanning many tiles received one float atomic add per tile from parallel tile tasks, and a particle one
per query listing it, so the last bits of the gradients changed from run to run.
"""
import numpy as np
import torch

from fluidnexus.camera import Camera
from reference.splat_reference import random_gaussians, render_reference

RERUNS = 4


def front_camera(width: int, height: int) -> Camera:
    return Camera.look_at(width, height, 1.2 * max(width, height), eye=(0.3, 0.2, -3.0), target=(0.0, 0.0, 0.0))


def leaves(*tensors):
    return [t.detach().clone().requires_grad_(True) for t in tensors]


def splat_gradients(render, camera, scene, background, cotangent):
    params = leaves(*scene, background)
    image, alpha, _ = render(camera, *params[:5], params[5], tile=4)
    return torch.autograd.grad((image * cotangent).sum() + alpha.sum(), params)


def test_splat_backward_is_bit_identical_across_reruns(ti_engine):
    from fluidnexus.engine.splat import render

    camera = front_camera(128, 96)  # 32 x 24 tiles of 4 px, most Gaussians cover hundreds of them
    scene = random_gaussians(40, 3, seed=9, spread=0.3, scale=(0.3, 0.6), opacity=(0.05, 0.15))
    background = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64)
    cotangent = torch.randn(96, 128, 3, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    first = splat_gradients(render, camera, scene, background, cotangent)
    assert float(first[0].abs().min()) > 0.0, "every Gaussian must reach the loss"
    for _ in range(RERUNS):
        again = splat_gradients(render, camera, scene, background, cotangent)
        for name, a, b in zip(("means", "scales", "quats", "opacities", "colors", "background"), first, again):
            assert torch.equal(a, b), f"d/d{name} changed between identical runs"


def test_splat_gradients_spanning_many_tiles_match_reference(ti_engine):
    """The fixed-order sums are the same gradients (a Gaussian here covers up to about 400 tiles)."""
    from fluidnexus.engine.splat import render

    camera = front_camera(96, 80)
    scene = random_gaussians(6, 3, seed=9, spread=0.3, scale=(0.2, 0.5), opacity=(0.05, 0.15))
    background = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64)
    cotangent = torch.randn(80, 96, 3, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    ours = splat_gradients(render, camera, scene, background, cotangent)
    params = leaves(*scene, background)
    image, alpha, _ = render_reference(camera, *params[:5], params[5])
    expected = torch.autograd.grad((image * cotangent).sum() + alpha.sum(), params)
    for a, b in zip(ours, expected):
        torch.testing.assert_close(a, b, rtol=1e-8, atol=1e-10)


def test_query_backward_is_bit_identical_across_reruns(ti_engine):
    engine = ti_engine
    rng = np.random.default_rng(7)
    p = torch.tensor(rng.uniform(0, 0.05, (600, 3)))
    u = torch.tensor(rng.normal(0, 0.3, (600, 3)))
    q = torch.tensor(rng.uniform(0, 0.05, (900, 3)))
    w = torch.tensor(rng.normal(size=(900, 3)))
    query = engine.FieldQuery(600, 900, 0.02)

    def grads():
        leaves_ = [t.clone().requires_grad_(True) for t in (q, p, u)]
        v = engine.velocity_at(*leaves_, query)
        rho = engine.density_at(leaves_[0], leaves_[1], query)
        return torch.autograd.grad((v * w).sum() + 1e-6 * rho.sum(), leaves_)

    first = grads()
    assert query.table.counts().min() > 20  # each particle is listed by many queries
    for _ in range(RERUNS):
        for name, a, b in zip("qpu", first, grads()):
            assert torch.equal(a, b), f"d/d{name} changed between identical runs"
