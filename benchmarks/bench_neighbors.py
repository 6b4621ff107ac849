"""Benchmark of the neighbour search (engine/neighbors.py): ms per table build on jittered lattices.

Usage: python benchmarks/bench_neighbors.py [--arch cpu|cuda] [--repeats 30] [--rounds 3]
Prints a markdown table: points, mean neighbours, the median over ``rounds`` of the mean build time over
``repeats`` builds (a build: cell assignment, sort, fill), at H = lattice spacing / 0.45 (the engine's ratio).
Cases: a compact cube of particles (4.9 k, 13.8 k, 64 k) and the 4.9 k split into two clusters 50 m apart. Run it in
two checkouts one after the other, twice, to compare them (BENCHMARKS.md: single runs moved by 2x on a shared VM).
"""
import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluidnexus import engine  # noqa: E402

SPACING = 0.01
H = SPACING / 0.45


def lattice(side: int, seed: int = 0) -> np.ndarray:
    """A cube of side**3 points on the lattice, each moved by up to 0.2 spacings."""
    g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3) * SPACING
    return g + np.random.default_rng(seed).uniform(-0.2, 0.2, g.shape) * SPACING + 0.3


def cases() -> list[tuple[str, np.ndarray]]:
    small = lattice(17)
    half = len(small) // 2
    apart = np.concatenate([small[:half], small[half:] + 50.0])
    return [("4.9 k, one cube", small), ("13.8 k, one cube", lattice(24)), ("64 k, one cube", lattice(40)),
            ("4.9 k, two clusters 50 m apart", apart)]


def time_builds(points: np.ndarray, repeats: int, rounds: int) -> tuple[float, float]:
    """(median over rounds of ms per build, mean neighbours)."""
    import taichi as ti

    n = len(points)
    field = ti.Vector.field(3, engine.real(), shape=n)
    field.from_numpy(points.astype(np.float32))  # engine.init's default precision
    table = engine.NeighborTable(n)
    table.build(field, n, H)
    times = []
    for _ in range(rounds):
        ti.sync()
        t = time.perf_counter()
        for _ in range(repeats):
            table.build(field, n, H)
        ti.sync()
        times.append((time.perf_counter() - t) / repeats * 1000.0)
    return float(np.median(times)), float(table.counts().mean())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    engine.init(arch=args.arch)
    print(f"machine: {platform.node()} {platform.processor() or platform.machine()}, arch {args.arch}, f32")
    print("| case | points | mean neighbours | ms per build |")
    print("|---|---|---|---|")
    for name, pts in cases():
        ms, nbrs = time_builds(pts, args.repeats, args.rounds)
        print(f"| {name} | {len(pts)} | {nbrs:.1f} | {ms:.2f} |")


if __name__ == "__main__":
    main()
