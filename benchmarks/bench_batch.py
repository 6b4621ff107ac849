"""Batch runs on Ray against a shell loop of single-scene commands, and Ray's own cost per task (docs/batch.md).

1. Sequential: two identical small scenes (the sample, four-view protocol) each run by hand as
   ``calibrate``, ``recon``, ``eval`` (the engine on all cores), one after the other.
2. Batch: the same two scenes as one ``fluidnexus batch`` with ``--cpus-per-scene`` (default 1: both scenes at once).
3. Ray's overhead: starting and stopping the local instance, and the round trip of a task that does nothing and
   one that imports the pipeline, each in a fresh worker process (``max_calls=1``, as the batch runs its steps).

    python benchmarks/bench_batch.py --work /tmp/bb
    python benchmarks/bench_batch.py --work /tmp/bb --recon "--frames 0:10 --resolution 0.25" --overhead-tasks 10
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cli(*args) -> float:
    tic = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fluidnexus_cli", *map(str, args)], cwd=ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - tic


def sequential(work: Path, recon: list[str]) -> dict:
    times = {}
    for name in ("a", "b"):
        scene, run = work / "seq" / name / "scene", work / "seq" / name / "run"
        t = cli("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--out", scene, "--overwrite")
        t += cli("recon", scene, "--out", run, "--arch", "cpu", *recon)
        t += cli("eval", run, "--json", work / "seq" / name / "eval.json", "--arch", "cpu")
        times[name] = round(t, 1)
    return times


def batch(work: Path, recon: list[str], cpus: float) -> tuple[float, dict]:
    pairs = [recon[i:i + 2] for i in range(0, len(recon), 2)]
    table = ", ".join(f"{k[2:].replace('-', '_')} = {json.dumps(_number(v))}" for k, v in pairs)
    manifest = work / "batch.toml"
    manifest.write_text(f'[defaults]\nsteps = ["recon", "eval"]\nrecon = {{ {table} }}\n'
                        + "".join(f'\n[[scene]]\nname = "{n}"\nsample = "scalarflow"\nprotocol = "four-view"\n'
                                  for n in ("a", "b")))
    out = work / "batch"
    tic = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fluidnexus_cli", "batch", str(manifest), "--out", str(out),
                    "--cpus-per-scene", str(cpus)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - tic
    record = json.loads((out / "batch.json").read_text())
    return wall, {n: s["seconds"] for n, s in record["scenes"].items()}


def _number(text: str):
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _noop() -> float:
    return time.time()


def _import_pipeline() -> float:
    import fluidnexus_cli.main  # noqa: F401  (what every batch step imports first)

    return time.time()


def overhead(tasks: int) -> dict:
    import ray

    tic = time.perf_counter()
    ray.init(num_cpus=os.cpu_count(), object_store_memory=128 * 1024 ** 2, include_dashboard=False,
             log_to_driver=False)
    started = time.perf_counter() - tic
    result = {"ray_init_s": round(started, 2)}
    for label, func in (("noop", _noop), ("import_pipeline", _import_pipeline)):
        remote = ray.remote(max_calls=1)(func).options(num_cpus=1)
        ray.get(remote.remote())  # the first worker also warms the worker pool's start-up code
        lat = []
        for _ in range(tasks):
            t0 = time.perf_counter()
            ray.get(remote.remote())
            lat.append(time.perf_counter() - t0)
        result[f"{label}_task_s"] = {"median": round(statistics.median(lat), 3), "min": round(min(lat), 3),
                                     "max": round(max(lat), 3)}
    tic = time.perf_counter()
    ray.shutdown()
    result["ray_shutdown_s"] = round(time.perf_counter() - tic, 2)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--recon", default="--frames 0:5 --resolution 0.25 --init-iters 60 --dynamics-iters 8 "
                                       "--appearance-iters 4", help="recon options of both scenes.")
    ap.add_argument("--cpus-per-scene", type=float, default=1.0)
    ap.add_argument("--overhead-tasks", type=int, default=8)
    ap.add_argument("--skip-pipeline", action="store_true", help="Only the overhead measurement.")
    args = ap.parse_args()
    work = args.work.resolve()
    work.mkdir(parents=True, exist_ok=True)
    report = {"load_average_before": os.getloadavg()}
    if not args.skip_pipeline:
        recon = shlex.split(args.recon)
        tic = time.perf_counter()
        report["sequential_s"] = sequential(work, recon)
        report["sequential_wall_s"] = round(time.perf_counter() - tic, 1)
        wall, steps = batch(work, recon, args.cpus_per_scene)
        report["batch_wall_s"] = round(wall, 1)
        report["batch_step_s"] = steps
        report["ratio_sequential_over_batch"] = round(report["sequential_wall_s"] / wall, 2)
    report["ray"] = overhead(args.overhead_tasks)
    report["load_average_after"] = os.getloadavg()
    print(json.dumps(report, indent=2))
    (work / "bench_batch.json").write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
