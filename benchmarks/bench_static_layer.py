"""The static layer alone from a held-out camera, against that camera's own temporal median (issue 32, item 1).

    fluidnexus calibrate --from-pinf ../shared/data/pinf_game/info.json --input train00,train01,train03,train05,\
train06 --ground-truth train02 --out G
    fluidnexus background G
    .venv/bin/python benchmarks/bench_static_layer.py G [--scale 0.25] [--frames 0:60] [--iterations 400] \
        [--seed 0] [--set NAME=VALUE ...] [--save DIR]
    .venv/bin/python benchmarks/bench_static_layer.py --composite WORK [...]

Fits the static layer as recon does (``fit_static`` on the input views' plates at ``--scale`` of the videos' size)
and scores its render from each fixed ground-truth camera against the per-pixel temporal median of that camera's
true video over ``--frames``, at the same size (PSNR and SSIM). Next to it: the PSNR of a flat image of the input
plates' median colour (what a layer that places nothing would score) and the layer's training views against their
own plates (how far the fit overfits). ``--composite WORK`` first writes the reconstruction tests' textured
composite (tests/recon/backdrop_scene.py: the ScalarFlow sample over a plane of gray waves, four views in, train02
held out, at 0.25 of the sample's size) into WORK with the input views' true plates, and scores that scene.
The background colour is scene.json's ``backdrop_color`` when it has one, as in recon. ``--set`` overrides a
``StaticConfig`` field (numbers only); ``--plates-median`` ignores ``backdrop_color``.
The ground truth is read for scoring only. ``--save DIR`` writes the fitted layer (DIR/static.npz) and, as PNG
files for a look, the layer's render and alpha, the median and the input plates.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def composite_scene(work: Path, frames: int) -> Path:
    """The textured composite (tests/recon/backdrop_scene.py) with its input views' true plates."""
    sys.path.insert(0, str(ROOT / "tests"))
    from recon.backdrop_scene import INPUTS, write_scenes

    scene_dir = work / "backdrop"
    if not (scene_dir / "backgrounds").is_dir():
        write_scenes(work, frames, 0.25)
        plates = [f"--plate={name}={work / 'plates' / f'{name}.png'}" for name in INPUTS]
        subprocess.run([sys.executable, "-m", "fluidnexus_cli", "background", str(scene_dir), *plates],
                       check=True)
    return scene_dir


def write_png(path: Path, image: np.ndarray) -> None:
    cv2.imwrite(str(path), np.rint(np.clip(image, 0, 1) * 255).astype(np.uint8)[..., ::-1])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("scene", nargs="?")
    parser.add_argument("--composite", type=Path)
    parser.add_argument("--scale", type=float, default=0.25)
    parser.add_argument("--frames", default="0:60")
    parser.add_argument("--iterations", type=int, help="default: StaticConfig's")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--save", type=Path)
    parser.add_argument("--plates-median", action="store_true",
                        help="ignore scene.json's backdrop_color (the background colour is the plates' median)")
    args = parser.parse_args()
    start, stop = (int(v) for v in args.frames.split(":"))
    scene_dir = composite_scene(args.composite, stop) if args.composite else Path(args.scene)

    from fluidnexus import engine
    from fluidnexus.metrics import psnr, ssim
    from fluidnexus.scene import load_ground_truth, load_scene
    from fluidnexus.scenery.plate_store import read_plate
    from fluidnexus.scenery.static_layer import StaticConfig, fit_static, render_static, save_static
    from fluidnexus.scenery.world import layer_floor, plates_at, view_anchor
    from fluidnexus.video import read_video

    engine.init(arch="cpu", precision="f32")
    scene = load_scene(scene_dir)
    names = [v.name for v in scene.usable_views() if v.name in scene.backgrounds]
    channels = read_plate(scene, names[0])[0].shape[-1]  # the plates as stored
    named, plates, confidences = plates_at(scene, {n: scene.view(n).camera.scaled(args.scale) for n in names},
                                           channels)
    cameras = list(named.values())
    overrides = {k: float(v) if not v.isdigit() else int(v) for k, v in (s.split("=", 1) for s in args.set)}
    cfg = StaticConfig(iterations=args.iterations or StaticConfig.iterations, seed=args.seed, **overrides)
    tic = time.perf_counter()
    backdrop = None if args.plates_median else scene.backdrop_color
    layer = fit_static(cameras, plates, confidences, scene.volume.min, scene.volume.max, cfg, backdrop,
                       layer_floor(scene, len(cameras)),
                       view_anchor(scene))
    fit_s = time.perf_counter() - tic
    sure = np.concatenate([p[c >= 0.5] for p, c in zip(plates, confidences)])
    flat_color = np.median(sure, axis=0)
    rows = []
    for truth in load_ground_truth(scene_dir):
        if truth.poses is not None:
            continue  # a moving camera has no temporal median
        camera = truth.camera.scaled(args.scale)
        video = read_video(scene.root / truth.video, frames=slice(start, stop), size=(camera.width, camera.height),
                           channels=plates[0].shape[-1])
        median = np.median(video, axis=0).astype(np.float32)
        image, alpha, _ = render_static(layer, camera)
        image, alpha = image.numpy(), alpha.numpy()
        flat = np.broadcast_to(flat_color.astype(np.float32), median.shape)
        rows.append({"view": truth.name, "psnr": round(float(psnr(image, median)), 2),
                     "ssim": round(float(ssim(image, median)), 3),
                     "flat_psnr": round(float(psnr(flat, median)), 2)})
        if args.save:
            args.save.mkdir(parents=True, exist_ok=True)
            write_png(args.save / f"{truth.name}.render.png", image)
            write_png(args.save / f"{truth.name}.alpha.png", alpha[..., None])
            write_png(args.save / f"{truth.name}.median.png", median)
    renders = [render_static(layer, c)[0].numpy() for c in cameras]
    train = [round(float(psnr(r, p)), 2) for r, p in zip(renders, plates)]
    if args.save:
        save_static(args.save, layer)
        for name, r, p in zip(names, renders, plates):
            write_png(args.save / f"{name}.render.png", r)
            write_png(args.save / f"{name}.plate.png", p)
    print(f"scene {scene_dir}  inputs {','.join(names)}  size {cameras[0].width}x{cameras[0].height}  "
          f"iterations {cfg.iterations}  seed {cfg.seed}  {overrides or ''}")
    print(f"fit {fit_s:.0f} s, {len(layer)} Gaussians, training views' PSNR {min(train):.1f}-{max(train):.1f} dB")
    print(f"{'held out':<10}{'PSNR dB':>9}{'SSIM':>7}{'flat colour dB':>16}")
    for r in rows:
        print(f"{r['view']:<10}{r['psnr']:>9.2f}{r['ssim']:>7.3f}{r['flat_psnr']:>16.2f}")
    print(json.dumps({"scene": str(scene_dir), "scale": args.scale, "config": overrides, "fit_s": round(fit_s, 1),
                      "gaussians": len(layer), "train_psnr": train, "held_out": rows}))


if __name__ == "__main__":
    main()
