"""The table of the generated scene family (issue 30): every scene of a split through the tool as a user runs it.

    .venv/bin/python benchmarks/bench_scene_family.py --work W [--split development] [--seeds 1,2] [--size small]
        [--protocols four-view,single-view] [--plates estimated|true] [--recon-args "..."]
    .venv/bin/python benchmarks/bench_scene_family.py --work W --split held-out --held-out    # fills the table only

For each seed: ``benchmarks.scenes.generate`` writes the scene as a PINF capture (W/seedN/capture), then per protocol
(W/seedN/PROTOCOL), each step a CLI command in a fresh process under ``/usr/bin/time -v`` (wall time, peak resident
memory):

- ``calibrate --from-pinf info.json --metres-per-unit M`` with the protocol's roles from truth.json (four-view:
  train00-03 in, test00 held out; single-view: train01 in, train00/02/03 novel, test00 held out). PINF declares
  no source and the import invents none, so ``synth`` (single view: the foot of the earliest smoke cast onto the
  floor) and ``recon`` (the footage's hulls) find it, and the table scores what recon found.
- ``background`` where the scene is not plain black (a backdrop or an obstacle is in view): plates estimated from
  the footage (``--plates true`` gives the generator's exact plates with ``--plate``).
- single-view: ``synth`` and ``refine`` (the non-learned defaults).
- ``recon`` (``--recon-args``, default the demo's reduced settings, below), ``eval --json``.

Scored on the held-out camera test00 (moving in some scenes), at the run's resolution over the run's frames: the
run's NVS PSNR / SSIM from eval's JSON, next to two references computed here the way eval averages (per-frame means):
an all-black image and the true frame 0 held still (frames equal to it excluded, as bench_sphere.py does), read
at the run's size and colour channels as eval reads the footage (recon's default is gray). The source
in run.json against truth.json's: centre error in source radii and in box heights, the angle between directions,
the radius ratio, found speed / true inflow speed, the start frame. Obstacles: run.json's ``found_obstacles``
(found only with plates) against the true ones: how many were found and the centre error of the nearest found body
for each true one, in the true body's size (radius or half-diagonal).

A step that fails (the tool's exit 2) makes a failed row with the tool's one-line message; it counts as beating no
reference. The single video's heights are stated as a user would state them: every source of the family floats in its
box (plumes start 8-30 % up it, jets 20-55 %, puffs 70-85 %: benchmarks/scenes/spec.py), so the volume's bottom face,
synth's default plane, is never where the smoke starts, and one view cannot show how far along its rays the nozzle
is; and a room's floor (a wall backdrop) lies below the volume, where the static layer should lay it. After
``calibrate`` (both protocols: several views' static layer seeds only on a declared floor) the table states, from
the truth, the room's floor (scene.json ``floor``: the horizontal plane of the room's floor, for wall and set
backdrops) and the nozzle's height above it (``source_height``, which only a single video uses; none where the
source sits on the floor, within its radius), and synth finds the rest from the input view; the row is marked
"stated" (W/seedN/PROTOCOL/stated.txt and the row's ``stated`` say what). Where synth refuses even so (a foot's
ray that misses the plane), the row fails with the tool's message. A scene is prepared again from scratch
unless every preparation step of an earlier run succeeded (W/seedN/PROTOCOL/prepared.json).
``--rescore`` computes the scores again from the runs and eval.json files already in W (steps not re-run, their
timings kept; failed rows stay as they are). Results go to W/results/seedN-PROTOCOL.json (kept, so the development
and held-out halves can be run separately into the same W), W/table.json and W/table.md (every row, then the two
halves' means side by side, then NVS by backdrop kind in each half and both halves over the kinds they share, weighted
by the development half's mix: the halves drew different mixes, and only the gap between like scenes measures
tuning).
Held-out seeds are refused unless ``--held-out`` is given (docs/scene-family.md: they are run only to fill the table).
"""
from __future__ import annotations

import argparse
import json
import math
import shlex
import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.cli_steps import timed_command  # noqa: E402
from benchmarks.references import held_still_scores  # noqa: E402
from benchmarks.scenes import HELD_OUT, SIZES, check_seeds, generate, split_of  # noqa: E402
from benchmarks.scenes.splits import SPLITS, HeldOutError  # noqa: E402

# the demo's reduced recon settings (cli/demo.py): a scene in minutes on a 2-core CPU
FAST_RECON = "--init-iters 150 --dynamics-iters 12 --appearance-iters 8 --stabilization-steps 10 --static-iters 150"
PROTOCOLS = ("four-view", "single-view")
STATED = "stated.txt"  # what the table stated for the single video (the room's floor, the nozzle's height)


def references(scene: Path, frames: tuple, size: tuple, channels: int) -> dict:
    """PSNR / SSIM of an all-black image and of the true frame 0 held still against test00 over ``frames``, read
    as eval reads it (resized to the run's ``size`` (width, height), the run's ``channels``)."""
    from fluidnexus.scene import load_ground_truth
    from fluidnexus.video import read_video

    gt = next(g for g in load_ground_truth(scene) if g.name == HELD_OUT)
    video = read_video(scene / gt.video, frames=slice(*frames), size=size, channels=channels)
    first = read_video(scene / gt.video, frames=slice(0, 1), size=size, channels=channels)[0]
    return held_still_scores(video, {"black": np.zeros_like(first), "frame0_held": first})


def source_score(found: dict, true: dict, length: float) -> dict:
    c, tc = np.asarray(found["center"]), np.asarray(true["center"])
    d, td = np.asarray(found.get("direction", [0, 1, 0]), float), np.asarray(true["direction"], float)
    cos = float(np.clip(d @ td / (np.linalg.norm(d) * np.linalg.norm(td)), -1, 1))
    window = found.get("window") or [0, None]
    return {"found": found, "center_error_m": float(np.linalg.norm(c - tc)),
            "center_error_radii": float(np.linalg.norm(c - tc) / true["radius"]),
            "center_error_box": float(np.linalg.norm(c - tc) / length),
            "direction_error_deg": math.degrees(math.acos(cos)),
            "radius_ratio": float(found["radius"] / true["radius"]),
            "speed_found_over_true": float(found.get("speed", 0.0) / true["speed"]) if true["speed"] else None,
            "start_error_frames": int(window[0] - true["window"][0])}


def obstacle_score(found: list, true: list) -> dict:
    """For each true obstacle, the centre error of the nearest found body in the true body's size."""
    sizes = [b["radius"] if b["kind"] == "sphere" else
             0.5 * float(np.linalg.norm(np.subtract(b["max"], b["min"]))) for b in true]
    errors = []
    for b, size in zip(true, sizes):
        dist = [float(np.linalg.norm(np.subtract(f["center"], b["center"]))) for f in found]
        errors.append(min(dist) / size if dist else None)
    return {"true": len(true), "found": len(found), "center_error_sizes": errors,
            "matched": sum(e is not None and e < 1.0 for e in errors)}


def prepare_scene(capture: Path, truth: dict, protocol: str, work: Path, log: Path, args) -> dict:
    """calibrate (+ background, + synth and refine); returns the steps' timings."""
    roles, scene, steps, done = truth["protocols"][protocol], work / "scene", {}, work / "prepared.json"
    if done.exists():  # every step of an earlier run succeeded
        return json.loads(done.read_text())
    shutil.rmtree(scene, ignore_errors=True)  # what a failed step of an earlier run left
    (work / STATED).unlink(missing_ok=True)
    cmd = ["calibrate", "--from-pinf", capture / "info.json", "--input", roles["input"], "--ground-truth",
           roles["ground_truth"], *truth["calibrate_args"], "--out", scene]
    if "novel" in roles:
        cmd[5:5] = ["--novel", roles["novel"]]
    steps["calibrate"] = timed_command(cmd, log)
    if truth["needs_plates"]:
        plates = []
        if args.plates == "true":
            plates = [t for n in roles["input"].split(",") for t in ("--plate", f"{n}={capture / 'plates' / n}.png")]
        steps["background"] = timed_command(["background", scene, *plates], log)
    state_heights(scene, truth, work / STATED)
    if protocol == "single-view":
        steps["synth"] = timed_command(["synth", scene], log)
        steps["refine"] = timed_command(["refine", scene], log)
    done.write_text(json.dumps(steps))
    return steps


def state_heights(scene: Path, truth: dict, record: Path) -> None:
    """The user's statements (module docstring): scene.json ``floor`` at the room's floor where the backdrop is a
    room, ``source_height`` where the true source stands above that floor by more than its radius; what was stated
    goes to ``record``."""
    source, room = truth["source"], truth["backdrop"].get("room")
    floor = room[0][1] if room is not None else truth["volume"]["min"][1]
    spec = json.loads((scene / "scene.json").read_text())
    said = []
    if room is not None:
        spec["floor"] = {"point": [source["center"][0], floor, source["center"][2]], "normal": [0.0, 1.0, 0.0]}
        said.append(f"the room's floor at y = {floor:.4g} m ({truth['volume']['min'][1] - floor:.4g} m below the "
                    "volume)")
    height = source["center"][1] - floor
    if height > source["radius"]:
        spec["source_height"] = height
        said.append(f"the nozzle {height:.4g} m above the floor")
    if said:
        (scene / "scene.json").write_text(json.dumps(spec, indent=1))
        record.write_text("; ".join(said) + "\n")


def one(seed: int, protocol: str, args) -> dict:
    work = args.work / f"seed{seed}"
    capture = work / "capture"
    if not (capture / "truth.json").exists():
        generate(seed, capture, args.size)
    truth = json.loads((capture / "truth.json").read_text())
    pwork = work / protocol
    pwork.mkdir(parents=True, exist_ok=True)
    log = pwork / "log.txt"
    runs = pwork / "run"
    previous = args.work / "results" / f"seed{seed}-{protocol}.json"
    if args.rescore and (pwork / "eval.json").exists() and previous.exists():
        steps = json.loads(previous.read_text())["steps"]  # scores again from the run and eval.json kept in W
    else:
        steps = prepare_scene(capture, truth, protocol, pwork, log, args)
        resume = ["--resume"] if (runs / "config.json").exists() else []
        steps["recon"] = timed_command(["recon", pwork / "scene", "--out", runs, "--arch", "cpu", *resume,
                                        *shlex.split(args.recon_args)], log)
        steps["eval"] = timed_command(["eval", runs, "--json", pwork / "eval.json", "--arch", "cpu"], log)
    scores = json.loads((pwork / "eval.json").read_text())
    info = json.loads((runs / "run.json").read_text())
    nv = scores["novel_view"]["per_view"][HELD_OUT]
    res = scores["resolution"]
    channels = json.loads((runs / "config.json").read_text())["recon"]["channels"]
    return {"seed": seed, "split": split_of(seed), "protocol": protocol, "size": args.size,
            "scene": {"source": truth["source"]["kind"], "window": truth["source"]["window"],
                      "backdrop": truth["backdrop"]["kind"], "smoke": truth["smoke"]["mode"],
                      "layout": truth["cameras"]["layout"], "elevation": truth["cameras"]["elevation"],
                      "moving": truth["cameras"]["held_out_moving"], "unit": truth["file"]["unit"],
                      "up": truth["file"]["up"], "length_m": truth["length_m"], "obstacles": len(truth["obstacles"]),
                      "size_px": [truth["width"], truth["height"]], "frames": truth["frames"]},
            "settings": {"plates": args.plates if truth["needs_plates"] else None,
                         "recon_args": args.recon_args},
            "frames": scores["frames"], "resolution": scores["resolution"],
            "nvs": {"psnr": nv["psnr"], "ssim": nv["ssim"]},
            "resimulation": scores["resimulation"]["per_view"][HELD_OUT],
            "references": references(pwork / "scene", tuple(scores["frames"]), (res["width"], res["height"]),
                                     channels),
            "source": source_score(info["source"], truth["source"], truth["length_m"]),
            "source_finder": info.get("source_finder"),
            "stated": (pwork / STATED).read_text().strip() if (pwork / STATED).exists() else None,
            "obstacles": obstacle_score(info.get("found_obstacles", []), truth["obstacles"]),
            "steps": steps,
            "seconds": round(sum(s["seconds"] for s in steps.values()), 1),
            "peak_mib": max(s["peak_mib"] for s in steps.values())}


def tool_error(log: Path) -> str:
    """The last ``error:`` line the tool wrote to ``log`` (its one-line refusal), or "" without one."""
    lines = [ln for ln in log.read_text().splitlines() if ln.startswith("error:")] if log.exists() else []
    return lines[-1] if lines else ""


def fmt(x, spec=".2f"):
    return "-" if x is None else format(x, spec)


def table(results: list) -> str:
    rows = ["| seed | split | protocol | scene | NVS PSNR / SSIM | black | frame 0 held | "
            "source centre err (radii / box) | direction err | obstacles matched / true (found) | time s | "
            "peak MiB |", "|" + "---|" * 12]
    for r in sorted(results, key=lambda r: (r["split"], r["seed"], r["protocol"])):
        s, ref, src, ob = r["scene"], r["references"], r["source"], r["obstacles"]
        scene = (f"{s['source']} {s['window']}, {s['backdrop']}/{s['smoke']}, {s['layout']} {s['elevation']}"
                 f"{' moving' if s['moving'] else ''}, {s['unit']} {s['up']}-up, {s['length_m']:.2f} m")
        protocol = r["protocol"] + (" (stated)" if r.get("stated") else "")
        rows.append(f"| {r['seed']} | {r['split']} | {protocol} | {scene} | {fmt(r['nvs']['psnr'])} / "
                    f"{fmt(r['nvs']['ssim'], '.3f')} | {fmt(ref['black']['psnr'])} / {fmt(ref['black']['ssim'], '.3f')}"
                    f" | {fmt(ref['frame0_held']['psnr'])} / {fmt(ref['frame0_held']['ssim'], '.3f')} | "
                    f"{fmt(src['center_error_radii'], '.1f')} / {fmt(src['center_error_box'], '.2f')} | "
                    f"{fmt(src['direction_error_deg'], '.0f')} deg | {ob['matched']} / {ob['true']} ({ob['found']}) | "
                    f"{r['seconds']:.0f} | {r['peak_mib']:.0f} |")
    return "\n".join(rows)


def means(results: list) -> dict:
    """Per split and protocol: the mean of each score over the rows that ran, how often the run beats each
    reference, and how many rows failed (a failed row beats nothing)."""
    out = {}
    for split in SPLITS:
        for protocol in PROTOCOLS:
            every = [r for r in results if r["split"] == split and r["protocol"] == protocol]
            rs = [r for r in every if "error" not in r]
            if not rs:
                continue
            m = lambda f: float(np.mean([f(r) for r in rs]))  # noqa: E731
            out[f"{split}/{protocol}"] = {
                "scenes": len(every), "failed": len(every) - len(rs),
                "stated": sum(bool(r.get("stated")) for r in rs),
                "nvs_psnr": m(lambda r: r["nvs"]["psnr"]), "nvs_ssim": m(lambda r: r["nvs"]["ssim"]),
                "black_psnr": m(lambda r: r["references"]["black"]["psnr"]),
                "frame0_psnr": m(lambda r: r["references"]["frame0_held"]["psnr"]),
                "beats_black": sum(r["nvs"]["psnr"] > r["references"]["black"]["psnr"] for r in rs),
                "beats_frame0": sum(r["nvs"]["psnr"] > r["references"]["frame0_held"]["psnr"] for r in rs),
                "source_err_radii": m(lambda r: r["source"]["center_error_radii"]),
                "source_err_box": m(lambda r: r["source"]["center_error_box"]),
                "direction_err_deg": m(lambda r: r["source"]["direction_error_deg"]),
                "seconds": m(lambda r: r["seconds"]), "peak_mib": max(r["peak_mib"] for r in rs)}
    return out


def means_table(summary: dict) -> str:
    keys = [("scenes", "d"), ("failed", "d"), ("stated", "d"), ("nvs_psnr", ".2f"), ("nvs_ssim", ".3f"),
            ("black_psnr", ".2f"), ("frame0_psnr", ".2f"),
            ("beats_black", "d"), ("beats_frame0", "d"), ("source_err_radii", ".1f"), ("source_err_box", ".2f"),
            ("direction_err_deg", ".0f"), ("seconds", ".0f"), ("peak_mib", ".0f")]
    lines = []
    for protocol in PROTOCOLS:
        cols = [f"{split}/{protocol}" for split in SPLITS]
        lines += [f"| {protocol} | " + " | ".join(SPLITS) + " |", "|---|---|---|"]
        for key, spec in keys:
            vals = [fmt(summary[c][key], spec) if c in summary else "not run" for c in cols]
            lines.append(f"| {key} | " + " | ".join(vals) + " |")
        lines.append("")
    return "\n".join(lines)


def by_backdrop(results: list) -> dict:
    """Per protocol: NVS PSNR means by backdrop kind in each split, and both splits' means over the kinds they
    share, each kind weighted by its count in the development half (the halves drew different mixes of backdrops:
    a gap that remains between like scenes is the measure of tuning, a gap from the mix is not)."""
    out = {}
    for protocol in PROTOCOLS:
        rows = [r for r in results if r["protocol"] == protocol and "error" not in r]
        kinds = sorted({r["scene"]["backdrop"] for r in rows})
        per = {k: {split: [r["nvs"]["psnr"] for r in rows if r["split"] == split and r["scene"]["backdrop"] == k]
                   for split in SPLITS} for k in kinds}
        shared = [k for k in kinds if all(per[k][split] for split in SPLITS)]
        weight = {k: len(per[k]["development"]) for k in shared}
        matched = {split: (float(sum(weight[k] * np.mean(per[k][split]) for k in shared) / sum(weight.values()))
                           if shared else None) for split in SPLITS}
        out[protocol] = {"kinds": {k: {split: {"scenes": len(v), "nvs_psnr": float(np.mean(v)) if v else None}
                                       for split, v in per[k].items()} for k in kinds},
                         "shared_kinds": shared, "matched_nvs_psnr": matched}
    return out


def backdrop_table(summary: dict) -> str:
    lines = []
    for protocol, s in summary.items():
        lines += [f"| {protocol}: NVS PSNR by backdrop | " + " | ".join(SPLITS) + " |", "|---|---|---|"]
        for kind, cells in s["kinds"].items():
            lines.append(f"| {kind} | " + " | ".join(
                f"{fmt(cells[split]['nvs_psnr'])} ({cells[split]['scenes']})" for split in SPLITS) + " |")
        lines.append(f"| shared kinds ({', '.join(s['shared_kinds'])}), the development half's mix | " + " | ".join(
            fmt(s["matched_nvs_psnr"][split]) for split in SPLITS) + " |")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--split", choices=sorted(SPLITS), default="development")
    parser.add_argument("--seeds", help="comma-separated seeds (default: the whole split)")
    parser.add_argument("--held-out", action="store_true", help="allow held-out seeds (only to fill the table)")
    parser.add_argument("--size", choices=sorted(SIZES), default="small")
    parser.add_argument("--protocols", default=",".join(PROTOCOLS))
    parser.add_argument("--plates", choices=["estimated", "true"], default="estimated")
    parser.add_argument("--recon-args", default=FAST_RECON)
    parser.add_argument("--rescore", action="store_true",
                        help="score the runs already in W again (their eval.json), without running any step")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")] if args.seeds else list(SPLITS[args.split])
    try:
        check_seeds(seeds + (list(SPLITS["held-out"]) if args.split == "held-out" and not args.seeds else []),
                    args.held_out)
    except HeldOutError as err:
        raise SystemExit(f"error: {err}") from None
    args.work.mkdir(parents=True, exist_ok=True)
    (args.work / "results").mkdir(exist_ok=True)
    for seed in seeds:
        for protocol in args.protocols.split(","):
            tic = time.time()
            previous = args.work / "results" / f"seed{seed}-{protocol}.json"
            if args.rescore and previous.exists() and "error" in json.loads(previous.read_text()):
                continue  # a failed row stays as it was
            try:
                result = one(seed, protocol, args)
            except RuntimeError as err:  # a failed step is a row of the table too, with the tool's own message
                result = {"seed": seed, "split": split_of(seed), "protocol": protocol,
                          "error": f"{err}: {tool_error(args.work / f'seed{seed}' / protocol / 'log.txt')}"}
            previous.write_text(json.dumps(result, indent=1))
            print(f"seed {seed} {protocol}: " + (result.get("error") or
                  f"NVS {result['nvs']['psnr']:.2f} dB (black {result['references']['black']['psnr']:.2f}, frame 0 "
                  f"held {result['references']['frame0_held']['psnr']:.2f}); source off by "
                  f"{result['source']['center_error_radii']:.1f} radii; {time.time() - tic:.0f} s"), flush=True)
    results = [json.loads(p.read_text()) for p in sorted((args.work / "results").glob("*.json"))]
    ok = [r for r in results if "error" not in r]
    failed = [f"- seed {r['seed']} {r['protocol']}: {r['error']}" for r in results if "error" in r]
    summary, backdrops = means(results), by_backdrop(results)
    (args.work / "table.json").write_text(json.dumps({"rows": results, "means": summary, "by_backdrop": backdrops},
                                                     indent=1))
    text = (table(ok) + "\n\n" + ("Failed:\n" + "\n".join(failed) + "\n\n" if failed else "")
            + "Means (development | held-out):\n\n" + means_table(summary)
            + "\nBy backdrop (scenes in brackets):\n\n" + backdrop_table(backdrops))
    (args.work / "table.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
