"""Quality of a scene's clean plates against its known backdrop colour (run ``fluidnexus background SCENE`` first).

Usage: python benchmarks/bench_background.py SCENE --reference R,G,B

For every input view with a plate, prints PSNR (dB) against a constant image of the reference colour of:
- ``plate``: the plate ``fluidnexus background`` recorded (its source in brackets);
- ``temporal``: the temporal-mode estimate alone (no colour, no clean frames), as the estimator sees the footage;
- ``frame0`` and ``median``: frame 0 and the per-pixel temporal median of the footage (baselines);
each over the whole image and over the backdrop (pixels whose recorded plate is the reference colour, i.e.
without the static objects the colour source kept), with the share of pixels kept as objects. Static objects
(Sphere's sphere) are real content, so the whole-image figure of a correct plate is finite.
"""
import argparse
import platform
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluidnexus.scene import load_scene  # noqa: E402
from fluidnexus.scenery.plate_store import read_plate  # noqa: E402
from fluidnexus.scenery.plates import noise_level, quiet_mask, temporal_mode  # noqa: E402
from fluidnexus.video import read_video  # noqa: E402


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - b) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(1.0 / mse)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--reference", required=True, help="R,G,B in [0, 1]")
    args = parser.parse_args()
    ref = np.array([float(v) for v in args.reference.split(",")], np.float32)
    scene = load_scene(args.scene)
    print(f"scene {args.scene}, reference colour {ref.tolist()}, {platform.node()}, {platform.processor()}")
    print("| view | plate (source) | temporal | frame 0 | median | objects | "
          "backdrop: plate | temporal | frame 0 | median |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for view in scene.with_role("input"):
        if view.name not in scene.backgrounds:
            continue
        plate, _ = read_plate(scene, view.name)
        video = read_video(scene.video_path(view), channels=3)
        noise = noise_level(video)
        temporal = temporal_mode(video, quiet_mask(video, noise), noise).plate
        images = {"plate": plate, "temporal": temporal, "frame0": video[0], "median": np.median(video, axis=0)}
        backdrop = np.abs(plate - ref).max(axis=2) < 1e-3
        whole = [psnr(im, ref) for im in images.values()]
        back = [psnr(im[backdrop], ref) for im in images.values()]
        source = scene.backgrounds[view.name].source
        print(f"| {view.name} | {whole[0]:.1f} ({source}) | {whole[1]:.1f} | {whole[2]:.1f} | {whole[3]:.1f} | "
              f"{1 - backdrop.mean():.1%} | " + " | ".join(f"{v:.1f}" for v in back) + " |")


if __name__ == "__main__":
    main()
