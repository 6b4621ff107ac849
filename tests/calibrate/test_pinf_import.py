"""PINF's format in full: Sphere's structure (z up, one voxel_scale, val videos, backdrop colour), length units,
moving cameras and bad input. The capture is built here (tests/calibrate/pinf_capture.py); the real Sphere scene
in ../shared is used too where it is present."""
import json
from pathlib import Path

import numpy as np
import pytest

from clirun import assert_clean_failure, invoke, ok
from fluidnexus.calibrate.pinf import read_pinf
from fluidnexus.samples import sample_path
from fluidnexus.scene import load_ground_truth, load_scene

from .pinf_capture import RING_HEIGHT, source_box, ring_camera, write_capture

TRAIN = "train00,train01,train02,train03,train04"
SPHERE = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "pinf_sphere"




def check_upright_ring(scene_dir: Path, height: float = RING_HEIGHT):
    """The imported rig: +y up, cameras on a ring at the file's height (its z), all looking at the volume."""
    scene = load_scene(scene_dir)
    cams = [v.camera for v in scene.views] + [g.camera for g in load_ground_truth(scene_dir)]
    for cam in cams:
        assert cam.center[1] == pytest.approx(height, abs=1e-9)  # the file's z is the scene's y
        assert -cam.R[1][1] > 0.8  # image up is world up
        uv, depth = cam.project(scene.volume.center[None])
        assert depth[0] > 0 and np.all((uv[0] > 0) & (uv[0] < cam.width)), uv  # the volume is in view
    return scene


def test_sphere_structure_imports_z_up_into_y_up(tmp_path):
    info = write_capture(tmp_path / "cap")
    out = tmp_path / "S"
    ok("calibrate", "--from-pinf", info, "--input", TRAIN, "--ground-truth", "test02,test04", "--out", out)
    scene = check_upright_ring(out)
    # the box: PINF's z-up box rotated by (x, y, z) -> (x, z, -y)
    lo, hi = source_box()
    np.testing.assert_allclose(scene.volume.min, [lo[0], lo[2], -hi[1]], atol=1e-12)
    np.testing.assert_allclose(scene.volume.max, [hi[0], hi[2], -lo[1]], atol=1e-12)
    assert scene.volume.max[0] - scene.volume.min[0] == pytest.approx(0.4 * 12.0064)
    assert scene.source is None  # PINF declares no inflow, and the import invents none
    data = json.loads((out / "scene.json").read_text())
    np.testing.assert_array_equal(data["source_frame"]["rotation"], [[1, 0, 0], [0, 0, 1], [0, -1, 0]])
    assert data["source_frame"]["metres_per_unit"] == 1.0
    assert data["backdrop_color"] == [1.0, 1.0, 1.0] and scene.backdrop_color == (1.0, 1.0, 1.0)
    assert data["extra"]["pinf"]["rot"] == "Z" and data["extra"]["pinf"]["voxel_scale"] == 12.0064
    assert [g.name for g in load_ground_truth(out)] == ["test02", "test04"]  # a val and a test video


def test_a_declared_source_is_converted_and_kept_and_a_bad_one_refused(tmp_path):
    info = write_capture(tmp_path / "cap")
    lo, hi = source_box()
    centre = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]  # z up: the foot of the file's box
    out = tmp_path / "S"
    ok("calibrate", "--from-pinf", info, "--input", TRAIN, "--out", out, "--source", ",".join(map(str, centre + [0.1])))
    scene = load_scene(out)
    np.testing.assert_allclose(scene.source.center, [centre[0], centre[2], -centre[1]], atol=1e-12)  # (x, z, -y)
    assert scene.source.radius == pytest.approx(0.1)
    for bad, says in (("1,2,3", "four finite numbers"), ("0,0,0,-1", "radius must be > 0"),
                      (f"{hi[0] + 10},0,0,0.1", "outside the volume")):
        res = invoke("calibrate", "--from-pinf", info, "--input", TRAIN, "--out", tmp_path / "bad", "--source", bad)
        assert res.exit_code == 2 and "--source" in res.output and says in res.output, res.output
        assert not (tmp_path / "bad").exists()


def test_every_split_names_views_in_every_role(tmp_path):
    info = write_capture(tmp_path / "cap")
    out = tmp_path / "S"
    ok("calibrate", "--from-pinf", info, "--input", "test02", "--novel", "test04,train01",
       "--ground-truth", "train00,train03", "--out", out)
    scene = load_scene(out)
    assert [v.name for v in scene.with_role("input")] == ["test02"]
    assert [v.name for v in scene.with_role("novel")] == ["test04", "train01"]
    assert [g.name for g in load_ground_truth(out)] == ["train00", "train03"]


def test_views_not_named_need_no_file(tmp_path):
    info = write_capture(tmp_path / "cap")
    for name in ("train04", "test02", "test04"):
        (tmp_path / "cap" / f"{name}.mp4").unlink()
    ok("calibrate", "--from-pinf", info, "--input", "train00,train01", "--novel", "train04",
       "--ground-truth", "train02", "--out", tmp_path / "S")
    result = invoke("calibrate", "--from-pinf", info, "--input", "train00", "--ground-truth", "test04",
                    "--out", tmp_path / "T")
    assert_clean_failure(result, "test04.mp4", "file not found")
    assert not (tmp_path / "T").exists()


@pytest.mark.parametrize("voxel_scale", [12.0064, [12.0064], [12.0064, 12.0064, 12.0064], [4.0, 5.0, 6.0]])
def test_voxel_scale_one_number_or_three(tmp_path, voxel_scale):
    info = write_capture(tmp_path / "cap", voxel_scale=voxel_scale, videos=False)
    vol = read_pinf(info).volume
    lo, hi = source_box(voxel_scale=voxel_scale)
    np.testing.assert_allclose(vol.min, [lo[0], lo[2], -hi[1]], atol=1e-12)
    np.testing.assert_allclose(vol.max, [hi[0], hi[2], -lo[1]], atol=1e-12)


def test_rot_absent_or_y_keeps_the_world(tmp_path):
    for rot in (None, "Y"):
        info = write_capture(tmp_path / f"cap{rot}", rot=rot)
        cap = read_pinf(info)
        assert cap.frame.is_identity
        np.testing.assert_allclose(cap.recordings["train01"].camera.w2c, ring_camera(72.0, 16, "Y").w2c, atol=1e-12)
        out = tmp_path / f"S{rot}"
        ok("calibrate", "--from-pinf", info, "--input", TRAIN, "--out", out)
        assert "source_frame" not in json.loads((out / "scene.json").read_text())
        check_upright_ring(out)


def test_same_rig_z_up_and_y_up_give_one_scene(tmp_path):
    z = read_pinf(write_capture(tmp_path / "z", videos=False))
    y = read_pinf(write_capture(tmp_path / "y", rot="Y", videos=False))
    for name, rec in z.recordings.items():
        np.testing.assert_allclose(rec.camera.w2c, y.recordings[name].camera.w2c, atol=1e-12)
    np.testing.assert_allclose(z.volume.min, y.volume.min, atol=1e-12)
    np.testing.assert_allclose(z.volume.max, y.volume.max, atol=1e-12)


def test_z_up_scene_back_to_pinf_is_the_file(tmp_path):
    info = write_capture(tmp_path / "cap")
    out = tmp_path / "S"
    ok("calibrate", "--from-pinf", info, "--input", TRAIN, "--ground-truth", "test02,test04", "--out", out,
       "--to-pinf", tmp_path / "back.json")
    original, back = json.loads(info.read_text()), json.loads((tmp_path / "back.json").read_text())
    for key in ("voxel_matrix", "voxel_scale", "rot", "frame_bkg_color", "near", "far", "phi"):
        assert back[key] == original[key], key
    entries = {e["file_name"].split("/")[-1]: e for split in ("train_videos", "test_videos") for e in back[split]}
    for e in original["train_videos"] + original["test_videos"] + original["val_videos"]:
        np.testing.assert_allclose(entries[e["file_name"]]["transform_matrix"], e["transform_matrix"], atol=1e-12)


def scaled_sample_info(folder: Path, factor: float) -> Path:
    """ScalarFlow's info.json with every length multiplied by ``factor`` (videos linked)."""
    src = sample_path("scalarflow")
    data = json.loads((src / "info.json").read_text())
    folder.mkdir()
    for e in data["train_videos"] + data["test_videos"]:
        (folder / e["file_name"]).symlink_to(src / e["file_name"])
        m = np.array(e["transform_matrix"])
        m[:3, 3] *= factor
        e["transform_matrix"] = m.tolist()
    m = np.array(data["voxel_matrix"])
    m[:3, 3] *= factor
    data["voxel_matrix"] = m.tolist()
    data["voxel_scale"] = (np.array(data["voxel_scale"]) * factor).tolist()
    (folder / "info.json").write_text(json.dumps(data))
    return folder / "info.json"


def test_metres_per_unit_gives_the_original_geometry(tmp_path):
    roles = ["--input", "train00,train01,train03,train04", "--ground-truth", "train02"]
    ok("calibrate", "--from-pinf", sample_path("scalarflow") / "info.json", *roles, "--out", tmp_path / "m",
       "--source", "0.34,0.0,-0.23,0.025")
    scaled = scaled_sample_info(tmp_path / "cm", 10.0)
    ok("calibrate", "--from-pinf", scaled, *roles, "--metres-per-unit", "0.1", "--out", tmp_path / "s",
       "--to-pinf", tmp_path / "back.json", "--source", "3.4,0.0,-2.3,0.25")  # the same disk in the file's unit
    original, back = json.loads(scaled.read_text()), json.loads((tmp_path / "back.json").read_text())
    assert back["voxel_scale"] == original["voxel_scale"] and back["voxel_matrix"] == original["voxel_matrix"]
    for split in ("train_videos", "test_videos"):  # cameras written back in the file's unit
        for e, f in zip(original[split], back[split]):
            np.testing.assert_allclose(f["transform_matrix"], e["transform_matrix"], atol=1e-12)
    a, b = (json.loads((tmp_path / n / "scene.json").read_text()) for n in ("m", "s"))
    assert b["source_frame"]["metres_per_unit"] == 0.1 and "source_frame" not in a
    for key in ("min", "max"):
        np.testing.assert_allclose(b["volume"][key], a["volume"][key], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b["source"]["center"], a["source"]["center"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a["source"]["center"], [0.34, 0.0, -0.23], atol=1e-15)
    assert b["source"]["radius"] == pytest.approx(a["source"]["radius"]) == pytest.approx(0.025)
    for va, vb in zip(a["views"] + a["ground_truth"], b["views"] + b["ground_truth"]):
        np.testing.assert_allclose(vb["camera"]["world_to_camera"], va["camera"]["world_to_camera"],
                                   rtol=1e-12, atol=1e-15)
        assert vb["camera"]["K"] == va["camera"]["K"]


def test_moving_ground_truth_camera(tmp_path):
    path = write_capture(tmp_path / "cap")
    info = json.loads(path.read_text())
    poses = [ring_camera(180.0 + 10.0 * t, 16) for t in range(3)]
    info["test_videos"][0] = {**info["test_videos"][0], "transform_matrix_list": [
        c.to_nerf()["transform_matrix"] for c in poses]}
    del info["test_videos"][0]["transform_matrix"]
    path.write_text(json.dumps(info))
    out = tmp_path / "S"
    ok("calibrate", "--from-pinf", path, "--input", TRAIN, "--ground-truth", "test04,test02", "--out", out,
       "--to-pinf", tmp_path / "back.json")
    gt = {g.name: g for g in load_ground_truth(out)}
    assert gt["test02"].poses is None and gt["test04"].poses.shape == (3, 4, 4)
    flip = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]])  # z up -> y up
    for t, cam in enumerate(poses):
        np.testing.assert_allclose(gt["test04"].camera_at(t).center, flip @ cam.center, atol=1e-12)
    np.testing.assert_allclose(gt["test04"].camera.w2c, gt["test04"].poses[0])
    back = json.loads((tmp_path / "back.json").read_text())
    moving = next(e for e in back["test_videos"] if e["file_name"].endswith("test04.mp4"))
    np.testing.assert_allclose(moving["transform_matrix_list"], info["test_videos"][0]["transform_matrix_list"],
                               atol=1e-12)
    # a moving camera cannot be an input or novel view
    for role in ("--input", "--novel"):
        args = [role, "test04"] if role == "--input" else ["--input", "train00", role, "test04"]
        result = invoke("calibrate", "--from-pinf", path, *args, "--out", tmp_path / "bad")
        assert_clean_failure(result, "info.json", role, "test04", "--ground-truth")
        assert not (tmp_path / "bad").exists()


# ---- bad input: one line naming the file and the field, exit 2, nothing written ------------------------------
@pytest.mark.parametrize("field,value,needle", [
    ("voxel_scale", [1.0, 2.0], "voxel_scale"),
    ("voxel_scale", -3.0, "voxel_scale"),
    ("voxel_scale", [1.0, 0.0, 1.0], "voxel_scale"),
    ("voxel_scale", "big", "voxel_scale"),
    ("rot", "X", "rot"),
    ("rot", 3, "rot"),
    ("frame_bkg_color", [1.0, 2.0, 0.0], "frame_bkg_color"),
    ("voxel_matrix", [[1.0, 0.0], [0.0, 1.0]], "voxel_matrix"),
])
def test_bad_fields(tmp_path, field, value, needle):
    info = write_capture(tmp_path / "cap", **{field: value})
    result = invoke("calibrate", "--from-pinf", info, "--input", TRAIN, "--out", tmp_path / "S")
    assert_clean_failure(result, "info.json", needle)
    assert not (tmp_path / "S").exists()


def test_bad_pose_list_and_unit(tmp_path):
    path = write_capture(tmp_path / "cap")
    info = json.loads(path.read_text())
    info["test_videos"][0]["transform_matrix_list"] = [info["test_videos"][0]["transform_matrix"]] * 2
    path.write_text(json.dumps(info))
    result = invoke("calibrate", "--from-pinf", path, "--input", TRAIN, "--ground-truth", "test04",
                    "--out", tmp_path / "S")
    assert_clean_failure(result, "info.json", "test_videos[0].transform_matrix_list", "frame_num = 3")
    for value in ("0", "-1", "nan"):
        result = invoke("calibrate", "--from-pinf", write_capture(tmp_path / "ok"), "--input", TRAIN,
                        "--metres-per-unit", value, "--out", tmp_path / "S")
        assert_clean_failure(result, "--metres-per-unit")
    result = invoke("calibrate", "--sample", "scalarflow", "--metres-per-unit", "0.1", "--out", tmp_path / "S")
    assert_clean_failure(result, "--metres-per-unit", "imported files")
    assert not (tmp_path / "S").exists()


# ---- the real scene -----------------------------------------------------------------------------------------
@pytest.fixture
def sphere() -> Path:
    if not (SPHERE / "info.json").exists():
        pytest.skip("../shared/data/pinf_sphere is not present on this machine")
    return SPHERE


def test_real_sphere_as_published(tmp_path, sphere):
    """The issue's command on PINF's unmodified Sphere files."""
    out = tmp_path / "S"
    ok("calibrate", "--from-pinf", sphere / "info.json", "--input", TRAIN, "--ground-truth", "test02,test04",
       "--out", out, "--link", "--to-pinf", tmp_path / "back.json")
    scene = check_upright_ring(out, height=1.659749150276184)  # every camera's z in the file
    assert scene.frame_count == 158 and scene.fps == 25 and scene.backdrop_color == (1.0, 1.0, 1.0)
    np.testing.assert_allclose(np.subtract(scene.volume.max, scene.volume.min), 0.4 * 12.0064, rtol=1e-6)
    original = json.loads((sphere / "info.json").read_text())
    back = json.loads((tmp_path / "back.json").read_text())
    entries = {e["file_name"].split("/")[-1]: e for split in ("train_videos", "test_videos") for e in back[split]}
    for e in original["train_videos"] + original["test_videos"] + original["val_videos"]:
        np.testing.assert_allclose(entries[e["file_name"]]["transform_matrix"], e["transform_matrix"], atol=1e-9)
