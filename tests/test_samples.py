"""The embedded ScalarFlow sample: found by name, complete, small, calibrated, and faithful to ../shared."""
from __future__ import annotations

import configparser
import fnmatch
import json
import math
from pathlib import Path

import numpy as np
import pytest

from fluidnexus.camera import Camera
from fluidnexus.errors import InputError
from fluidnexus.samples import sample_names, sample_path
from fluidnexus.video import VideoInfo, probe_video, read_video

VIEWS = [f"train{v:02d}.mp4" for v in range(5)]
SETUP_CFG = Path(__file__).resolve().parents[1] / "setup.cfg"


@pytest.fixture(scope="module")
def scalarflow() -> Path:
    return sample_path("scalarflow")


@pytest.fixture(scope="module")
def info(scalarflow) -> dict:
    return json.loads((scalarflow / "info.json").read_text())


def entries(info: dict) -> list[dict]:
    return info["train_videos"] + info["test_videos"]


def test_sample_is_found_by_name(scalarflow):
    assert "scalarflow" in sample_names()
    assert scalarflow.is_dir() and scalarflow.name == "scalarflow"


def test_unknown_sample_lists_the_known_ones():
    with pytest.raises(InputError) as err:
        sample_path("nosuch")
    assert err.value.field == "--sample" and "nosuch" in str(err.value) and "scalarflow" in str(err.value)


def test_sample_files_are_complete_small_and_installed(scalarflow):
    names = sorted(p.name for p in scalarflow.iterdir())
    assert names == sorted(VIEWS + ["info.json", "README.md"])
    assert sum(p.stat().st_size for p in scalarflow.iterdir()) < 4e6
    # Every file is covered by setup.cfg's package_data, so an installed package carries it.
    config = configparser.ConfigParser()
    config.read(SETUP_CFG)
    patterns = [p.strip() for p in config["options.package_data"]["fluidnexus.samples"].split(",")]
    for name in names:
        assert any(fnmatch.fnmatch(f"scalarflow/{name}", p) for p in patterns), name


@pytest.mark.parametrize("view", VIEWS)
def test_sample_videos_have_the_expected_shape(scalarflow, view):
    path = scalarflow / view
    assert probe_video(path) == VideoInfo(frame_count=120, width=270, height=480, fps=30.0)
    clip = read_video(path, frames=slice(60, 62), gray=True)
    assert clip.shape == (2, 480, 270, 1)
    assert 0.0 < clip.mean() < 0.2 and clip.max() < 0.8  # gray smoke (at most ~190/255) on black


def test_info_json_is_sized_for_the_sample(info):
    assert [e["file_name"] for e in entries(info)] == ["train00.mp4", "train01.mp4", "train03.mp4",
                                                       "train04.mp4", "train02.mp4"]
    for entry in entries(info):
        assert entry["camera_hw"] == [480, 270]
        assert entry["frame_num"] == 120 and entry["frame_rate"] == 30
    first = info["train_videos"][0]
    cam = Camera.from_nerf(first["transform_matrix"], width=270, height=480,
                           camera_angle_x=first["camera_angle_x"])
    assert cam.K[0, 0] == pytest.approx(653.44, abs=0.005)
    assert cam.K[0, 2] == 135.0 and cam.K[1, 2] == 240.0


def test_readme_carries_the_licence_and_citations(scalarflow):
    text = (scalarflow / "README.md").read_text()
    for needle in ("CC BY-NC-SA 4.0", "ScalarFlow", "2019", "Physics Informed Neural Fields", "2022",
                   "camera_hw"):
        assert needle in text


def test_sample_matches_the_shared_capture(scalarflow, info, shared_scalarflow):
    npz = np.load(shared_scalarflow / "frames_quarter_480x270.npz")
    for view, name in enumerate(VIEWS):
        target = npz["frames"][view].astype(np.float32)[..., None] / 255.0
        decoded = read_video(scalarflow / name, gray=True)
        psnr = 10 * math.log10(1.0 / np.mean((decoded.astype(np.float64) - target) ** 2))
        assert psnr > 40.0, (name, psnr)
    original = json.loads((shared_scalarflow / "info.json").read_text())
    for entry in entries(original):
        entry["camera_hw"] = [480, 270]
    assert info == original
    by_name = {e["file_name"]: e for e in entries(info)}
    for view, name in enumerate(VIEWS):
        cam = Camera.from_nerf(by_name[name]["transform_matrix"], 270, 480, by_name[name]["camera_angle_x"])
        np.testing.assert_allclose(cam.K, npz["K"][view], rtol=1e-12)
        np.testing.assert_allclose(cam.w2c, npz["w2c_opencv"][view], atol=1e-6)
