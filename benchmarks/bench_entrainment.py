"""Benchmark of the entrainment term: ms per step of the paper's gas (``step_particles``, 10 solver iterations) with
and without entrainment, and the entrainment pass alone, at about 4.6 k and 39 k particles.

Usage: python benchmarks/bench_entrainment.py [--arch cpu|cuda] [--repeats 5]
States as benchmarks/bench_pbf.py: the release's lattice (0.009 m, H = 0.02 m) in a cylinder of radius 0.10 m;
ScalarFlow model (buoyancy -3, drag 3), entrainment alpha 0.1. Prints a markdown table; the ratio is measured in
the same run.
"""
import argparse
import platform
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.bench_pbf import CASES, _time  # noqa: E402
from fluidnexus import engine  # noqa: E402
from fluidnexus.engine.entrainment import Entrainment, entrain  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    engine.init(arch=args.arch, precision="f32")
    solver = engine.SolverConfig()
    plain = engine.ModelConfig.scalarflow()
    entraining = replace(plain, entrainment=Entrainment(0.1))
    print(f"machine: {platform.processor() or platform.machine()}, arch {args.arch}, f32, {args.repeats} repeats")
    print("| particles | step, paper's gas [ms] | step with entrainment [ms] | ratio | entrainment pass alone [ms] |")
    print("|---|---|---|---|---|")
    for name, y1 in CASES:
        p = engine.cylinder_lattice((0.34, -0.225), 0.10, -0.02, y1, 0.009)
        u = np.random.default_rng(0).normal(0.0, 0.05, p.shape)
        times = []
        for model in (plain, entraining):
            parts = engine.PhysicalParticles(len(p))
            parts.add(position=p, velocity=u)
            sim = engine.PBFSimulator(len(p), solver, model)

            def step():
                parts.keep(np.ones(parts.n, bool))  # same state every repeat: reload the lattice
                parts.set("position", p)
                parts.set("velocity", u)
                parts.set("volume", np.ones(len(p)))
                engine.step_particles(sim, parts)

            times.append(_time(step, args.repeats))
        vol = np.ones(len(p))
        alone = _time(lambda: entrain(entraining, p, u, vol, solver), args.repeats)
        print(f"| {name}: {len(p)} | {times[0]:.1f} | {times[1]:.1f} | {times[1] / times[0]:.2f} | {alone:.1f} |")


if __name__ == "__main__":
    main()
