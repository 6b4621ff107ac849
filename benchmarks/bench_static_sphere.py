"""The static layer and the obstacle it shows on a scene with plates (docs/static-layer.md), e.g. PINF Sphere.

    fluidnexus calibrate --from-pinf ../shared/data/pinf_sphere/info.json --input train00,train01,train02,train03,\
train04 --ground-truth test02,test04 --out S
    fluidnexus background S
    .venv/bin/python benchmarks/bench_static_sphere.py S [--scale 0.25] [--frames 0:120] [--iterations 400]

Fits the static layer to the input views' plates at ``--scale`` of the videos' size, prints the obstacles found
in the volume (centre, radius, fit residual, in scene coordinates; as the layer shows them and refitted to its
silhouettes, as recon finds them) and, for each ground-truth camera, the PSNR
of the static layer's render against the true video over ``--frames`` next to a white image and that video's
frame 0 held still (the ground truth is read here for scoring only; nothing of it reaches the fit).
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("scene")
    parser.add_argument("--scale", type=float, default=0.25)
    parser.add_argument("--frames", default="0:120")
    parser.add_argument("--iterations", type=int, help="default: StaticConfig's")
    args = parser.parse_args()

    from fluidnexus import engine
    from fluidnexus.metrics import mean_psnr_db
    from fluidnexus.scene import load_ground_truth, load_scene
    from fluidnexus.scenery.found_obstacles import find_obstacles, refine_balls
    from fluidnexus.scenery.plate_store import read_plate
    from fluidnexus.scenery.static_layer import StaticConfig, fit_static, render_static
    from fluidnexus.scenery.world import plates_at
    from fluidnexus.video import read_video

    engine.init(arch="cpu", precision="f32")
    scene = load_scene(args.scene)
    names = [v.name for v in scene.usable_views() if v.name in scene.backgrounds]
    channels = read_plate(scene, names[0])[0].shape[-1]  # the plates as stored
    named, plates, confidences = plates_at(scene, {n: scene.view(n).camera.scaled(args.scale) for n in names},
                                           channels)
    cameras = list(named.values())
    tic = time.perf_counter()
    layer = fit_static(cameras, plates, confidences, scene.volume.min, scene.volume.max,
                       StaticConfig(iterations=args.iterations or StaticConfig.iterations))
    fit_s = time.perf_counter() - tic
    found = find_obstacles(layer, cameras, scene.volume.min, scene.volume.max)
    refitted = refine_balls(found, layer, cameras)
    start, stop = (int(v) for v in args.frames.split(":"))
    rows = []
    for truth in load_ground_truth(args.scene):
        camera = truth.camera.scaled(args.scale)
        video = read_video(scene.root / truth.video, frames=slice(start, stop), size=(camera.width, camera.height),
                           channels=3)
        image = render_static(layer, camera)[0].numpy()
        rows.append({"view": truth.name,
                     "static": round(mean_psnr_db(np.broadcast_to(image, video.shape), video), 2),
                     "white": round(mean_psnr_db(np.ones_like(video), video), 2),
                     "frame0": round(mean_psnr_db(np.broadcast_to(video[0], video.shape), video), 2)})
    print(json.dumps({"views": names, "scale": args.scale, "gaussians": len(layer), "fit_s": round(fit_s, 1),
                      "loss": layer.info["loss"], "obstacles": [f.to_dict() for f in found],
                      "refitted": [f.to_dict() for f in refitted],
                      "held_out": rows}, indent=1))


if __name__ == "__main__":
    main()
