"""PINF Game end to end (issue 32), as a user runs it, on either of the data README's protocols.

    .venv/bin/python benchmarks/bench_game.py --data ../shared/data/pinf_game --work W [--protocol fixed|pinf] \
        [--frames 0:60] [--resolution 0.5] [-- extra recon options]

Protocols (../shared/data/pinf_game/README.md): ``fixed``: train00, 01, 03, 05, 06 in, train02 held out;
``pinf``: train00, 01, 02, 03, 05, 06 in, test00 (moving, one pose per frame) held out. Frames 0:60 at 400 x 400
(``--resolution 0.5`` of the 800 x 800 videos), RGB. Steps (``cli_steps.pinf_pipeline``): ``calibrate --from-pinf``
(no source declared: recon finds it), ``background``, ``recon``, ``eval``, ``render --compare``. Then it prints and
writes ``W/game.json``: NVS and re-simulation PSNR / SSIM of the held-out view next to three references over the
same frames at the same size, computed here as eval averages (per-frame means): an all-black image, the true frame
0 held still (frames equal to it excluded) and the per-pixel temporal median of the true video itself (a perfect
static scene without the smoke's motion, which no method can know; for the moving test00 it is no static scene and
is given for completeness); the source recon found and the bodies it found (kinds, balls).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.cli_steps import pinf_pipeline  # noqa: E402
from benchmarks.references import held_still_scores  # noqa: E402

PROTOCOLS = {"fixed": (("train00", "train01", "train03", "train05", "train06"), ("train02",)),
             "pinf": (("train00", "train01", "train02", "train03", "train05", "train06"), ("test00",))}


def references(scene: Path, frames: slice, size: tuple[int, int]) -> dict:
    """Per held-out view: PSNR / SSIM of black, of the true frame 0 held still and of the true video's temporal
    median (module docstring), RGB at ``size`` (width, height)."""
    from fluidnexus.scene import load_ground_truth
    from fluidnexus.video import read_video

    out = {}
    for gt in load_ground_truth(scene):
        video = read_video(scene / gt.video, frames=frames, size=size, channels=3)
        first = read_video(scene / gt.video, frames=slice(0, 1), size=size, channels=3)[0]
        out[gt.name] = held_still_scores(video, {"black": np.zeros_like(first), "frame0_held": first,
                                                 "temporal_median": np.median(video, axis=0).astype(video.dtype)})
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--protocol", choices=sorted(PROTOCOLS), default="fixed")
    parser.add_argument("--frames", default="0:60")
    parser.add_argument("--resolution", default="0.5")
    parser.add_argument("recon", nargs="*", help="extra recon options (after --)")
    args = parser.parse_args()
    inputs, held_out = PROTOCOLS[args.protocol]
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    steps = pinf_pipeline(args.data, work, list(inputs), list(held_out), args.frames,
                          ["--resolution", args.resolution, "--channels", "rgb", *args.recon])
    scores = json.loads((work / "eval.json").read_text())
    start, stop = scores["frames"]
    size = (scores["resolution"]["width"], scores["resolution"]["height"])
    info = json.loads((work / "run" / "run.json").read_text())
    bodies = info.get("found_obstacles", [])
    found = {"boundaries": sum(b["kind"] == "boundary" for b in bodies),
             "solids": sum(b["kind"] == "solid" for b in bodies),
             "balls": [round(b["radius"], 4) for b in bodies if b.get("sphere_like")]}
    result = {"protocol": args.protocol, "steps": steps, "frames": [start, stop], "novel_view": scores["novel_view"],
              "resimulation": scores["resimulation"],
              "references": references(work / "scene", slice(start, stop), size),
              "source": info.get("source"), "source_finder": info.get("source_finder"), "found_obstacles": found}
    (work / "game.json").write_text(json.dumps(result, indent=1))
    for name in held_out:
        nv, rs = scores["novel_view"]["per_view"][name], scores["resimulation"]["per_view"][name]
        ref = result["references"][name]
        print(f"{name}: NVS {nv['psnr']:.2f} dB / SSIM {nv['ssim']:.3f}; re-simulation {rs['psnr']:.2f} dB; "
              + ", ".join(f"{k} {v['psnr']:.2f} dB" for k, v in ref.items()))
    print(f"found {found}; steps {steps}")


if __name__ == "__main__":
    main()
