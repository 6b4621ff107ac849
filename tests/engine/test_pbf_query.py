"""V(x), rho(x) (FluidNexus Eq. 2), advection and the divergence metric vs the torch reference."""
import numpy as np
import pytest
import torch

from reference import pbf_reference as ref

H = 0.02


def _cloud(seed=0, n=48, m=30):
    rng = np.random.default_rng(seed)
    p = torch.tensor(rng.uniform(0, 0.04, (n, 3)), requires_grad=True)
    u = torch.tensor(rng.normal(0, 0.3, (n, 3)), requires_grad=True)
    q = torch.tensor(rng.uniform(-0.01, 0.05, (m, 3)), requires_grad=True)
    return p, u, q


def _leaves(*ts):
    return [t.detach().clone().requires_grad_(True) for t in ts]


@pytest.mark.parametrize("what", ["velocity", "density", "advect1", "advect2"])
def test_queries_match_reference(ti_engine, what):
    engine = ti_engine
    query = engine.FieldQuery(64, 64, H)
    p, u, q = _cloud()
    rp, ru, rq = _leaves(p, u, q)
    dt = 1.0 / 30.0
    if what == "velocity":
        out, expect = engine.velocity_at(q, p, u, query), ref.velocity_at(rq, rp, ru, H)
    elif what == "density":
        out, expect = engine.density_at(q, p, query), ref.density_at(rq, rp, H)
    else:
        order = int(what[-1])
        out, expect = engine.advect(q, p, u, dt, query, order), ref.advect(rq, rp, ru, dt, H, order)
    scale = expect.detach().abs().max().item()
    assert scale > 0
    torch.testing.assert_close(out, expect, rtol=0, atol=1e-12 * scale)
    w = torch.tensor(np.random.default_rng(1).normal(size=out.shape))
    (out * w).sum().backward()
    (expect * w).sum().backward()
    for mine, theirs in ((q.grad, rq.grad), (p.grad, rp.grad)) + (((u.grad, ru.grad),) if what != "density" else ()):
        torch.testing.assert_close(mine, theirs, rtol=1e-9, atol=1e-9 * theirs.abs().max().item())


def test_velocity_gradient_matches_finite_differences(ti_engine):
    engine = ti_engine
    query = engine.FieldQuery(64, 64, H)
    p, u, q = _cloud(seed=3)
    w = np.random.default_rng(2).normal(size=(len(q), 3))
    q0, p0 = q.detach().numpy(), p.detach().numpy()

    def loss(qq, pp):
        with torch.no_grad():
            return float((engine.velocity_at(torch.tensor(qq), torch.tensor(pp), u.detach(), query).numpy() * w).sum())

    (engine.velocity_at(q, p, u, query) * torch.tensor(w)).sum().backward()
    eps = 1e-7
    for arr, grad, idx in ((q0, q.grad, (4, 1)), (q0, q.grad, (9, 2)), (p0, p.grad, (7, 0)), (p0, p.grad, (20, 1))):
        plus, minus = arr.copy(), arr.copy()
        plus[idx] += eps
        minus[idx] -= eps
        args_p = (plus, p0) if arr is q0 else (q0, plus)
        args_m = (minus, p0) if arr is q0 else (q0, minus)
        fd = (loss(*args_p) - loss(*args_m)) / (2 * eps)
        assert abs(fd - grad[idx].item()) <= 1e-5 * max(1.0, abs(fd))


def test_point_without_neighbours_does_not_move(ti_engine):
    engine = ti_engine
    query = engine.FieldQuery(8, 8, H)
    p = torch.zeros((2, 3), dtype=torch.float64)
    u = torch.ones((2, 3), dtype=torch.float64)
    x = torch.tensor([[1.0, 1.0, 1.0], [0.001, 0.0, 0.0]], dtype=torch.float64)
    out = engine.advect(x, p, u, 0.1, query)
    assert torch.equal(out[0], x[0])
    torch.testing.assert_close(out[1], x[1] + 0.1)


def test_divergence_metric_on_known_fields(ti_engine):
    engine = ti_engine
    p = engine.cylinder_lattice((0.0, 0.0), 0.06, -0.06, 0.06, 0.009)
    query = engine.FieldQuery(len(p), 4096, H)
    lo, hi, res = (-0.03, -0.03, -0.03), (0.03, 0.03, 0.03), (9, 9, 9)
    uniform = np.tile([0.1, -0.2, 0.3], (len(p), 1))
    div, rho = engine.divergence_on_grid(query, p, uniform, lo, hi, res)
    assert div.shape == (7, 7, 7) and (rho > 0).all()
    assert np.abs(div).max() < 1e-10  # Shepard interpolation reproduces constants exactly
    expand = p * np.array([1.0, 2.0, 0.0])  # div = 3 for the linear field (x, 2y, 0)
    assert abs(engine.mean_abs_divergence(query, p, expand, lo, hi, res) - 3.0) < 0.15
