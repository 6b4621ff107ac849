"""PINF import on the embedded ScalarFlow sample and the full capture in ../shared."""
import json

import numpy as np
import pytest

from clirun import ok
from fluidnexus.calibrate.pinf import pinf_dict, read_pinf
from fluidnexus.samples import sample_path
from fluidnexus.scene import load_ground_truth, load_scene
from fluidnexus.video import read_video

OTHERS = "train00,train01,train03,train04"



@pytest.fixture(scope="module")
def sample_scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("scenes") / "single"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "single-view", "--out", out)
    return out


def test_single_view_protocol(sample_scene):
    scene = load_scene(sample_scene)
    assert [v.name for v in scene.with_role("input")] == ["train02"]
    assert [v.name for v in scene.with_role("novel")] == OTHERS.split(",")
    assert all(v.video is None for v in scene.with_role("novel"))
    assert [g.name for g in load_ground_truth(sample_scene)] == OTHERS.split(",")
    assert scene.frame_count == 120 and scene.fps == 30
    cam = scene.view("train02").camera
    assert (cam.width, cam.height) == (270, 480)
    assert cam.K[0, 0] == pytest.approx(2565.0 / 4, abs=0.5)  # README: 2565 px at full size for view 2


def test_four_view_protocol(tmp_path):
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--out", tmp_path / "s")
    scene = load_scene(tmp_path / "s")
    assert [v.name for v in scene.with_role("input")] == OTHERS.split(",")
    assert not scene.with_role("novel")
    assert [g.name for g in load_ground_truth(tmp_path / "s")] == ["train02"]


def test_volume_from_voxel_matrix(sample_scene):
    vol = load_scene(sample_scene).volume
    np.testing.assert_allclose(vol.min, [0.082, -0.045, -0.496], atol=1e-3)
    np.testing.assert_allclose(vol.max, [0.573, 0.692, -0.005], atol=1e-3)


def test_bottom_centre_projects_onto_the_inflow(sample_scene):
    """The volume's bottom centre lands on the smoke inflow column in every real view."""
    scene = load_scene(sample_scene)
    views = {v.name: v.camera for v in scene.views}
    videos = {"train02": scene.root / scene.view("train02").video}
    videos.update({g.name: scene.root / g.video for g in load_ground_truth(sample_scene)})
    foot = np.asarray(scene.source.center)[None]
    np.testing.assert_allclose(foot[0], scene.volume.bottom_center)
    for name, path in videos.items():
        frames = read_video(path, frames=slice(0, 30), gray=True)[..., 0].mean(0)
        rows = np.where(frames.max(1) > 0.1)[0]
        lowest = rows.max()
        cols = np.where(frames[lowest - 3] > 0.1)[0]  # the inflow column just above its lowest row
        uv, depth = views[name].project(foot)
        assert depth[0] > 0
        assert cols.min() - 3 <= uv[0, 0] <= cols.max() + 3, (name, uv, cols.min(), cols.max())
        assert lowest <= uv[0, 1] <= lowest + 40, (name, uv, lowest)  # just below the first visible smoke


def test_round_trip_pinf_scene_pinf(tmp_path):
    """Four-view protocol keeps the file's own train/test split, so the round trip must give the file back."""
    info = sample_path("scalarflow") / "info.json"
    out = tmp_path / "s"
    ok("calibrate", "--from-pinf", info, "--input", OTHERS, "--ground-truth", "train02", "--out", out,
        "--to-pinf", out / "info.json")
    original = json.loads(info.read_text())
    back = json.loads((out / "info.json").read_text())
    for key in ("voxel_matrix", "voxel_scale", "near", "far", "render_center", "phi", "rot", "frame_bkg_color"):
        assert back[key] == original[key], key
    for split in ("train_videos", "test_videos"):
        assert [e["file_name"].split("/")[-1] for e in back[split]] == [e["file_name"] for e in original[split]]
        for a, b in zip(original[split], back[split]):
            for key in ("frame_rate", "frame_num", "camera_hw"):
                assert a[key] == b[key], key
            assert b["camera_angle_x"] == pytest.approx(a["camera_angle_x"], abs=1e-12)
            np.testing.assert_allclose(b["transform_matrix"], a["transform_matrix"], rtol=0, atol=1e-12)
    # and the written info.json imports again into the same cameras
    again = read_pinf(out / "info.json")
    first = read_pinf(info)
    for name, rec in first.recordings.items():
        np.testing.assert_allclose(again.recordings[name].camera.w2c, rec.camera.w2c, atol=1e-12)
        assert again.recordings[name].media.resolve() == (out / "videos" / f"{name}.mp4").resolve() or \
            again.recordings[name].media.resolve() == (out / "ground_truth" / f"{name}.mp4").resolve()


def test_pinf_dict_without_import_metadata_builds_a_voxel_box(sample_scene):
    scene = load_scene(sample_scene)
    from dataclasses import replace

    data = pinf_dict(replace(scene, extra={}), ())
    m, s = np.array(data["voxel_matrix"]), np.array(data["voxel_scale"])
    R = m[:3, :3][:, [2, 1, 0]]
    np.testing.assert_allclose(R, np.eye(3))
    np.testing.assert_allclose(m[:3, 3] + s, scene.volume.max)


@pytest.mark.parametrize("protocol_args", [
    ["--input", "train02", "--novel", OTHERS, "--ground-truth", OTHERS],
    ["--input", OTHERS, "--ground-truth", "train02"],
])
def test_shared_capture_exact_commands(tmp_path, shared_scalarflow, protocol_args):
    """The issue's two commands on the real full-resolution capture, with README conventions."""
    out = tmp_path / "scene"
    ok("calibrate", "--from-pinf", shared_scalarflow / "info.json", *protocol_args, "--out", out, "--link")
    scene = load_scene(out)
    cams = {v.name: v.camera for v in scene.views}
    cams.update({g.name: g.camera for g in load_ground_truth(out)})
    expected_fx = {"train00": 2614, "train01": 2705, "train02": 2565, "train03": 2576, "train04": 2614}
    known = json.loads((shared_scalarflow / "cameras.json").read_text())["cameras"]
    for entry in known:
        name = entry["file"][:-4]
        cam = cams[name]
        assert (cam.width, cam.height) == (1080, 1920)
        assert cam.K[0, 0] == pytest.approx(expected_fx[name], abs=0.5)
        np.testing.assert_allclose(cam.w2c, entry["w2c_opencv"], atol=1e-6)
        np.testing.assert_allclose(cam.center, entry["position"], atol=1e-6)
        # a point one metre along the README's view direction projects to the principal point
        p = np.asarray(entry["position"]) + np.asarray(entry["viewdir"])
        uv, depth = cam.project(p[None])
        np.testing.assert_allclose(uv[0], [540, 960], atol=1e-3)
        assert depth[0] == pytest.approx(1.0, abs=1e-6)
