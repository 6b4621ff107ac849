"""Benchmark of the PBF gas step: ms per 10-iteration step, forward and forward+backward, vs the torch reference.

Usage: python benchmarks/bench_pbf.py [--arch cpu|cuda] [--precision f32|f64] [--repeats 5]
Prints a markdown table. States: the release's lattice (0.009 m, H = 0.02 m) in a cylinder of radius 0.10 m,
cut at a height that gives about 4.6 k and 39 k particles; ScalarFlow model (buoyancy -3, drag 3).
"""
import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from fluidnexus import engine  # noqa: E402

CASES = (("4.6k (ScalarFlow)", 0.08), ("39k (FluidNexus-Smoke)", 0.90))


def _time(fn, repeats: int) -> float:
    fn()
    t = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t) / repeats * 1000.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--precision", default="f32", choices=["f32", "f64"])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ref-repeats", type=int, default=1)
    args = ap.parse_args()
    engine.init(arch=args.arch, precision=args.precision)
    from reference import pbf_reference as ref

    solver, model = engine.SolverConfig(), engine.ModelConfig.scalarflow()
    dtype = torch.float32 if args.precision == "f32" else torch.float64
    rows = []
    for name, y1 in CASES:
        p = engine.cylinder_lattice((0.34, -0.225), 0.10, -0.02, y1, 0.009)
        n = len(p)
        rng = np.random.default_rng(0)
        u = rng.normal(0.0, 0.05, p.shape)
        sim = engine.PBFSimulator(n, solver, model)
        sim.load(p, u)
        gp = torch.as_tensor(rng.normal(size=p.shape), dtype=dtype)

        def fwd():
            sim.forward()
            sim.result()

        def fwd_bwd():
            fwd()
            sim.backward(gp, gp)

        t_f, t_fb = _time(fwd, args.repeats), _time(fwd_bwd, args.repeats)
        P, U = torch.as_tensor(p, dtype=dtype), torch.as_tensor(u, dtype=dtype)
        theta = torch.as_tensor(model.to_vector(), dtype=dtype)
        t_ref = _time(lambda: ref.step(P, U, theta, model, solver, pairs_fn=ref.pairs_kdtree), args.ref_repeats)
        rows.append((name, n, t_f, t_fb, t_ref))
    print(f"machine: {platform.processor() or platform.machine()}, {torch.get_num_threads()} torch threads, "
          f"arch={args.arch}, precision={args.precision}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print("| N | particles | forward ms | fwd+bwd ms | fwd+bwd / fwd | torch reference fwd ms | reference / taichi |")
    print("|---|---|---|---|---|---|---|")
    for name, n, t_f, t_fb, t_ref in rows:
        print(f"| {name} | {n} | {t_f:.1f} | {t_fb:.1f} | {t_fb / t_f:.2f} | {t_ref:.0f} | {t_ref / t_f:.1f}x |")


if __name__ == "__main__":
    main()
