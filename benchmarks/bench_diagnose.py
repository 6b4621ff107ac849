"""Time ``fluidnexus diagnose`` on the shared ScalarFlow sample (all 5 views, 90 frames, observation height 48)
and print the finding with its validation gain. The issue's budget is 10 minutes on the 2-core CPU.

Usage: python benchmarks/bench_diagnose.py [--arch cpu|cuda] [--evals N] [--out DIR] [--jobs 1,2]

With several ``--jobs`` values, the same diagnose runs once per value (``diagnose --jobs``: fits side by side in that
many processes) into ``DIR/diag`` (the first) and ``DIR/diag_jobsN``; it prints each time, the ratio to the first
and whether report.json and model.json are the same as the first's.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from click.testing import CliRunner

from fluidnexus_cli.main import main


def run() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--arch", default="cpu")
    ap.add_argument("--evals", type=int, default=20)
    ap.add_argument("--out", default=None)
    ap.add_argument("--jobs", default="1", help="comma-separated --jobs values, each a run (e.g. 1,2)")
    args = ap.parse_args()
    root = Path(args.out or tempfile.mkdtemp(prefix="bench_diagnose_"))
    scene = root / "scene"
    if not (scene / "scene.json").exists():
        r = CliRunner().invoke(main, ["calibrate", "--sample", "scalarflow", "--protocol", "four-view",
                                      "--out", str(scene)])
        assert r.exit_code == 0, r.output
    first = None
    for i, jobs in enumerate(int(j) for j in args.jobs.split(",")):
        out = root / ("diag" if i == 0 else f"diag_jobs{jobs}")
        t = time.perf_counter()
        r = CliRunner().invoke(main, ["diagnose", str(scene), "--out", str(out), "--train-frames", "0:60",
                                      "--validate-frames", "60:90", "--evals", str(args.evals), "--arch", args.arch,
                                      "--jobs", str(jobs)])
        assert r.exit_code == 0, r.output
        seconds = time.perf_counter() - t
        files = [json.loads((out / name).read_text()) for name in ("report.json", "model.json")]
        report, g = files[0], files[0]["finding"]["gain"]
        first = first or (seconds, files)
        print(f"diagnose 5 views x 90 frames, --jobs {jobs}: {seconds:.0f} s (budget 600 s; {first[0] / seconds:.2f}x "
              f"the first); finding {report['finding']['effect']} {report['finding']['params']}; validation image "
              f"error {g['before']:.4f} -> {g['after']:.4f}; outputs as the first's: {files == first[1]}")


if __name__ == "__main__":
    run()
