"""Test-only control data: a plume made by the paper's PBF gas itself (the engine), with inflow jitter.

Diagnose's structure level must keep the paper's gas for it (a model that diagnoses data made by itself is the
control, not evidence). It differs from diagnose's own rollout: a finer lattice (0.015 m), 6 solver iterations,
a jittered source lattice and an inflow speed drawn per emitted layer (+-20 % around 0.25 m/s). The particles are
binned onto the Eulerian generator's grid and rendered by the same code (eulerian_plume.write_scene).
"""
from __future__ import annotations

import numpy as np

from fluidnexus import engine

from .eulerian_plume import Grid

SPACING, INFLOW, JITTER = 0.015, 0.25, 0.2


def simulate_pbf(frames: int, alpha: float = -0.04, k: float = 3.0, grid: Grid = Grid(), seed: int = 0,
                 entrainment: float | None = None, spacing: float = SPACING, iterations: int = 6) -> np.ndarray:
    """Smoke density [frames, nx, ny, nz] (particle counts per grid cell) of the paper's gas, frame 0 empty;
    ``entrainment``: the gas's entrainment coefficient (engine/entrainment.py), None for none; ``spacing``: the
    lattice [m]; ``iterations``: solver iterations per step."""
    h = spacing / 0.45
    solver = engine.SolverConfig(h=h, rest_density=engine.rest_density_for_lattice(spacing, h, 1.44),
                                 iterations=iterations,
                                 dt=1.0 / grid.fps)
    src = engine.SourceDisk(center=grid.source, radius=grid.source_radius, spacing=spacing, jitter=0.3)
    parts = engine.PhysicalParticles(src.count * frames + 16)
    model = engine.ModelConfig((engine.Buoyancy(alpha=alpha), engine.Drag(k=k)),
                               entrainment=None if entrainment is None else engine.Entrainment(entrainment))
    sim = engine.PBFSimulator(parts.capacity, solver, model)
    lo = np.asarray(grid.lo)
    hi = lo + np.asarray(grid.shape) * grid.dx
    edges = [lo[a] + grid.dx * np.arange(grid.shape[a] + 1) for a in range(3)]
    rng, phase = np.random.default_rng(seed), 1.0
    out = [np.zeros(grid.shape)]
    for _ in range(1, frames):
        phase += INFLOW / (spacing * grid.fps)
        if phase >= 1.0:
            phase -= 1.0
            pts = src.sample(rng)
            speed = INFLOW * (1.0 + rng.uniform(-JITTER, JITTER))
            parts.add(position=pts, velocity=np.tile([0.0, speed, 0.0], (len(pts), 1)))
        engine.step_particles(sim, parts)
        engine.prune(parts, None, h, lo - 0.1, hi + 0.1)
        out.append(np.histogramdd(parts.get("position"), bins=edges)[0])
    return np.asarray(out)
