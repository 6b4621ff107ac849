"""Brightness across views: each synthesised novel view's total smoke intensity against what the input view implies.

    python benchmarks/bench_synth_brightness.py --work /tmp/brightness [--seeds 1,3,6,9] [--frames 120]

For emission-only smoke a view's total intensity (sum over its pixels) is the smoke's mass weighted by the pixel
density in solid angle over r^2, ``fx fy r / z^3`` at a point at distance r and camera depth z (``(f / d)^2`` on the
optical axis), whatever the direction. So a novel view should hold ``input total x g(novel) / g(input)`` at the
plume's centre on the vertical through its foot (``benchmarks/brightness.py``). Per novel view this prints the
median over frames with smoke of

- ``synth @ its foot``: the synthesised view's total over that implied total, with the foot synth used (the declared
  source, or the one it found): whether the synthesiser keeps the input's smoke;
- ``synth @ true foot``, ``real @ true foot``: the synthesised and the real video of that camera (never read by
  the pipeline) against the total implied at the true foot; ``real`` says how well the footage follows the rule;
- ``synth / real``; and the found foot's distance from the true one, % of the box's height.

Scenes: development seeds of the generated family (docs/scene-family.md; held-out seeds are refused), each plume
made upright, standing on its box's floor at 30 % / 70 % across the box, glowing on black with no bodies, the
generator's own solver and emission-absorption ray marcher; the single-view protocol's roles, no source declared
(synth finds the foot). Then the embedded ScalarFlow sample (single-view protocol; its declared source is the only
foot known there).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.bench_plume_foot import capture as plume_foot_capture  # noqa: E402
from benchmarks.cli_steps import timed_command  # noqa: E402
from benchmarks.scenes import draw  # noqa: E402
from benchmarks.scenes.spec import Backdrop, Smoke  # noqa: E402
from benchmarks.scenes.splits import check_seeds  # noqa: E402
from benchmarks.brightness import brightness_ratios  # noqa: E402
from fluidnexus.scene import load_ground_truth, load_scene  # noqa: E402
from fluidnexus.video import read_footage  # noqa: E402

def capture(seed: int, out: Path) -> tuple[Path, dict]:
    """The development scene ``seed`` at size small, upright on its floor off the box's centre, glowing on black."""
    return plume_foot_capture(seed, out, backdrop=Backdrop("black"),
                              smoke=Smoke("glowing", (0.9, 0.9, 0.9), draw(seed, "small").smoke.tau), obstacles=(),
                              set_pieces=())


def measure(scene_dir: Path, real: dict[str, Path], frames: int | None, true_foot=None) -> dict:
    """Per novel view: the ratios of the module docstring, medians over the frames with smoke; ``true_foot``
    None: the scene's declared source is the truth."""
    scene = load_scene(scene_dir)
    source = scene.with_role("input")[0]
    footage = read_footage(scene.video_path(source))[:frames]
    novel = scene.with_role("novel")
    found = novel[0].provenance["synth"].get("plume_foot")
    foot = np.asarray(scene.source.center if found is None else found["center"])
    true_foot = foot if true_foot is None else np.asarray(true_foot)
    synth = {v.name: read_footage(scene_dir / v.video)[:frames] for v in novel}
    truth = {n: read_footage(p, (synth[n].shape[2], synth[n].shape[1]))[:frames] for n, p in real.items()}
    cams = {v.name: v.camera for v in novel}
    ratios = {"synth_own": brightness_ratios(footage, source.camera, synth, cams, foot),
              "synth_true": brightness_ratios(footage, source.camera, synth, cams, true_foot),
              "real_true": brightness_ratios(footage, source.camera, truth, cams, true_foot)}
    out = {}
    for name in synth:
        keep = np.all([np.isfinite(r[name]) for r in ratios.values()], axis=0)
        out[name] = {k: float(np.median(r[name][keep])) for k, r in ratios.items()}
        out[name]["synth_over_real"] = float(np.median(ratios["synth_true"][name][keep] /
                                                       ratios["real_true"][name][keep]))
    return {"views": out, "foot_error_m": float(np.linalg.norm(foot - true_foot))}


def run_family(seed: int, work: Path) -> dict:
    info, truth = capture(seed, work / f"seed{seed}" / "cap")
    roles, scene, log = truth["protocols"]["single-view"], work / f"seed{seed}" / "scene", work / f"seed{seed}.log"
    timed_command(["calibrate", "--from-pinf", info, "--input", roles["input"], "--novel", roles["novel"],
                   "--ground-truth", roles["ground_truth"], *truth["calibrate_args"], "--out", scene, "--overwrite"],
                  log)
    timed_command(["synth", scene], log)
    names = [v.name for v in load_scene(scene).with_role("novel")]
    result = measure(scene, {n: info.parent / f"{n}.mp4" for n in names}, None, truth["source"]["center"])
    result["foot_error_pct"] = 100 * result.pop("foot_error_m") / truth["length_m"]
    return result


def run_scalarflow(work: Path, frames: int) -> dict:
    scene, log = work / "scalarflow", work / "scalarflow.log"
    timed_command(["calibrate", "--sample", "scalarflow", "--protocol", "single-view", "--out", scene, "--overwrite"],
                  log)
    timed_command(["synth", scene], log)
    real = {g.name: scene / g.video for g in load_ground_truth(scene)}
    result = measure(scene, real, frames)
    result["foot_error_pct"] = None
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--seeds", default="1,3,6,9", help="development seeds (plumes) of the generated family")
    parser.add_argument("--frames", type=int, default=120, help="ScalarFlow frames measured")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",") if s]
    check_seeds(seeds, held_out=False)
    args.work.mkdir(parents=True, exist_ok=True)
    results = {f"seed {s}": run_family(s, args.work) for s in seeds}
    results["scalarflow"] = run_scalarflow(args.work, args.frames)
    (args.work / "results.json").write_text(json.dumps(results, indent=1))
    print("| scene | view | synth @ its foot | synth @ true foot | real @ true foot | synth / real | foot error, % |")
    print("|---|---|---|---|---|---|---|")
    for scene, result in results.items():
        error = "declared" if result["foot_error_pct"] is None else f"{result['foot_error_pct']:.1f}"
        for name, r in result["views"].items():
            print(f"| {scene} | {name} | {r['synth_own']:.3f} | {r['synth_true']:.3f} | {r['real_true']:.3f} | "
                  f"{r['synth_over_real']:.3f} | {error} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
