"""Benchmark of the gas in ambient air against the paper's gas at the same smoke particle count.

Usage: python benchmarks/bench_ambient.py [--arch cpu|cuda] [--steps 48] [--spacing 0.03] [--repeats 2]
       python benchmarks/bench_ambient.py --run RUN [--steps 10] [--arch cpu|cuda]

Both plumes rise from a 5 cm source at 0.25 m/s for ``--steps`` steps of 1/30 s (4 solver iterations, the
solver's H and rho0 follow ``--spacing`` with diagnose's ratios; buoyancy alpha -0.15, XSPH c 0.4 in both):
- ``ambient_air``: engine/ambient.py (inlet, air region, open boundaries; housekeeping included in the time);
- ``paper_gas``: disk layers of the air lattice's spacing emitted at the inflow speed (one layer each
  spacing / inflow seconds, as diagnose's plume does), so its smoke count grows at the inlet's rate.
Prints wall and CPU (process) ms per step (mean over the rollout, best of the repeats; the first rollout of each is
a warm-up that compiles), the smoke and total particle counts at the last step, and the ratios, measured in the
same run. On a shared machine the CPU time is the steadier figure.

With ``--run``: predict's physics rollout (``predict.rollout``: emission, step, advection of the Gaussians) from the
run's last frame with the same terms in both structures and the run's solver, the ambient-air one around the run's
reconstructed smoke (``predict/air.py``); the first frame of each is a warm-up that compiles.
"""
import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluidnexus import engine  # noqa: E402

SOURCE, RADIUS, INFLOW, FPS = (0.3, 0.0, -0.2), 0.05, 0.25, 30.0


def _solver(spacing: float) -> engine.SolverConfig:
    h = spacing / 0.45
    return engine.SolverConfig(h=h, rest_density=engine.rest_density_for_lattice(spacing, h, 1.44), iterations=4,
                               dt=1.0 / FPS)


def _terms():
    return (engine.Buoyancy(alpha=-0.15), engine.Viscosity(c=0.4))


def run_air(solver, steps: int) -> tuple[float, float, int, int, float]:
    lo, hi = np.array([0.0, -0.1, -0.5]), np.array([0.6, 0.8, 0.1])
    dom = engine.AirDomain(engine.AmbientAir(inflow=INFLOW), solver.h, solver.rest_density, solver.dt, SOURCE,
                           RADIUS, lo, hi)
    sim = engine.PBFSimulator(dom.capacity(), solver, engine.ModelConfig(_terms(), dom.air))
    state = dom.initial()
    t, c = time.perf_counter(), time.process_time()
    for _ in range(steps):
        state = dom.step(sim, state)
    return ((time.perf_counter() - t) / steps * 1000.0, (time.process_time() - c) / steps * 1000.0,
            int(state.is_smoke.sum()), state.n, dom.spacing)


def run_gas(solver, steps: int, spacing: float) -> tuple[float, float, int, int]:
    src = engine.SourceDisk(center=SOURCE, radius=RADIUS, spacing=spacing, velocity=(0.0, INFLOW, 0.0))
    parts = engine.PhysicalParticles(src.count * (steps + 1))
    sim = engine.PBFSimulator(parts.capacity, solver, engine.ModelConfig(_terms()))
    rng, phase, per_step = np.random.default_rng(0), 1.0, INFLOW / (spacing * FPS)
    t, c = time.perf_counter(), time.process_time()
    for _ in range(steps):
        phase += per_step
        if phase >= 1.0:
            phase -= 1.0
            src.emit(parts, 0, rng)
        engine.step_particles(sim, parts)
    return (time.perf_counter() - t) / steps * 1000.0, (time.process_time() - c) / steps * 1000.0, parts.n, parts.n


def run_predict(run_dir: Path, steps: int) -> None:
    from fluidnexus.engine.tensors import torch_dtype
    from fluidnexus.predict.rollout import RunContext, rollout, workspace_for
    from fluidnexus.recon.smoke import Smoke
    from fluidnexus.runs import open_run

    run = open_run(run_dir)
    ctx = RunContext.of(run)
    start = Smoke.from_state(run.state(run.frames[-1]), torch_dtype())
    print(f"load average {os.getloadavg()[0]:.1f}; {run_dir} frame {start.frame}: {start.p.shape[0]} physical "
          f"particles, {start.x.shape[0]} Gaussians; H {ctx.solver.h} m, {ctx.solver.iterations} iterations; "
          f"{steps} steps after a warm-up")
    print("| structure | wall ms per step | CPU ms per step | smoke particles at the end | all particles at the end |")
    print("|---|---|---|---|---|")
    for air in (None, engine.AmbientAir(inflow=INFLOW)):
        ws = workspace_for(start, steps + 1, ctx, engine.ModelConfig(_terms(), air))
        frames = rollout(start, steps + 1, ws, ctx)
        next(frames)
        t, c = time.perf_counter(), time.process_time()
        for smoke in frames:
            pass
        wall, cpu = (time.perf_counter() - t) / steps * 1000.0, (time.process_time() - c) / steps * 1000.0
        name = "paper_gas" if air is None else air.name
        print(f"| {name} | {wall:.1f} | {cpu:.1f} | {smoke.p.shape[0]} | {ws.sim.n} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--steps", type=int, default=48)
    ap.add_argument("--spacing", type=float, default=0.03)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--run", type=Path, help="time predict's rollout from this run's last frame instead")
    args = ap.parse_args()
    engine.init(arch=args.arch)
    if args.run is not None:
        run_predict(args.run, args.steps)
        return
    solver = _solver(args.spacing)
    air = [run_air(solver, args.steps) for _ in range(args.repeats + 1)][1:]
    rest = air[0][4]
    gas = [run_gas(solver, args.steps, rest) for _ in range(args.repeats + 1)][1:]
    wall = [min(r[0] for r in runs) for runs in (gas, air)]
    cpu = [min(r[1] for r in runs) for runs in (gas, air)]
    print(f"machine: {platform.machine()} {platform.processor() or ''} arch {args.arch}, load average "
          f"{os.getloadavg()[0]:.1f}; {args.steps} steps, lattice ratios of {args.spacing} m (air spacing "
          f"{rest:.4f} m, H {solver.h:.4f} m), best of {args.repeats}")
    print("| structure | wall ms per step | CPU ms per step | smoke particles at the end | all particles at the end |")
    print("|---|---|---|---|---|")
    for name, w, c, r in (("paper_gas", wall[0], cpu[0], gas[0]), ("ambient_air", wall[1], cpu[1], air[0])):
        print(f"| {name} | {w:.1f} | {c:.1f} | {r[2]} | {r[3]} |")
    print(f"ratio ambient_air / paper_gas: wall {wall[1] / wall[0]:.1f} x, CPU {cpu[1] / cpu[0]:.1f} x")


if __name__ == "__main__":
    main()
