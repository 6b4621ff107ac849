"""Benchmark of ``synth`` (axisym) and ``refine`` (temporal) on the ScalarFlow paper protocol at 1/4 resolution.

train02 is the input; the four other cameras are scored against their real videos (ground truth, read here
only). Reported per view and as a mean: PSNR (mean of per-frame PSNR, dB) and SSIM, for

- ``plain warp``: the reference, a warp of the input about one fixed vertical axis through (0.34, -0.225)
  (README of the data: 26.0 dB), computed in the same run with the same code path;
- ``axisym``: the default synthesiser with the scene as the pipeline sees it;
- ``axisym + temporal``: the same, refined.

Then the refiner on a flickering input: a real ground-truth video with per-frame gain noise and pixel noise;
flicker (mean absolute motion-compensated temporal difference) and PSNR against the clean video, before and
after ``temporal``.

Run: ``.venv/bin/python benchmarks/bench_synth.py [--frames 120]`` (3-7 minutes on 2 shared CPU cores).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.video import read_footage
from fluidnexus.gen.axisym import AxisymConfig, AxisymSynthesizer
from fluidnexus.gen.synthesizer import SynthesisInput
from fluidnexus.gen.temporal import temporal_filter
from fluidnexus.metrics import flicker, mean_psnr_db, mean_ssim
from fluidnexus.scene import Source, load_ground_truth, load_scene

PLAIN_AXIS = (0.34, -0.225)


def score(pred: dict, truth: dict) -> dict:
    return {n: (mean_psnr_db(pred[n], truth[n]), mean_ssim(pred[n], truth[n])) for n in truth}


def table(label: str, scores: dict) -> None:
    cells = "  ".join(f"{n} {p:6.2f} / {s:.3f}" for n, (p, s) in scores.items())
    mean_p = np.mean([p for p, _ in scores.values()])
    mean_s = np.mean([s for _, s in scores.values()])
    print(f"{label:<22} {cells}  | mean {mean_p:6.2f} dB / {mean_s:.3f}")


def main_bench(frames: int) -> None:
    work = Path(tempfile.mkdtemp(prefix="bench-synth-"))
    res = CliRunner().invoke(main, ["calibrate", "--sample", "scalarflow", "--protocol", "single-view",
                                    "--out", str(work / "scene")])
    assert res.exit_code == 0, res.output
    scene = load_scene(work / "scene")
    src = scene.with_role("input")[0]
    video = read_footage(scene.video_path(src))[:frames]
    truth = {g.name: read_footage(scene.root / g.video)[:frames] for g in load_ground_truth(scene.root)}
    cams = {g.name: g.camera for g in load_ground_truth(scene.root)}
    print(f"ScalarFlow sim_000000, input {src.name}, {video.shape[0]} frames at {video.shape[2]}x{video.shape[1]}")
    print("PSNR dB / SSIM per view")
    black = {n: np.zeros_like(v) for n, v in truth.items()}
    table("all black", score(black, truth))

    y0 = scene.source.center[1] if scene.source else 0.0
    plain_in = SynthesisInput(video, src.camera, Source((PLAIN_AXIS[0], y0, PLAIN_AXIS[1]), 0.02), scene.volume)
    plain = AxisymSynthesizer(AxisymConfig(follow_axis=False, antisymmetric_gain="keep", path_factor=False,
                                           depth_spread_m=0.0))
    table("plain warp (ref)", score({n: plain.synthesize(plain_in, c) for n, c in cams.items()}, truth))

    inp = SynthesisInput(video, src.camera, scene.source, scene.volume)
    t0 = time.perf_counter()
    synth = AxisymSynthesizer()
    ours = {n: synth.synthesize(inp, c) for n, c in cams.items()}
    t_synth = time.perf_counter() - t0
    table("axisym", score(ours, truth))
    t0 = time.perf_counter()
    refined = {n: temporal_filter(v) for n, v in ours.items()}
    t_ref = time.perf_counter() - t0
    table("axisym + temporal", score(refined, truth))
    print(f"time: axisym {t_synth:.1f} s, temporal {t_ref:.1f} s for {len(cams)} views")
    fl = {n: (flicker(ours[n]), flicker(refined[n])) for n in ours}
    print("flicker of the synthesised videos, before -> after temporal: "
          + ", ".join(f"{n} {a:.4f} -> {b:.4f}" for n, (a, b) in fl.items()))

    rng = np.random.default_rng(0)
    clean = truth[next(iter(truth))][:60]
    gains = 1 + 0.15 * rng.standard_normal((clean.shape[0], 1, 1, 1))
    noisy = np.clip(clean * gains + 0.02 * rng.standard_normal(clean.shape), 0, 1).astype(np.float32)
    out = temporal_filter(noisy)
    print("flickering input (real video, 15 % gain noise + 0.02 pixel noise, 60 frames):")
    print(f"  flicker clean {flicker(clean):.4f}  noisy {flicker(noisy, clean):.4f}  "
          f"temporal {flicker(out, clean):.4f}")
    print(f"  PSNR vs clean: noisy {mean_psnr_db(noisy, clean):.2f} dB  temporal {mean_psnr_db(out, clean):.2f} dB")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=120)
    main_bench(parser.parse_args().frames)
