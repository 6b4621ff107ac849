"""How right the static layer's stereo is against the angle between two views (fluidnexus/scenery/stereo.py,
``StereoConfig.max_angle``), on the generated family's rooms, where the true depth of every pixel is known.

    .venv/bin/python benchmarks/bench_stereo_angle.py [--seeds 1,3,4,5,7,9,10] [--angles 20,30,45,60,65,70,75,90]

For each seed whose backdrop is a room (``wall`` or ``set``) and each angle, two cameras of the scene's rig
(its distance, elevation and field of view) stand that many degrees apart in azimuth, starting at each of the
rig's four azimuths in turn; their true plates (no smoke) go through ``depth_maps`` with every pair compared
(``max_angle`` 180). Printed per seed and angle: the share of pixels with a confirmed depth, and the share of
those within 5 % of the true depth (the first surface along the pixel's ray: room, set pieces, obstacles).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.scenes.generate import camera_at  # noqa: E402
from benchmarks.scenes.geometry import surfaces  # noqa: E402
from benchmarks.scenes.raymarch import static_image  # noqa: E402
from benchmarks.scenes.spec import draw  # noqa: E402


def as_camera(pinhole):
    """The family's ``PinholeCamera`` as the project's ``Camera`` (the same OpenCV axes and pixel centres)."""
    from fluidnexus.camera import Camera

    k = np.array([[pinhole.fx, 0.0, pinhole.width / 2], [0.0, pinhole.fx, pinhole.height / 2], [0.0, 0.0, 1.0]])
    return Camera(pinhole.width, pinhole.height, k, pinhole.w2c)


def true_depth(pinhole, spec) -> np.ndarray:
    """[H, W] camera-space depth of the first solid surface along each pixel's ray."""
    origin, directions = pinhole.rays()
    t, _ = surfaces(origin, directions, spec.bodies, spec.backdrop)
    return (t * (directions @ pinhole.w2c[:3, :3].T)[:, 2]).reshape(pinhole.height, pinhole.width)


def main() -> None:
    from fluidnexus.scenery.stereo import StereoConfig, depth_maps

    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", default="1,3,4,5,7,9,10")
    parser.add_argument("--angles", default="20,30,45,60,65,70,75,90")
    parser.add_argument("--size", default="small")
    args = parser.parse_args()
    every_pair = StereoConfig(max_angle=180.0)
    print(f"{'seed':>5} {'room':<5} {'angle':>6} {'confirmed':>10} {'right':>6}")
    for seed in (int(s) for s in args.seeds.split(",")):
        spec = draw(seed, args.size)
        if spec.backdrop.room is None:
            continue
        for angle in (float(a) for a in args.angles.split(",")):
            right = confirmed = pixels = 0
            for start in spec.rig.azimuths:
                pair = [camera_at(spec, start + k * angle, spec.rig.elevation_deg) for k in (0, 1)]
                plates = [static_image(p, spec.bodies, spec.backdrop) for p in pair]
                sure = [np.ones(p.shape[:2], np.float32) for p in plates]
                maps = depth_maps([as_camera(p) for p in pair], plates, sure, spec.lo, spec.hi, every_pair)
                for depth, pinhole in zip(maps, pair):
                    truth = true_depth(pinhole, spec)
                    kept = np.isfinite(depth.depth)
                    confirmed += int(kept.sum())
                    pixels += kept.size
                    right += int((kept & (np.abs(depth.depth - truth) < 0.05 * truth)).sum())
            print(f"{seed:>5} {spec.backdrop.kind:<5} {angle:>6.0f} {confirmed / pixels:>10.2f} "
                  f"{right / max(confirmed, 1):>6.2f}", flush=True)


if __name__ == "__main__":
    main()
