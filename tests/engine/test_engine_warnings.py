"""The torch bridges hand Taichi detached tensors: no warning, and no ``.grad`` planted on the caller's tensors.

Taichi reads the ``.grad`` of every ndarray argument that requires grad: torch warns when that tensor is not a
leaf ("The .grad attribute of a Tensor that is not a leaf Tensor is being accessed"), and a leaf gets a zero
``.grad`` allocated behind the caller's back.
"""
import warnings

import numpy as np
import torch

from fluidnexus.camera import Camera
from reference.splat_reference import random_gaussians


def render_and_simulate(engine, sim):
    """Forward and backward through ``render`` and ``simulate_step`` with non-leaf and leaf inputs."""
    scene = [t.clone().requires_grad_(True) for t in random_gaussians(3, 3, seed=1)]
    camera = Camera.look_at(12, 10, 14.0, eye=(0.3, 0.2, -3.0), target=(0.0, 0.0, 0.0))
    means = scene[0] * 1.0  # not a leaf
    image, alpha, depth = engine.render(camera, means, *scene[1:], return_depth=True)
    rng = np.random.default_rng(0)
    p = torch.tensor(rng.uniform(0, 0.03, (20, 3)), requires_grad=True)
    u = torch.tensor(rng.normal(0, 0.1, (20, 3)), requires_grad=True)
    theta = torch.tensor(sim.model.to_vector(), requires_grad=True)
    p1, u1 = engine.simulate_step(p * 1.0, u * 1.0, theta * 1.0, sim)
    (image.sum() + alpha.sum() + depth.sum() + p1.sum() + u1.sum()).backward()
    return scene, p, u, theta


def test_render_and_simulate_step_raise_no_warning(ti_engine):
    engine = ti_engine
    sim = engine.PBFSimulator(32, engine.SolverConfig(iterations=2))
    render_and_simulate(engine, sim)  # compile first (Taichi's own first-compile notices are not ours)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene, p, u, theta = render_and_simulate(engine, sim)
    for t in scene + [p, u, theta]:
        assert t.grad is not None and float(t.grad.abs().max()) > 0  # the gradients still arrive


def test_forward_leaves_the_inputs_grad_alone(ti_engine):
    """A forward pass alone must not allocate ``.grad`` on a leaf input (Taichi would, for a tensor that needs it)."""
    engine = ti_engine
    scene = [t.clone().requires_grad_(True) for t in random_gaussians(2, 1, seed=2)]
    camera = Camera.look_at(8, 8, 10.0, eye=(0.0, 0.0, -3.0), target=(0.0, 0.0, 0.0))
    engine.render(camera, *scene)
    sim = engine.PBFSimulator(8, engine.SolverConfig(iterations=1))
    p = torch.zeros((2, 3), dtype=torch.float64, requires_grad=True)
    engine.simulate_step(p, torch.zeros_like(p), torch.tensor(sim.model.to_vector()), sim)
    assert all(t.grad is None for t in scene + [p])
