"""Time ``fluidnexus diagnose`` on the shared ScalarFlow sample (all 5 views, 90 frames, observation height 48)
and print the finding with its validation gain. The issue's budget is 10 minutes on the 2-core CPU.

Usage: python benchmarks/bench_diagnose.py [--arch cpu|cuda] [--evals N] [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from click.testing import CliRunner

from cli.main import main


def run() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--arch", default="cpu")
    ap.add_argument("--evals", type=int, default=20)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    root = Path(args.out or tempfile.mkdtemp(prefix="bench_diagnose_"))
    scene = root / "scene"
    if not (scene / "scene.json").exists():
        r = CliRunner().invoke(main, ["calibrate", "--sample", "scalarflow", "--protocol", "four-view",
                                      "--out", str(scene)])
        assert r.exit_code == 0, r.output
    t = time.perf_counter()
    r = CliRunner().invoke(main, ["diagnose", str(scene), "--out", str(root / "diag"), "--train-frames", "0:60",
                                  "--validate-frames", "60:90", "--evals", str(args.evals), "--arch", args.arch])
    assert r.exit_code == 0, r.output
    seconds = time.perf_counter() - t
    report = json.loads((root / "diag" / "report.json").read_text())
    g = report["finding"]["gain"]
    print(f"diagnose 5 views x 90 frames: {seconds:.0f} s (budget 600 s); finding {report['finding']['effect']} "
          f"{report['finding']['params']}; validation image error {g['before']:.4f} -> {g['after']:.4f}")


if __name__ == "__main__":
    run()
