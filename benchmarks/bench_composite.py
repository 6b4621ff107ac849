"""The ScalarFlow sample over a textured 3D backdrop, through the pipeline as a user runs it (issue 16 benchmarks).

    .venv/bin/python benchmarks/bench_composite.py --work /tmp/composite --protocol four-view|single-view \
        [--frames 120] [--backdrop waves|black|PHOTO] [-- extra recon options]

The backdrop (``--backdrop``):

- ``waves`` (the default): the test scene's (tests/recon/backdrop_scene.py), a plane of gray waves 0.1 m behind the
  sample's volume, ray cast per camera;
- a photograph (``coffee``, ``chelsea``, ``astronaut``, ``rocket`` from scikit-image, or an image file) on a folded
  wall behind the volume (``photo_backdrop.py``), in colour;
- ``black``: no backdrop, the same run on the sample as it is (the reference for the others).

The sample's glowing smoke is composited over the backdrop as white smoke of opacity S, ``I = S + B (1 - S)``. The
input views get their true plates (``fluidnexus background --plate``).

- ``four-view``: train00, train01, train03, train04 in; train02 held out, its truth composited too (its backdrop comes
  from the static layer). Compare with the four-view protocol on black (BENCHMARKS.md).
- ``single-view``: train02 in (composited, with its plate); the four others are synthesised from its smoke layer
  (``synth``, ``refine``; ``--smoke-color`` gives synth the smoke's colour instead of its estimate) and scored, as
  smoke layers, against the real footage on black. Compare with the single-view protocol on black (BENCHMARKS.md).

Every step is a CLI command in a fresh process; the scores are ``WORK/eval.json``; ``WORK/videos`` has the
side-by-side comparisons.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))
from benchmarks.cli_steps import timed_command  # noqa: E402


def backdrop_plates(backdrop: str, volume):
    """camera -> [H, W] or [H, W, 3] plate, or None for ``black``."""
    if backdrop == "black":
        return None
    if backdrop == "waves":
        from recon.backdrop_scene import plate

        return plate
    from benchmarks.photo_backdrop import load_photo, plate

    photo = load_photo(backdrop)
    return lambda camera: plate(camera, volume, photo)


def write_scene(out: Path, protocol: str, frames: int, backdrop: str) -> list[str]:
    """The composited scene folder; returns the names of its input views (whose plates are in out/plates)."""
    from fluidnexus.calibrate.pinf import read_pinf, source_at_volume_foot
    from fluidnexus.samples import sample_path
    from fluidnexus.scene import GroundTruth, Scene, View, save_scene
    from fluidnexus.video import read_video, write_video

    cap = read_pinf(sample_path("scalarflow") / "info.json")
    plate = backdrop_plates(backdrop, cap.volume)
    inputs = ["train00", "train01", "train03", "train04"] if protocol == "four-view" else ["train02"]
    (out / "plates").mkdir(parents=True, exist_ok=True)
    views, truths = [], []
    for name, rec in cap.recordings.items():
        smoke = read_video(rec.media, frames=slice(0, frames), channels=1)
        composite = name in inputs or protocol == "four-view"  # single view: the novel views' truth is on black
        if composite and plate is not None:
            back = plate(rec.camera)
            back = back[:, :, None] if back.ndim == 2 else back
            smoke = smoke + back[None] * (1.0 - smoke)
            cv2.imwrite(str(out / "plates" / f"{name}.png"), np.rint(back[:, :, ::-1] * 65535).astype(np.uint16))
        if name in inputs:
            write_video(out / "scene" / "videos" / f"{name}.mp4", smoke, cap.fps, crf=12)
            views.append(View(name, "input", rec.camera, f"videos/{name}.mp4"))
        else:
            write_video(out / "scene" / "ground_truth" / f"{name}.mp4", smoke, cap.fps, crf=12)
            truths.append(GroundTruth(name, rec.camera, f"ground_truth/{name}.mp4"))
            if protocol == "single-view":
                views.append(View(name, "novel", rec.camera))
    save_scene(Scene(out / "scene", cap.fps, frames, tuple(views), cap.volume, source_at_volume_foot(cap.volume)),
               tuple(truths))
    return inputs


def step(args: list, log: Path, seconds: dict) -> None:
    """``fluidnexus ARGS`` (``cli_steps.timed_command``), its seconds added to ``seconds[ARGS[0]]``."""
    took = timed_command(args, log)
    seconds[args[0]] = round(seconds.get(args[0], 0.0) + took["seconds"], 1)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--protocol", choices=["four-view", "single-view"], required=True)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--backdrop", default="waves", help="waves, black, or a photo (a scikit-image name or a file)")
    parser.add_argument("--smoke-color", help="single-view: synth --smoke-color (the composite's smoke: 1,1,1)")
    parser.add_argument("recon", nargs="*", help="extra recon options (after --)")
    args = parser.parse_args()
    work, log, seconds = args.work, args.work / "log.txt", {}
    scene, run = work / "scene", work / "run"
    if not (scene / "scene.json").exists():
        inputs = write_scene(work, args.protocol, args.frames, args.backdrop)
        if args.backdrop != "black":
            plates = [t for n in inputs for t in ("--plate", f"{n}={work / 'plates' / (n + '.png')}")]
            step(["background", scene, *plates], log, seconds)
    if args.protocol == "single-view" and not (scene / "videos" / "train00_synth.mp4").exists():
        step(["synth", scene, *(["--smoke-color", args.smoke_color] if args.smoke_color else [])], log, seconds)
        step(["refine", scene], log, seconds)
    resume = ["--resume"] if (run / "config.json").exists() else []
    step(["recon", scene, "--out", run, "--arch", "cpu", *resume, *args.recon], log, seconds)
    over = ["--background", "black"] if args.protocol == "single-view" else []  # smoke layers against black footage
    step(["eval", run, "--json", work / "eval.json", "--arch", "cpu", *over], log, seconds)
    step(["render", run, "--out", work / "videos", "--compare", "--arch", "cpu", *over], log, seconds)
    scores = json.loads((work / "eval.json").read_text())
    result = {"protocol": args.protocol, "backdrop": args.backdrop, "frames": scores["frames"], "seconds": seconds,
              "novel_view": scores["novel_view"], "resimulation": scores["resimulation"]}
    (work / "composite.json").write_text(json.dumps(result, indent=1))
    nv = scores["novel_view"]
    print(f"{args.protocol} over {args.backdrop}: NVS {nv['psnr']:.2f} dB / SSIM {nv['ssim']:.4f}; re-simulation "
          f"{scores['resimulation']['psnr']:.2f} dB; per view "
          + ", ".join(f"{k} {v['psnr']:.2f}" for k, v in nv["per_view"].items()) + f"; seconds {seconds}")


if __name__ == "__main__":
    main()
