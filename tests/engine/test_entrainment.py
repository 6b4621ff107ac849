"""The entrainment term (engine/entrainment.py): nothing at alpha 0, the plume's radius, momentum and smoke kept,
and a plume that widens with height faster the larger alpha."""
import numpy as np

from fluidnexus.engine.entrainment import Entrainment, entrain, plume_radius


def _plume(engine, alpha: float, steps: int = 40):
    """A plume of the paper's gas from a disk source: (positions, volumes) after ``steps`` steps."""
    spacing = 0.02
    h = spacing / 0.45
    solver = engine.SolverConfig(h=h, rest_density=engine.rest_density_for_lattice(spacing, h, 1.44), iterations=4,
                                 dt=1.0 / 30.0)
    model = engine.ModelConfig((engine.Buoyancy(alpha=-0.3), engine.Drag(k=3.0)),
                               entrainment=Entrainment(alpha) if alpha is not None else None)
    source = engine.SourceDisk(center=(0.0, 0.0, 0.0), radius=0.06, spacing=spacing)
    parts = engine.PhysicalParticles(source.count * steps + 8)
    sim = engine.PBFSimulator(parts.capacity, solver, model)
    rng = np.random.default_rng(0)
    for t in range(steps):
        if t % 2 == 0:
            pts = source.sample(rng)
            parts.add(position=pts, velocity=np.tile([0.0, 0.3, 0.0], (len(pts), 1)))
        engine.step_particles(sim, parts)
    return parts.get("position"), parts.get("volume")


def test_alpha_zero_changes_nothing(ti_engine):
    """A model with entrainment 0 rolls out bit for bit as the paper's gas (the null candidate of diagnose)."""
    p0, v0 = _plume(ti_engine, None, 12)
    p1, v1 = _plume(ti_engine, 0.0, 12)
    np.testing.assert_array_equal(p0, p1)
    assert np.all(v1 == 1.0)


def test_plume_radius_of_a_disk():
    """Particles spread uniformly over disks of radius R: the top-hat radius sqrt(2 <r^2>) is R."""
    rng = np.random.default_rng(1)
    r, phi = 0.1 * np.sqrt(rng.uniform(size=4000)), rng.uniform(0, 2 * np.pi, 4000)
    y = rng.uniform(0, 0.5, 4000)
    p = np.stack([0.3 + r * np.cos(phi), y, -0.2 + r * np.sin(phi)], -1)
    b = plume_radius(p, np.array([0.0, 1.0, 0.0]), 0.05)
    assert abs(np.median(b) - 0.1) < 0.005, np.median(b)


def test_growth_keeps_momentum_relative_to_the_air(ti_engine):
    """Each particle's volume times its velocity relative to the ambient air is kept (the air takes its share)."""
    engine = ti_engine
    model = engine.ModelConfig((engine.Buoyancy(alpha=-0.3), engine.Drag(k=3.0, v_env=(0.05, 0.0, 0.0))),
                               entrainment=Entrainment(0.12))
    rng = np.random.default_rng(2)
    p, u, vol = rng.uniform(0, 0.2, (50, 3)), rng.normal(0, 0.3, (50, 3)), rng.uniform(1, 2, 50)
    u1, vol1 = entrain(model, p, u, vol, engine.SolverConfig(h=0.04))
    env = np.array([0.05, 0.0, 0.0])
    assert np.all(vol1 > vol)
    np.testing.assert_allclose(vol1[:, None] * (u1 - env), vol[:, None] * (u - env), rtol=1e-12)


def test_the_plume_widens_with_height_at_a_rate_set_by_alpha(ti_engine):
    """The width (horizontal std) against height: the paper's gas stays a column; with entrainment the slope grows
    with alpha, and no smoke is lost (every emitted particle is still there)."""
    slopes, counts = {}, {}
    for alpha in (0.0, 0.1, 0.2):
        p, vol = _plume(ti_engine, alpha)
        counts[alpha] = len(p)
        bins = np.linspace(0.05, np.percentile(p[:, 1], 90), 6)
        k = np.digitize(p[:, 1], bins)
        mid = [(p[k == i, 1].mean(), np.hypot(p[k == i, 0].std(), p[k == i, 2].std())) for i in range(1, len(bins))
               if (k == i).sum() >= 5]
        hgt, wid = np.array(mid).T
        slopes[alpha] = np.polyfit(hgt, wid, 1)[0]
    assert len(set(counts.values())) == 1, counts
    assert slopes[0.1] > slopes[0.0] + 0.03 and slopes[0.2] > slopes[0.1] + 0.03, slopes
