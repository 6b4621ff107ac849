"""The PBF step vs the torch reference (forward and ti.ad gradients) and vs central finite differences."""
import json

import numpy as np
import pytest
import torch

from reference import pbf_reference as ref



def _all_terms(engine):
    return engine.ModelConfig((engine.Buoyancy(alpha=-3.0, decay=0.7),
                               engine.Drag(k=3.0, v_env=(0.1, -0.05, 0.2)),
                               engine.Wind(accel=(0.3, 0.0, 0.1), profile="ramp", y0=0.0, height=0.03),
                               engine.Vorticity(epsilon=0.3), engine.Viscosity(c=0.2)))


def _state(n=40, seed=0):
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 0.035, (n, 3))
    u = rng.normal(0, 0.2, (n, 3))
    age = rng.uniform(0, 2.0, n)
    return p, u, age


@pytest.mark.parametrize("averaging, volumes", [(True, False), (False, False), (True, True)])
def test_step_matches_reference_forward_and_gradients(ti_engine, averaging, volumes):
    """``volumes``: particles of rest volumes between 1 and 2 (entrainment, engine/entrainment.py)."""
    engine = ti_engine
    model = _all_terms(engine)
    solver = engine.SolverConfig(iterations=4, averaging=averaging, rest_density=1.2e6)
    p, u, age = _state()
    vol = torch.tensor(np.random.default_rng(9).uniform(1.0, 2.0, len(p))) if volumes else None
    sim = engine.PBFSimulator(64, solver, model)
    P = torch.tensor(p, requires_grad=True)
    U = torch.tensor(u, requires_grad=True)
    th = torch.tensor(model.to_vector(), requires_grad=True)
    p1, u1 = engine.simulate_step(P, U, th, sim, torch.tensor(age), volume=vol)
    rP, rU, rth = (t.detach().clone().requires_grad_(True) for t in (P, U, th))
    rp1, ru1 = ref.step(rP, rU, rth, model, solver, torch.tensor(age), volume=vol)
    if volumes:  # a larger rest volume moves the particles apart: the step differs from the unit-volume one
        unit, _ = ref.step(rP.detach(), rU.detach(), rth.detach(), model, solver, torch.tensor(age))
        assert (unit - rp1).abs().max() > 1e-4
    assert (rp1 - torch.tensor(p)).abs().max() > 1e-3  # the step actually moves the particles
    torch.testing.assert_close(p1, rp1, rtol=0, atol=1e-12)
    torch.testing.assert_close(u1, ru1, rtol=0, atol=1e-10)
    rng = np.random.default_rng(5)
    wp, wu = torch.tensor(rng.normal(size=p.shape)), torch.tensor(rng.normal(size=p.shape))
    ((p1 * wp).sum() + (u1 * wu).sum()).backward()
    ((rp1 * wp).sum() + (ru1 * wu).sum()).backward()
    for mine, theirs in ((P.grad, rP.grad), (U.grad, rU.grad), (th.grad, rth.grad)):
        torch.testing.assert_close(mine, theirs, rtol=1e-8, atol=1e-8 * theirs.abs().max().item())
    assert th.grad.abs().min() > 0  # every model parameter receives a gradient


def test_a_simulator_given_other_terms_steps_as_a_new_one(ti_engine):
    """``set_model`` keeps the particles' fields and tables (diagnose's one simulator per structure): a step after
    models of other terms and other parameter counts, forward and gradients, is bit for bit a new simulator's."""
    engine = ti_engine
    solver = engine.SolverConfig(iterations=3, rest_density=1.2e6)
    models = [engine.ModelConfig((engine.Buoyancy(alpha=-3.0), engine.Drag(k=3.0), engine.Vorticity(epsilon=0.3))),
              engine.ModelConfig((engine.Buoyancy(alpha=-2.0), engine.Drag(k=1.0), engine.Viscosity(c=0.2))),
              engine.ModelConfig((engine.Buoyancy(alpha=-4.0, decay=0.5),)),
              engine.ModelConfig((engine.Buoyancy(alpha=-3.0), engine.Drag(k=3.0), engine.Vorticity(epsilon=0.3)))]
    p, u, age = _state()
    rng = np.random.default_rng(3)
    wp, wu = torch.tensor(rng.normal(size=p.shape)), torch.tensor(rng.normal(size=p.shape))

    def step(sim, model):
        P, U = torch.tensor(p, requires_grad=True), torch.tensor(u, requires_grad=True)
        th = torch.tensor(model.to_vector(), requires_grad=True)
        p1, u1 = engine.simulate_step(P, U, th, sim, torch.tensor(age))
        ((p1 * wp).sum() + (u1 * wu).sum()).backward()
        return p1.detach(), u1.detach(), P.grad, U.grad, th.grad

    shared = engine.PBFSimulator(64, solver, models[0])
    for model in models:
        shared.set_model(model)
        for a, b in zip(step(shared, model), step(engine.PBFSimulator(64, solver, model), model)):
            assert torch.equal(a, b)


def test_step_gradients_match_finite_differences(ti_engine):
    engine = ti_engine
    model = _all_terms(engine)
    solver = engine.SolverConfig(iterations=3, rest_density=1.2e6)
    p, u, age = _state(24, seed=1)
    sim = engine.PBFSimulator(32, solver, model)
    rng = np.random.default_rng(6)
    wp, wu = rng.normal(size=p.shape), rng.normal(size=p.shape)

    vol = np.random.default_rng(7).uniform(1.0, 1.5, len(p))  # rest volumes of entrained particles

    def loss(pp, uu, tt):
        sim.load_theta(tt)
        sim.load(pp, uu, age, volume=vol)
        sim.forward()
        a, b = sim.result()
        return float((a.numpy() * wp).sum() + (b.numpy() * wu).sum())

    theta = model.to_vector()
    loss(p, u, theta)
    gp, gu, gt = (g.numpy() for g in sim.backward(torch.tensor(wp), torch.tensor(wu)))
    checks = [("p", (3, 1)), ("p", (10, 0)), ("u", (5, 2)), ("u", (17, 1))] + [("t", (k,)) for k in range(len(theta))]
    for which, idx in checks:
        base = {"p": p, "u": u, "t": theta}[which]
        eps = 1e-7 if which == "p" else 1e-6
        plus, minus = base.copy(), base.copy()
        plus[idx] += eps
        minus[idx] -= eps
        args_p = [plus if which == w else {"p": p, "u": u, "t": theta}[w] for w in "put"]
        args_m = [minus if which == w else {"p": p, "u": u, "t": theta}[w] for w in "put"]
        fd = (loss(*args_p) - loss(*args_m)) / (2 * eps)
        ad = {"p": gp, "u": gu, "t": gt}[which][idx]
        assert abs(fd - ad) <= 1e-5 * max(1.0, abs(fd)), (which, idx, fd, ad)


def test_rollout_with_checkpointing_matches_reference(ti_engine):
    engine = ti_engine
    model = engine.ModelConfig.scalarflow()
    solver = engine.SolverConfig(iterations=2, rest_density=1.2e6)
    p, u, _ = _state(30, seed=2)
    sim = engine.PBFSimulator(32, solver, model)
    th = torch.tensor(model.to_vector(), requires_grad=True)
    rth = th.detach().clone().requires_grad_(True)
    P, U = torch.tensor(p), torch.tensor(u)
    rP, rU = P.clone(), U.clone()
    for _ in range(3):  # each backward replays its step: the fields only hold the last one
        P, U = engine.simulate_step(P, U, th, sim)
        rP, rU = ref.step(rP, rU, rth, model, solver)
    P[:, 1].sum().backward()
    rP[:, 1].sum().backward()
    torch.testing.assert_close(th.grad, rth.grad, rtol=1e-8, atol=1e-10)


def test_model_config_round_trips_through_json(ti_engine):
    engine = ti_engine
    model = _all_terms(engine)
    back = engine.ModelConfig.from_dict(json.loads(json.dumps(model.to_dict())))
    assert back == model
    assert len(model.param_names()) == len(model.to_vector()) == 11
    moved = model.with_vector(model.to_vector() + 1.0)
    assert moved.term("drag").v_env == (1.1, 0.95, 1.2)
    with pytest.raises(ValueError):
        engine.ModelConfig.from_dict({"terms": [{"kind": "nope"}]})
    with pytest.raises(ValueError):
        engine.Wind(profile="sideways")
