"""Bad input to ``fluidnexus calibrate``: one line naming file and field, exit code 2, nothing written."""
import json
import subprocess
import sys

import pytest
from click.testing import CliRunner

from clirun import assert_clean_failure
from fluidnexus_cli.main import main
from fluidnexus.samples import sample_path


def calibrate(*args):
    return CliRunner().invoke(main, ["calibrate", *[str(a) for a in args]])




@pytest.fixture
def info_copy(tmp_path):
    """A copy of the sample's info.json whose videos are symlinks to the sample's."""
    src = sample_path("scalarflow")
    data = json.loads((src / "info.json").read_text())
    for entry in data["train_videos"] + data["test_videos"]:
        (tmp_path / entry["file_name"]).symlink_to(src / entry["file_name"])
    return tmp_path, data


def write_info(folder, data):
    (folder / "info.json").write_text(json.dumps(data))
    return folder / "info.json"


def test_missing_file(tmp_path):
    r = calibrate("--from-pinf", tmp_path / "nope.json", "--input", "a", "--out", tmp_path / "s")
    assert_clean_failure(r, "nope.json", "file not found")
    assert not (tmp_path / "s").exists()


def test_unknown_view_name(info_copy, tmp_path):
    folder, data = info_copy
    r = calibrate("--from-pinf", write_info(folder, data), "--input", "train09", "--out", tmp_path / "s")
    assert_clean_failure(r, "info.json", "--input", "train09", "train02")
    assert not (tmp_path / "s").exists()


def test_truncated_video(info_copy, tmp_path):
    folder, data = info_copy
    video = folder / "train02.mp4"
    blob = video.read_bytes()
    video.unlink()
    video.write_bytes(blob[: len(blob) // 2])
    r = calibrate("--from-pinf", write_info(folder, data), "--input", "train02", "--out", tmp_path / "s")
    assert_clean_failure(r, "train02.mp4", "video")
    assert not (tmp_path / "s").exists()
    assert not list(tmp_path.glob(".s.*"))  # no temporary folder left behind


def test_garbage_video(info_copy, tmp_path):
    folder, data = info_copy
    (folder / "train02.mp4").unlink()
    (folder / "train02.mp4").write_bytes(b"not a video at all" * 100)
    r = calibrate("--from-pinf", write_info(folder, data), "--input", "train02", "--out", tmp_path / "s")
    assert_clean_failure(r, "train02.mp4")


def test_frame_count_mismatch(info_copy, tmp_path, make_video):
    folder, data = info_copy
    (folder / "train00.mp4").unlink()
    make_video(folder / "train00.mp4", frames=7, width=270, height=480)
    r = calibrate("--from-pinf", write_info(folder, data), "--input", "train00,train02", "--out", tmp_path / "s")
    assert_clean_failure(r, "train00.mp4", "frame_count", "7")
    assert not (tmp_path / "s").exists()


def test_resolution_mismatch(info_copy, tmp_path, make_video):
    folder, data = info_copy
    (folder / "train00.mp4").unlink()
    make_video(folder / "train00.mp4", frames=120, width=136, height=240)
    r = calibrate("--from-pinf", write_info(folder, data), "--input", "train00,train02", "--out", tmp_path / "s")
    assert_clean_failure(r, "train00.mp4", "resolution")


@pytest.mark.parametrize("field, value, needle", [
    ("transform_matrix", [[float("nan")] * 4] * 4, "non-finite"),
    ("transform_matrix", [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "not a rotation"),
    ("camera_angle_x", -0.4, "focal"),
])
def test_bad_camera(info_copy, tmp_path, field, value, needle):
    folder, data = info_copy
    data["train_videos"][1][field] = value
    r = calibrate("--from-pinf", write_info(folder, data), "--input", "train02", "--out", tmp_path / "s")
    assert_clean_failure(r, "info.json", "train_videos[1]", needle)


def test_unknown_scene_format(tmp_path):
    (tmp_path / "scene").mkdir()
    (tmp_path / "scene" / "scene.json").write_text(json.dumps({"format": "other/2"}))
    from fluidnexus.errors import InputError
    from fluidnexus.scene import load_scene

    with pytest.raises(InputError) as err:
        load_scene(tmp_path / "scene")
    assert "scene.json: format: unknown format tag 'other/2'" in str(err.value)


def test_existing_output_is_kept(tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    r = calibrate("--sample", "scalarflow", "--out", out)
    assert_clean_failure(r, str(out), "--overwrite")
    assert (out / "keep.txt").read_text() == "mine"


def test_two_modes_at_once(tmp_path):
    r = calibrate("--sample", "scalarflow", "--video", tmp_path / "v.mp4", "--out", tmp_path / "s")
    assert_clean_failure(r, "exactly one")


def test_bad_scale_distance(tmp_path):
    r = calibrate("--images", tmp_path / "a.png", tmp_path / "b.png", "--scale-distance", "a,b,-1", "--out",
                  tmp_path / "s")
    assert_clean_failure(r, "--scale-distance")


def test_console_script_exit_code(tmp_path):
    """The installed entry point itself: exit 2 and one line on stderr."""
    proc = subprocess.run([sys.executable, "-m", "fluidnexus_cli", "calibrate", "--from-pinf", str(tmp_path / "x.json"),
                           "--input", "a", "--out", str(tmp_path / "s")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"error: {tmp_path / 'x.json'}: file not found"]
