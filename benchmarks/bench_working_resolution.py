"""Benchmark: ``synth`` and ``refine`` on a full-resolution (1080 x 1920) import, at the video's size against the
working resolution (``--resolution auto``, recon's rule: long side 480 px).

The 1080 x 1920 scene is the embedded ScalarFlow sample upscaled 4x (bilinear) with its PINF metadata's
``camera_hw`` set to the new size, imported with the single-view protocol (train02 in, four novel cameras).
Both runs start from the same freshly imported scene; wall times of each command are printed, with the size of
the written novel videos and the time ``recon`` then spends reading them (``load_observations``).

Run: ``.venv/bin/python benchmarks/bench_working_resolution.py [--frames 20]``
"""
from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.recon.observations import load_observations
from fluidnexus.samples import sample_path
from fluidnexus.scene import load_scene
from fluidnexus.video import probe_video, read_video, write_video


def cli(*args) -> float:
    tic = time.perf_counter()
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return time.perf_counter() - tic


def upscaled_import(root: Path, frames: int, factor: int = 4) -> Path:
    src, folder = sample_path("scalarflow"), root / "pinf"
    folder.mkdir(parents=True)
    info = json.loads((src / "info.json").read_text())
    for entry in info["train_videos"] + info.get("test_videos", []):
        h, w = entry["camera_hw"]
        entry["camera_hw"], entry["frame_num"] = [h * factor, w * factor], frames
        video = read_video(src / entry["file_name"], frames=slice(0, frames), size=(w * factor, h * factor))
        write_video(folder / entry["file_name"], video, fps=entry["frame_rate"])
    (folder / "info.json").write_text(json.dumps(info))
    scene = root / "scene"
    cli("calibrate", "--from-pinf", folder / "info.json", "--input", "train02",
        "--novel", "train00,train01,train03,train04", "--out", scene)
    return scene


def main_(frames: int) -> None:
    root = Path(tempfile.mkdtemp(prefix="bench_wres_"))
    try:
        base = upscaled_import(root, frames)
        print(f"scene: {frames} frames at {probe_video(next((base / 'videos').glob('*.mp4'))).width}x"
              f"{probe_video(next((base / 'videos').glob('*.mp4'))).height}")
        for label, resolution in (("full size (before)", "1"), ("working resolution (auto)", "auto")):
            scene = root / f"scene_{resolution}"
            shutil.copytree(base, scene)
            t_synth = cli("synth", scene, "--resolution", resolution)
            t_refine = cli("refine", scene, "--resolution", resolution)
            loaded = load_scene(scene)
            novel = [v for v in loaded.views if v.role == "novel"]
            info = probe_video(loaded.video_path(novel[0]))
            tic = time.perf_counter()
            load_observations(loaded, (0, frames), 480 / 1920, 1)
            t_read = time.perf_counter() - tic
            print(f"{label:28s} synth {t_synth:7.1f} s  refine {t_refine:7.1f} s  novel videos {info.width}x"
                  f"{info.height}  recon reads all views in {t_read:5.1f} s")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    main_(parser.parse_args().frames)
