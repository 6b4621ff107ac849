"""PINF Sphere end to end on PINF's protocol (train00-04 in, test02 and test04 scored), as a user runs it.

    .venv/bin/python benchmarks/bench_sphere.py --data ../shared/data/pinf_sphere --work /tmp/sphere \
        [--frames 0:120] [--resolution auto] [-- extra recon options]

Steps (each a CLI command in a fresh process, timed, with its peak resident memory from ``/usr/bin/time``):
``calibrate --from-pinf``, ``background`` (clean plates), ``recon`` (static layer, obstacles, smoke), ``eval``,
``render --compare`` (side-by-side MP4s of both held-out views) and ``render --background black --alpha``. A step
whose output exists is skipped (a killed recon continues with ``--resume``). Then it prints and writes
``WORK/sphere.json``: per held-out view the NVS and re-simulation PSNR / SSIM next to two references over the
same frames (a white image; the true frame 0 held still), and the obstacle found against the ball measured from
its silhouettes (docs/calibration.md: centre (-0.0224, 0.1662, -0.0553), radius 0.4242, scene units).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.cli_steps import pinf_pipeline, timed_command  # noqa: E402
from benchmarks.references import held_still_scores  # noqa: E402

BALL_CENTER, BALL_RADIUS = np.array([-0.0224, 0.1662, -0.0553]), 0.4242
VIEWS = ("train00", "train01", "train02", "train03", "train04")
HELD_OUT = ("test02", "test04")


def references(scene: Path, frames: slice) -> dict:
    """Per held-out view: PSNR / SSIM of a white image and of the true frame 0 held still (mean per-frame PSNR as
    eval computes it, over the frames the reference does not equal exactly)."""
    from fluidnexus.scene import load_ground_truth
    from fluidnexus.video import read_video

    out = {}
    for gt in load_ground_truth(scene):
        if gt.name not in HELD_OUT:
            continue
        video = read_video(scene / gt.video, frames=frames, channels=1)
        first = read_video(scene / gt.video, frames=slice(0, 1), channels=1)[0]
        out[gt.name] = held_still_scores(video, {"white": np.ones_like(first), "frame0_held": first})
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--frames", default="0:120")
    parser.add_argument("--resolution", default="auto")
    parser.add_argument("recon", nargs="*", help="extra recon options (after --)")
    args = parser.parse_args()
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    scene, runs = work / "scene", work / "run"
    steps = pinf_pipeline(args.data, work, list(VIEWS), list(HELD_OUT), args.frames,
                          ["--resolution", args.resolution, *args.recon])
    steps["render_black"] = timed_command(["render", runs, "--out", work / "smoke", "--views", ",".join(HELD_OUT),
                                           "--background", "black", "--alpha", "--arch", "cpu"], work / "log.txt")
    scores = json.loads((work / "eval.json").read_text())
    start, stop = scores["frames"]
    info = json.loads((runs / "run.json").read_text())
    found = info.get("found_obstacles", [])
    ball = None
    if found:
        c, r = np.asarray(found[0]["center"]), found[0]["radius"]
        ball = {"center": c.tolist(), "radius": r,
                "center_error_of_radius": float(np.linalg.norm(c - BALL_CENTER) / BALL_RADIUS),
                "radius_error": float(r / BALL_RADIUS - 1)}
    result = {"steps": steps, "frames": [start, stop], "novel_view": scores["novel_view"],
              "resimulation": scores["resimulation"], "references": references(scene, slice(start, stop)),
              "ball": ball, "summary": json.loads((runs / "summary.json").read_text())}
    (work / "sphere.json").write_text(json.dumps(result, indent=1))
    for name in HELD_OUT:
        nv, rs = scores["novel_view"]["per_view"][name], scores["resimulation"]["per_view"][name]
        ref = result["references"][name]
        print(f"{name}: NVS {nv['psnr']:.2f} dB / SSIM {nv['ssim']:.3f}; re-simulation {rs['psnr']:.2f} dB / "
              f"{rs['ssim']:.3f}; white {ref['white']['psnr']:.2f} dB, "
              f"frame 0 held {ref['frame0_held']['psnr']:.2f} dB")
    print(f"re-simulation {scores['resimulation']['psnr']:.2f} dB; ball {ball}; steps {steps}")


if __name__ == "__main__":
    main()
