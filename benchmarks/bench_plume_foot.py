"""The single-video protocol on off-centre plumes of another solver: the source found from the input view against
the source at the box's foot (what the import declared before), against black and frame 0 held.

    python benchmarks/bench_plume_foot.py --work /tmp/foot [--seeds 2016,2013,2023]

Each seed (outside both halves of the scene family, docs/scene-family.md) is drawn at size ``small`` with its plume
moved off the box's centre (30 % / 70 % across it) onto the box's floor, upright; the generator's solver and ray
marcher make the footage (benchmarks/scenes). For each of two sources

- ``found``: the import declares none; synth casts the foot of the earliest smoke onto the floor (gen/plume_foot.py)
  and recon finds the inflow in the footage;
- ``box-foot``: an upward source at the bottom centre of the box written into scene.json after the import (the
  source the import declared before this change)

it runs calibrate, background (where a backdrop or a body is in view), synth, refine, recon (the family table's
reduced settings) and eval, and reports the held-out view's PSNR / SSIM, the references (black, frame 0 held:
``bench_scene_family.references``), the synthesised views' total intensity against the real views' (median over
frames of sum(synth) / sum(real)), the source error (synth's plume foot and recon's inflow against the truth, in %
of the box size) and the time. Markdown on stdout, JSON in
WORK/results.json.
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.bench_scene_family import FAST_RECON, references  # noqa: E402
from benchmarks.cli_steps import timed_command  # noqa: E402
from benchmarks.scenes import draw, generate  # noqa: E402
from fluidnexus.scene import load_scene  # noqa: E402
from fluidnexus.video import read_footage  # noqa: E402

ACROSS = (0.3, 0.7)  # the plume's place across the box (x, z shares)


def capture(seed: int, out: Path, **changes) -> tuple[Path, dict]:
    """The scene ``seed`` at size small, its plume upright on its floor off the box's centre (``ACROSS``), with
    ``changes`` to the generator's other arguments (e.g. its backdrop); (info.json, truth.json's content)."""
    spec = draw(seed, "small")
    lo, hi = np.asarray(spec.lo), np.asarray(spec.hi)
    centre = lo + np.array([ACROSS[0], 0.03, ACROSS[1]]) * (hi - lo)
    info = out / "info.json"
    if not info.exists():
        generate(seed, out, "small", source=replace(spec.source, center=tuple(centre), direction=(0.0, 1.0, 0.0)),
                 **changes)
    return info, json.loads((out / "truth.json").read_text())


def brightness(scene: Path, capture: Path) -> dict:
    """Per novel view: median over frames of the synthesised video's total intensity over the real one's (the
    capture's video of that camera, which the protocol never reads)."""
    out = {}
    for view in load_scene(scene).with_role("novel"):
        synth = read_footage(scene / (view.provenance or {}).get("unrefined", view.video))
        real = read_footage(capture / f"{view.name}.mp4", (synth.shape[2], synth.shape[1]))
        synth_total, real_total = (v.reshape(len(v), -1).sum(1) for v in (synth, real))
        keep = real_total > 1e-6 * synth[0].size  # frames the real smoke shows in
        out[view.name] = round(float(np.median(synth_total[keep] / real_total[keep])), 3)
    return out


def protocol(info: Path, truth: dict, work: Path, source: str, recon_args: str) -> dict:
    roles, scene, run_dir = truth["protocols"]["single-view"], work / "scene", work / "run"
    log = work / "log.txt"
    work.mkdir(parents=True, exist_ok=True)
    times = {}
    if not (run_dir / "eval.json").exists():
        times["calibrate"] = timed_command(["calibrate", "--from-pinf", info, "--input", roles["input"], "--novel",
                                  roles["novel"], "--ground-truth", roles["ground_truth"], *truth["calibrate_args"],
                                  "--out", scene, "--overwrite"], log)
        if source == "box-foot":  # what the import declared before: the bottom centre of the box, upward
            data = json.loads((scene / "scene.json").read_text())
            lo, hi = data["volume"]["min"], data["volume"]["max"]
            foot = [(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2]
            data["source"] = {"center": foot, "radius": truth["source"]["radius"]}
            (scene / "scene.json").write_text(json.dumps(data, indent=1))
        if truth["needs_plates"]:  # a backdrop or a body in view: the smoke over its plate, as the family table does
            times["background"] = timed_command(["background", scene], log)
        times["synth"] = timed_command(["synth", scene], log)
        times["refine"] = timed_command(["refine", scene], log)
        times["recon"] = timed_command(["recon", scene, "--out", run_dir, "--arch", "cpu", *shlex.split(recon_args)],
                                       log)
        times["eval"] = timed_command(["eval", run_dir, "--json", run_dir / "eval.json", "--arch", "cpu"], log)
    score = json.loads((run_dir / "eval.json").read_text())
    res = score["resolution"]
    refs = references(scene, tuple(score["frames"]), (res["width"], res["height"]), 1)
    length = float(truth["length_m"])
    true_centre = np.asarray(truth["source"]["center"])
    foot = load_scene(scene).with_role("novel")[0].provenance["synth"].get("plume_foot")
    inflow = json.loads((run_dir / "run.json").read_text())["source"]["center"]
    return {"source": source, "nvs": score["novel_view"]["per_view"], "references": refs,
            "brightness": brightness(scene, info.parent),
            "foot_error_pct": None if foot is None else
            round(100 * float(np.linalg.norm(np.asarray(foot["center"]) - true_centre)) / length, 2),
            "inflow_error_pct": round(100 * float(np.linalg.norm(np.asarray(inflow) - true_centre)) / length, 2),
            "seconds": round(sum(t["seconds"] for t in times.values()), 1) if times else None}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--seeds", default="2016,2013,2023")
    parser.add_argument("--recon-args", default=FAST_RECON)
    args = parser.parse_args()
    rows, results = [], []
    for seed in (int(s) for s in args.seeds.split(",")):
        info, truth = capture(seed, args.work / f"seed{seed}" / "cap")
        for source in ("found", "box-foot"):
            r = protocol(info, truth, args.work / f"seed{seed}" / source, source, args.recon_args)
            r["seed"] = seed
            results.append(r)
            (view, s), = r["nvs"].items()
            ref = r["references"]
            rows.append(f"| {seed} | {source} | {s['psnr']:.2f} / {s['ssim']:.3f} | {ref['black']['psnr']:.2f} | "
                        f"{ref['frame0_held']['psnr']:.2f} | {r['foot_error_pct']} | {r['inflow_error_pct']} | "
                        f"{', '.join(f'{k} {v}' for k, v in r['brightness'].items())} | {r['seconds']} |")
    (args.work / "results.json").write_text(json.dumps(results, indent=1))
    print("| seed | source | NVS PSNR / SSIM | black | frame 0 held | synth foot error, % box | recon inflow error, "
          "% box | synth / real intensity per novel view | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
