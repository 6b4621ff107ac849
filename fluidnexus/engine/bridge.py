"""Torch entry points to the Taichi kernels, differentiable through ``ti.ad``.

Tensors are CPU torch tensors of the running Taichi precision (float64 when the engine runs in f64,
float32 in f32); shapes: positions and velocities [N, 3] (m, m/s), query points [M, 3] (m),
model parameters [P] in the layout of ``ModelConfig.param_names()``.

Each call of :func:`simulate_step` saves only its inputs; backward replays the step's forward kernels
when the simulator's fields hold another step (per-step checkpointing: memory O(steps x N) for the
saved inputs plus one step's tape).
"""
import torch

from .pbf import PBFSimulator
from .query import FieldQuery


class _SimulateStep(torch.autograd.Function):
    @staticmethod
    def forward(ctx, p0, u0, theta, sim, age, smoke, volume):
        sim.load_theta(theta.detach())
        sim.load(p0, u0, age, smoke, volume)
        sim.forward()
        ctx.sim, ctx.token, ctx.age, ctx.smoke, ctx.volume = sim, sim.token, age, smoke, volume
        ctx.save_for_backward(p0, u0, theta)
        p1, u1 = sim.result()
        return p1, u1

    @staticmethod
    def backward(ctx, grad_p, grad_u):
        sim = ctx.sim
        p0, u0, theta = ctx.saved_tensors
        if sim.token is not ctx.token:  # the fields hold another step: recompute this one (checkpointing)
            sim.load_theta(theta.detach())
            sim.load(p0, u0, ctx.age, ctx.smoke, ctx.volume)
            sim.forward()
            ctx.token = sim.token
        gp, gu, gt = sim.backward(grad_p, grad_u)
        return gp, gu, gt.to(theta.dtype), None, None, None, None


def simulate_step(p0: torch.Tensor, u0: torch.Tensor, params: torch.Tensor, sim: PBFSimulator,
                  age: torch.Tensor | None = None, smoke: torch.Tensor | None = None,
                  volume: torch.Tensor | None = None):
    """One PBF step ``p1, u1 = Sim(u0, p0)`` (FluidNexus Eq. S1-S3), differentiable w.r.t. p0, u0, params.

    Args:
        p0: positions [N, 3] m. u0: velocities [N, 3] m/s.
        params: model parameters [P] (``sim.model.to_vector()`` layout).
        sim: the simulator (capacity, solver constants, which terms).
        age: particle ages [N] s for the decaying buoyancy (default 0); not differentiated.
        smoke: smoke weights [N] (default 1; 0 marks ambient air, which buoyancy skips); not differentiated.
        volume: rest volumes [N] (default 1; the entrainment term grows them, ``PBFSimulator.load``); not
            differentiated.

    Returns:
        (p1 [N, 3], u1 [N, 3]).
    """
    return _SimulateStep.apply(p0, u0, params, sim, age, smoke, volume)


class _Interpolate(torch.autograd.Function):
    @staticmethod
    def forward(ctx, q, p, u, query):
        query.forward(q, p, u)
        ctx.query, ctx.token = query, query.token
        ctx.save_for_backward(q, p, u)
        return query.velocity(), query.density()

    @staticmethod
    def backward(ctx, grad_v, grad_rho):
        query = ctx.query
        q, p, u = ctx.saved_tensors
        if query.token is not ctx.token:
            query.forward(q, p, u)
        gq, gp, gu = query.backward(grad_v, grad_rho)
        return gq, gp, gu, None


def velocity_at(q: torch.Tensor, p: torch.Tensor, u: torch.Tensor, query: FieldQuery) -> torch.Tensor:
    """V(q) [M, 3] m/s, the kernel-weighted mean of particle velocities (FluidNexus Eq. 2)."""
    return _Interpolate.apply(q, p, u, query)[0]


def density_at(q: torch.Tensor, p: torch.Tensor, query: FieldQuery) -> torch.Tensor:
    """rho(q) [M] 1/m^3 = sum_j W(q - p_j)."""
    return _Interpolate.apply(q, p, torch.zeros_like(p), query)[1]
