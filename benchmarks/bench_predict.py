"""Future prediction on the ScalarFlow sample (issue protocol; docs/prediction.md).

Reconstruct frames A:90 of a calibrated sample scene (or reuse --run: any reconstruction that contains frame 89,
e.g. the 120-frame run of the recon benchmark; frame 89 of a run depends on frames 0-89 only), predict 90:120 after
frame 89 and score at the run's resolution (the sample's 270 x 480) against the real future: the input view(s), the
ground-truth novel view(s), and the same-run reference of repeating the last observed input frame. Variants: the
physics alone with the paper's constants (--no-refit --no-calibrate), the physics with the backtest-calibrated model
(--no-refit), the render / refine / re-fit loop without anchoring (--no-anchor), and the default loop (anchored).

    python benchmarks/bench_predict.py --protocol four-view --work /tmp/bp --first 0
    python benchmarks/bench_predict.py --run RUN --work /tmp/bp   # reuse a reconstruction
    python benchmarks/bench_predict.py --run RUN --work /tmp/bp --model D/model.json \
        --only physics,refit,physics_model,refit_model
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cli(*args) -> float:
    tic = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fluidnexus_cli", *map(str, args)], cwd=ROOT, check=True)
    return time.perf_counter() - tic


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--protocol", choices=["four-view", "single-view"], default="four-view")
    ap.add_argument("--work", type=Path, required=True, help="Folder for the scene, runs and scores.")
    ap.add_argument("--run", type=Path, help="An existing reconstruction containing frame 89 (skips recon).")
    ap.add_argument("--first", type=int, default=0, help="First reconstructed frame (the protocol: 0).")
    ap.add_argument("--frames", type=int, default=30, help="Predicted frames (the protocol: 30, 90-119).")
    ap.add_argument("--skip-refit", action="store_true", help="Only the physics rollout.")
    ap.add_argument("--model", type=Path,
                    help="A model.json (e.g. diagnose's): adds the physics and the default loop with --model.")
    ap.add_argument("--only", help="Comma-separated variants to run (default: all).")
    ap.add_argument("--recon-args", default="", help="Extra recon options, e.g. '--max-loss 100000'.")
    args = ap.parse_args()
    work = args.work.resolve()  # the CLI runs from the repository root
    work.mkdir(parents=True, exist_ok=True)
    timing = {}
    run = args.run.resolve() if args.run else None
    if run is None:
        scene = work / "scene"
        if not scene.exists():
            cli("calibrate", "--sample", "scalarflow", "--protocol", args.protocol, "--out", scene)
        run = work / "run"
        timing["recon_s"] = cli("recon", scene, "--out", run, "--frames", f"{args.first}:90",
                                *args.recon_args.split())
    results = {"run": str(run), "protocol": args.protocol}
    variants = [("physics_paper_model", ["--no-refit", "--no-calibrate"]), ("physics", ["--no-refit"])]
    if not args.skip_refit:
        variants += [("refit_unanchored", ["--refine", "temporal", "--no-anchor"]), ("refit", ["--refine", "temporal"])]
    if args.model:
        variants += [("physics_model", ["--no-refit", "--model", args.model.resolve()]),
                     ("refit_model", ["--refine", "temporal", "--model", args.model.resolve()])]
    if args.only:
        variants = [v for v in variants if v[0] in args.only.split(",")]
    for name, extra in variants:
        out = work / f"predict_{name}"
        timing[f"{name}_s"] = cli("predict", run, "--from", 89, "--frames", args.frames, "--out", out, *extra)
        cli("eval", out, "--json", work / f"scores_{name}.json")
        scores = json.loads((work / f"scores_{name}.json").read_text())["prediction"]
        results[name] = {"input_view_psnr": scores["input_view"]["psnr"],
                         "input_view_ssim": scores["input_view"]["ssim"],
                         "novel_views_psnr": scores["novel_views"]["psnr"],
                         "novel_views_ssim": scores["novel_views"]["ssim"],
                         "repeat_last_input_view_psnr": scores["repeat_last_input_view"]["psnr"],
                         "frames": scores["frames"]}
    results["timing_s"] = timing
    (work / "bench_predict.json").write_text(json.dumps(results, indent=2) + "\n")
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
