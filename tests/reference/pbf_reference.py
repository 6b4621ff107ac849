"""Slow, obvious torch reference of the PBF gas step and the field queries (tests and benchmarks only).

Pairs are explicit index lists (dense all-pairs for tiny inputs, scipy cKDTree for large ones), sums are
``index_add``, gradients come from torch autograd. It mirrors fluidnexus/engine/{pbf,forces,query}.py
equation by equation but shares no code with them.
"""
from __future__ import annotations

import math

import numpy as np
import torch

TINY = 1e-20


def pairs_dense(x: torch.Tensor, h: float, q: torch.Tensor | None = None):
    """(i, j) with |q_i - x_j| < h (i != j when q is None), from all pairs. Shapes [M] int64."""
    qq = x if q is None else q
    d2 = ((qq[:, None, :] - x[None, :, :]) ** 2).sum(-1).detach()
    m = d2 < h * h
    if q is None:
        m.fill_diagonal_(False)
    i, j = torch.nonzero(m, as_tuple=True)
    return i, j


def pairs_kdtree(x: torch.Tensor, h: float, q: torch.Tensor | None = None):
    """Same as :func:`pairs_dense` from scipy's cKDTree (for large inputs)."""
    from scipy.spatial import cKDTree

    xs = x.detach().cpu().numpy()
    tree = cKDTree(xs)
    if q is None:
        pr = tree.query_pairs(h * (1 - 1e-12), output_type="ndarray")
        i = np.concatenate([pr[:, 0], pr[:, 1]])
        j = np.concatenate([pr[:, 1], pr[:, 0]])
    else:
        lists = cKDTree(q.detach().cpu().numpy()).query_ball_tree(tree, h * (1 - 1e-12))
        i = np.concatenate([np.full(len(l), k) for k, l in enumerate(lists)] + [np.zeros(0, int)])
        j = np.concatenate([np.asarray(l, dtype=int) for l in lists] + [np.zeros(0, int)])
    return torch.as_tensor(i, dtype=torch.long), torch.as_tensor(j, dtype=torch.long)


def poly6(r2, h):
    coef = 315.0 / (64.0 * math.pi * h**9)
    return torch.where(r2 < h * h, coef * (h * h - r2).clamp(min=0) ** 3, torch.zeros_like(r2))


def spiky_grad(r, h):
    coef = -45.0 / (math.pi * h**6)
    r2 = (r * r).sum(-1, keepdim=True)
    rl = torch.sqrt(r2.clamp(min=TINY))
    g = coef * (h - rl) ** 2 / rl * r
    return torch.where((r2 < h * h) & (r2 > 0), g, torch.zeros_like(g))


def scatter(values, index, n):
    out = torch.zeros((n,) + values.shape[1:], dtype=values.dtype)
    return out.index_add(0, index, values)


def density(p, pairs, h):
    """rho_i = W(0) + sum_{j in pairs} W(p_i - p_j)."""
    i, j = pairs
    w0 = 315.0 / (64.0 * math.pi * h**9) * h**6
    return w0 + scatter(poly6(((p[i] - p[j]) ** 2).sum(-1), h), i, len(p))


def _term_params(model, theta):
    """Split the flat theta tensor into {kind: {param: tensor}} following the model's layout."""
    out, k = {}, 0
    for t in model.terms:
        d = {}
        for name in t.params:
            v = getattr(t, name)
            n = len(v) if isinstance(v, (tuple, list)) else 1
            d[name] = theta[k] if n == 1 else theta[k:k + n]
            k += n
        out[t.kind] = d
    return out


def forces(p, u, age, model, theta, solver, pairs, smoke=None):
    """Sum of the external accelerations [N, 3] at the start-of-step state (buoyancy times the smoke weight)."""
    h, dt, rho0 = solver.h, solver.dt, solver.rest_density
    prm = _term_params(model, theta)
    rho = density(p, pairs, h)
    i, j = pairs
    n = len(p)
    f = torch.zeros_like(p)
    for t in model.terms:
        q = prm[t.kind]
        if t.kind == "buoyancy":
            w = torch.ones_like(age) if smoke is None else smoke
            f = f + (q["alpha"] * torch.exp(-q["decay"] * age) * w)[:, None] * torch.tensor(t.gravity, dtype=p.dtype)
        elif t.kind == "drag":
            w = torch.clamp(1.0 - rho / rho0, min=0.0)
            f = f - q["k"] * w[:, None] * (u - q["v_env"])
        elif t.kind == "wind":
            s = (p[:, 1] - t.y0) / t.height
            phi = {"constant": torch.ones_like(s), "ramp": s.clamp(0.0, 1.0), "exp": torch.exp(s)}[t.profile]
            f = f + phi[:, None] * q["accel"]
        elif t.kind == "vorticity":
            g = spiky_grad(p[i] - p[j], h)
            omega = scatter(torch.cross(g, u[j] - u[i], dim=-1) / rho[j, None], i, n)
            a = torch.sqrt((omega**2).sum(-1) + TINY)
            eta = scatter(((a[j] - a[i]) / rho[j])[:, None] * g, i, n)
            nrm = eta / torch.sqrt((eta**2).sum(-1, keepdim=True) + TINY)
            f = f + q["epsilon"] * torch.cross(nrm, omega, dim=-1)
        elif t.kind == "viscosity":
            w = poly6(((p[i] - p[j]) ** 2).sum(-1), h) / rho[j]
            f = f + q["c"] / dt * scatter(w[:, None] * (u[j] - u[i]), i, n)
        else:
            raise ValueError(t.kind)
    return f


def step(p, u, theta, model, solver, age=None, pairs_fn=pairs_dense, smoke=None, volume=None):
    """One PBF step (FluidNexus Eq. S1-S3); returns (p1, u1). Tables at p (terms) and p_hat (solver). ``volume``
    [N]: rest volumes v (default 1): particle i rests at rho0 / v_i and buoyancy acts on smoke / v_i."""
    h, dt, rho0 = solver.h, solver.dt, solver.rest_density
    age = torch.zeros(len(p), dtype=p.dtype) if age is None else age
    v = torch.ones(len(p), dtype=p.dtype) if volume is None else volume
    smoke = (torch.ones(len(p), dtype=p.dtype) if smoke is None else smoke) / v
    f = forces(p, u, age, model, theta, solver, pairs_fn(p, h), smoke)
    x = p + dt * (u + dt * f)
    i, j = pairs_fn(x, h)
    n = len(p)
    cnt = torch.bincount(i, minlength=n).to(p.dtype)
    coef6 = 315.0 / (64.0 * math.pi * h**9)
    w_dq = coef6 * (h * h - (solver.scorr_dq * h) ** 2) ** 3
    for _ in range(solver.iterations):
        r = x[i] - x[j]
        r2 = (r * r).sum(-1)
        g = spiky_grad(r, h)
        rho = density(x, (i, j), h)
        gsum = scatter(g, i, n)
        gsq = scatter((g * g).sum(-1), i, n)
        # C_i = v_i rho_i / rho0 - 1, grad C_i = v_i grad rho_i / rho0: the update uses v_i lambda_i
        lam = -v * (v * rho / rho0 - 1.0) / (v * v * ((gsum**2).sum(-1) + gsq) / rho0**2 + solver.eps)
        s = -solver.scorr_k * (poly6(r2, h) / w_dq) ** solver.scorr_n
        dp = scatter(((lam[i] + lam[j] + s) / rho0)[:, None] * g, i, n)
        if solver.averaging:
            dp = dp / cnt.clamp(min=1.0)[:, None]
        x = x + dp
    return x, (x - p) / dt


def velocity_at(q, p, u, h, pairs_fn=pairs_dense):
    """FluidNexus Eq. 2: V(q) = sum_j u_j W / sum_j W (0 where no particle is within h)."""
    i, j = pairs_fn(p, h, q)
    w = poly6(((q[i] - p[j]) ** 2).sum(-1), h)
    num = scatter(w[:, None] * u[j], i, len(q))
    den = scatter(w, i, len(q))
    return torch.where(den[:, None] > 0, num / den.clamp(min=TINY)[:, None], torch.zeros_like(num))


def density_at(q, p, h, pairs_fn=pairs_dense):
    """rho(q) = sum_j W(q - p_j) [1/m^3]."""
    i, j = pairs_fn(p, h, q)
    return scatter(poly6(((q[i] - p[j]) ** 2).sum(-1), h), i, len(q))


def advect(x, p, u, dt, h, order=1, pairs_fn=pairs_dense):
    """Euler x + dt V(x), or midpoint x + dt V(x + dt/2 V(x)) for order 2."""
    if order == 1:
        return x + dt * velocity_at(x, p, u, h, pairs_fn)
    mid = x + 0.5 * dt * velocity_at(x, p, u, h, pairs_fn)
    return x + dt * velocity_at(mid, p, u, h, pairs_fn)
