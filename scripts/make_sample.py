"""Regenerate the embedded ScalarFlow sample (fluidnexus/samples/scalarflow) from ../shared.

Source: ``../shared/data/scalarflow_sim000000``: ``frames_quarter_480x270.npz`` (uint8 frames [V=5, T=120,
H=480, W=270], the 1/4-resolution decode of the original train00..04.mp4) and ``info.json`` (PINF metadata).

Output, in ``fluidnexus/samples/scalarflow/``:
    train00.mp4 .. train04.mp4   270 x 480 (W x H), 120 frames, 30 fps, H.264 yuv420p, gray smoke (R = G = B),
                                 x264 CRF 10 preset slow (view i of the npz is train0i.mp4).
    info.json                    the original PINF file with every ``camera_hw`` set to [480, 270].
The README.md beside them (licence and citations) is maintained by hand.

Deterministic: the same npz and the same bundled ffmpeg give byte-identical files. The script prints, per view,
the PSNR of the decoded MP4 against the npz frames, and checks that the npz intrinsics equal the ones derived
from info.json at the new size (fx = 0.5 W / tan(0.5 camera_angle_x)).

Usage (from the repository root, with fluidnexus importable: ``pip install -e .`` or ``PYTHONPATH=.``):
    python scripts/make_sample.py [--shared ../shared/data/scalarflow_sim000000] [--out fluidnexus/samples/scalarflow]
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from fluidnexus.atomic import write_json
from fluidnexus.video import read_video, write_video

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_HW = [480, 270]
CRF = 10
PRESET = "slow"


def sample_info(info: dict, npz_K: np.ndarray) -> dict:
    """The PINF info with ``camera_hw`` set to the sample size, checked against the npz intrinsics [V, 3, 3]."""
    info = json.loads(json.dumps(info))
    for entry in info["train_videos"] + info["test_videos"]:
        entry["camera_hw"] = list(SAMPLE_HW)
        view = int(Path(entry["file_name"]).stem.removeprefix("train"))
        fx = 0.5 * SAMPLE_HW[1] / math.tan(0.5 * entry["camera_angle_x"])
        if not np.isclose(fx, npz_K[view, 0, 0], rtol=1e-9):
            raise SystemExit(f"{entry['file_name']}: fx {fx} from info.json != npz K {npz_K[view, 0, 0]}")
    return info


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB of two arrays in [0, 1]."""
    return float(10.0 * np.log10(1.0 / np.mean((a.astype(np.float64) - b) ** 2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", type=Path, default=ROOT.parent / "shared" / "data" / "scalarflow_sim000000")
    parser.add_argument("--out", type=Path, default=ROOT / "fluidnexus" / "samples" / "scalarflow")
    args = parser.parse_args()

    npz = np.load(args.shared / "frames_quarter_480x270.npz")
    frames, fps = npz["frames"], float(npz["fps"])
    info = json.loads((args.shared / "info.json").read_text())
    write_json(args.out / "info.json", sample_info(info, npz["K"]))
    for view in range(frames.shape[0]):
        target = frames[view].astype(np.float32)[..., None] / 255.0
        path = write_video(args.out / f"train{view:02d}.mp4", target, fps, crf=CRF, preset=PRESET)
        decoded = read_video(path, gray=True)
        print(f"{path.name}: {path.stat().st_size / 1e6:.2f} MB, PSNR vs npz {psnr(decoded, target):.2f} dB, "
              f"max |error| {np.abs(decoded - target).max() * 255:.0f}/255")


if __name__ == "__main__":
    main()
