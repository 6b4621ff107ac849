"""The gas in ambient air (engine/ambient.py): buoyancy on smoke only, open boundaries, inlet, wind, model.json."""
import numpy as np
import pytest
import torch

from reference import pbf_reference as ref

SOURCE, RADIUS = (0.3, 0.0, -0.2), 0.05
SPACING = 0.03  # the lattice spacing the solver's H and rho0 follow (diagnose's ratios)


def _solver(engine, iterations=4):
    h = SPACING / 0.45
    return engine.SolverConfig(h=h, rest_density=engine.rest_density_for_lattice(SPACING, h, 1.44),
                               iterations=iterations, dt=1.0 / 30.0)


def _domain(engine, solver, **air):
    lo, hi = np.array([0.0, -0.05, -0.5]), np.array([0.6, 0.6, 0.1])
    return engine.AirDomain(engine.AmbientAir(**air), solver.h, solver.rest_density, solver.dt, SOURCE, RADIUS, lo, hi)


def _run(engine, steps, alpha=0.0, c=0.3, **air):
    solver = _solver(engine)
    dom = _domain(engine, solver, **air)
    model = engine.ModelConfig((engine.Buoyancy(alpha=alpha), engine.Viscosity(c=c)), dom.air)
    sim = engine.PBFSimulator(dom.capacity(), solver, model)
    state, history = dom.initial(), []
    for _ in range(steps):
        state = dom.step(sim, state)
        history.append(state)
    return dom, history


def test_buoyancy_acts_on_smoke_only_and_matches_the_reference(ti_engine):
    """Two blobs far apart, one smoke and one air: buoyancy lifts the smoke blob, the air blob's centre of mass
    stays put; forward and gradients match the torch reference with the same smoke weights."""
    engine = ti_engine
    rng = np.random.default_rng(3)
    blob = rng.uniform(0, 0.03, (20, 3))
    p = np.concatenate([blob, blob + [0.5, 0.0, 0.0]])
    smoke = np.r_[np.ones(20), np.zeros(20)]
    model = engine.ModelConfig((engine.Buoyancy(alpha=-0.5, decay=0.3), engine.Viscosity(c=0.2)))
    solver = engine.SolverConfig(iterations=3, averaging=False, rest_density=1.2e6)
    sim = engine.PBFSimulator(48, solver, model)
    P, U = torch.tensor(p, requires_grad=True), torch.zeros((40, 3), dtype=torch.float64, requires_grad=True)
    th = torch.tensor(model.to_vector(), requires_grad=True)
    age = torch.tensor(rng.uniform(0, 1, 40))
    p1, u1 = engine.simulate_step(P, U, th, sim, age, torch.tensor(smoke))
    rise = (p1[:20, 1] - P[:20, 1]).mean().item()
    assert rise > 1e-4
    assert abs((p1[20:] - P[20:]).mean(0)).max().item() < 1e-12
    rP, rU, rth = (t.detach().clone().requires_grad_(True) for t in (P, U, th))
    rp1, ru1 = ref.step(rP, rU, rth, model, solver, age, smoke=torch.tensor(smoke))
    torch.testing.assert_close(p1, rp1, rtol=0, atol=1e-12)
    w = torch.tensor(rng.normal(size=(40, 3)))
    ((p1 * w).sum() + (u1 * w).sum()).backward()
    ((rp1 * w).sum() + (ru1 * w).sum()).backward()
    for mine, theirs in ((P.grad, rP.grad), (th.grad, rth.grad)):
        torch.testing.assert_close(mine, theirs, rtol=1e-8, atol=1e-8 * theirs.abs().max().item())
    # the default smoke weight (every particle smoke) is the paper's gas, to the last bit
    sim.load(p, np.zeros((40, 3)), age)
    sim.forward()
    a = sim.result()[0]
    sim.load(p, np.zeros((40, 3)), age, np.ones(40))
    sim.forward()
    assert torch.equal(a, sim.result()[0])


def test_open_boundaries_keep_the_particle_count_bounded(ti_engine):
    """A plume rising through air for 40 steps: the count never exceeds the lattice sites of the air region and
    its shell by more than 25 % (measured up to 16 %; 1.02-1.18 over 110 steps), nor the domain's capacity, and
    air never counts as smoke."""
    engine = ti_engine
    dom, history = _run(engine, 40, alpha=-0.1)
    for state in history:
        smoke_p = state.p[state.is_smoke]
        sites = len(dom.sites(*dom.outer(*dom.region(smoke_p))))
        assert state.n <= 1.25 * sites, (state.n, sites)
        assert state.n <= dom.capacity()
        assert set(np.unique(state.smoke)) <= {0.0, 1.0}
    assert history[-1].is_smoke.sum() < 0.2 * history[-1].n  # mostly air


def test_inlet_turns_air_into_smoke_at_the_inflow_speed(ti_engine):
    """Without buoyancy, smoke appears at the inlet's particle flux (rest number density x disk area x inflow)
    and leaves the source at the inflow speed."""
    engine = ti_engine
    inflow = 0.3
    dom, history = _run(engine, 30, alpha=0.0, inflow=inflow)
    counts = np.array([s.is_smoke.sum() for s in history])
    rate = (counts[-1] - counts[9]) / (20 * dom.dt)
    expected = np.pi * RADIUS**2 * inflow / dom.spacing**3  # number density at rest x area x speed
    assert abs(rate - expected) < 0.25 * expected, (rate, expected)
    last = history[-1]
    young = last.is_smoke & (last.age < 0.2) & (last.p[:, 1] > SOURCE[1])
    vy = last.u[young, 1].mean()
    assert abs(vy - inflow) < 0.25 * inflow, vy


def test_wind_shifts_the_plume_downwind(ti_engine):
    """The air's motion carries the smoke: the smoke centroid drifts toward the wind, by a good part of
    wind x (mean smoke age), and not sideways."""
    engine = ti_engine
    wind = np.array([0.0, 0.0, 0.12])
    _, calm = _run(engine, 24, alpha=-0.1)
    _, windy = _run(engine, 24, alpha=-0.1, wind=tuple(wind))
    a, b = calm[-1], windy[-1]
    shift = b.p[b.is_smoke].mean(0) - a.p[a.is_smoke].mean(0)
    expected = wind[2] * b.age[b.is_smoke].mean()
    assert shift[2] > 0.4 * expected, (shift, expected)
    assert abs(shift[0]) < 0.3 * shift[2], shift


def test_model_json_round_trip_and_old_files(ti_engine):
    engine = ti_engine
    air = engine.AmbientAir(inflow=0.3, wind=(0.1, 0.0, -0.05), margin=1.2, below=1.0)
    model = engine.ModelConfig((engine.Buoyancy(alpha=-0.1), engine.Viscosity(c=0.3)), air)
    d = model.to_dict()
    assert d["structure"] == {"name": "ambient_air", "inflow": 0.3, "wind": [0.1, 0.0, -0.05], "margin": 1.2,
                              "below": 1.0}
    back = engine.ModelConfig.from_dict(d)
    assert back == model and back.structure == "ambient_air"
    assert model.with_vector(model.to_vector()).air == air  # refitting the terms keeps the structure
    old = engine.ModelConfig.from_dict({"terms": d["terms"]})  # a model.json from before structures
    assert old.structure == "paper_gas" and old.air is None
    assert engine.ModelConfig.scalarflow().to_dict()["structure"] == {"name": "paper_gas"}
    for bad in ({"name": "vacuum"}, {"name": "paper_gas", "inflow": 1.0}, {"name": "ambient_air", "speed": 1.0},
                {"name": "ambient_air", "inflow": -1.0}):
        with pytest.raises(ValueError):
            engine.ModelConfig.from_dict({"terms": [], "structure": bad})


def test_air_around_smoke_at_any_positions_does_not_compress_it(ti_engine):
    """Smoke at random positions (a reconstructed state) at about the rest density: the air placed around it
    raises the density among the smoke by less than 20 % (air on every site no smoke particle is near: about
    45 %), fills the rest of the region, and stays out of an obstacle."""
    from fluidnexus.engine.obstacle import SphereObstacle
    from fluidnexus.engine.sph import point_density

    engine = ti_engine
    solver = _solver(engine)
    dom = _domain(engine, solver)
    rng = np.random.default_rng(5)
    center = np.asarray(SOURCE) + [0.0, 0.15, 0.0]
    n = int(4.0 / 3.0 * np.pi * 0.08**3 / dom.spacing**3)  # the rest number density in a ball of 8 cm
    d = rng.normal(size=(n, 3))
    smoke = center + 0.08 * d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0, 1, (n, 1)) ** (1 / 3)
    core = np.linalg.norm(smoke - center, axis=1) < 0.05
    alone = np.median(point_density(smoke[core], smoke, solver.h))
    state = dom.initial(smoke)
    assert np.median(point_density(smoke[core], state.p, solver.h)) < 1.2 * alone
    air = state.p[~state.is_smoke]
    assert len(air) > 0.8 * len(dom.sites(*dom.outer(*dom.region(smoke)))) - n
    ball = (np.asarray(SOURCE) + [0.15, 0.1, 0.0], 0.04)
    assert np.linalg.norm(air - ball[0], axis=1).min() < ball[1]
    dom.obstacle = SphereObstacle(*ball)
    state = dom.initial(smoke)
    assert np.linalg.norm(state.p[~state.is_smoke] - ball[0], axis=1).min() > ball[1]
