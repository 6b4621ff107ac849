"""``fluidnexus background`` end to end on small synthetic scenes (MP4 footage written by the test)."""
import json
import shutil

import cv2
import numpy as np
import pytest

from fluidnexus.errors import InputError
from fluidnexus.scene import load_scene
from fluidnexus.scenery.plate_store import read_image, read_plate
from tests.clirun import assert_clean_failure, invoke, ok

from .plate_scenes import HEIGHT, WIDTH, make_scene, psnr

CLI_PSNR = 38.0  # dB through H.264 (crf 12); measured 41.6-46.1 dB (docs/background.md)




def assert_nothing_written(root, scene_json_before):
    assert not (root / "backgrounds").exists()
    assert not list(root.glob(".backgrounds*"))
    assert (root / "scene.json").read_bytes() == scene_json_before


@pytest.mark.parametrize("kind", ["dark", "bright"])
def test_plates_are_estimated_and_recorded(tmp_path, kind):
    truth = make_scene(tmp_path / "s", kind)
    ok("background", tmp_path / "s")
    scene = load_scene(tmp_path / "s")
    assert sorted(scene.backgrounds) == ["cam0", "cam1"]  # the ground-truth camera gets none
    for name in ("cam0", "cam1"):
        record = scene.backgrounds[name]
        assert record.source == "temporal" and record.summary["seen_fraction"] > 0.9
        plate, conf = read_plate(scene, name)
        assert plate.shape == (HEIGHT, WIDTH, 3) and conf.shape == (HEIGHT, WIDTH)
        assert psnr(plate, truth[name]) > CLI_PSNR
    sheet = cv2.imread(str(tmp_path / "s/backgrounds/sheet.png"))
    assert sheet is not None and sheet.shape[0] > 2 * 240


def test_user_plate_is_used_as_is(tmp_path):
    make_scene(tmp_path / "s")
    given = np.random.default_rng(0).integers(0, 256, (HEIGHT, WIDTH, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "wall.png"), given)
    ok("background", tmp_path / "s", "--plate", f"cam0={tmp_path / 'wall.png'}")
    scene = load_scene(tmp_path / "s")
    plate, conf = read_plate(scene, "cam0")
    np.testing.assert_array_equal(plate, read_image(tmp_path / "wall.png"))
    assert np.all(conf == 1) and scene.backgrounds["cam0"].source == "plate"
    assert scene.backgrounds["cam1"].source == "temporal"


def test_clean_frames_and_known_color(tmp_path):
    truth = make_scene(tmp_path / "s", "bright", clean=6)
    ok("background", tmp_path / "s")
    scene = load_scene(tmp_path / "s")
    for name in ("cam0", "cam1"):
        assert scene.backgrounds[name].source == "clean-frames"
        assert scene.backgrounds[name].summary["clean_frames"] == [0, 6]
        assert psnr(read_plate(scene, name)[0], truth[name]) > 40
    truth = make_scene(tmp_path / "c", "bright", cover=("cam1",))
    ok("background", tmp_path / "c", "--color", "0.1,0.2,0.3")
    scene = load_scene(tmp_path / "c")
    assert scene.backgrounds["cam1"].source == "color"
    assert scene.backgrounds["cam1"].summary["color"] == pytest.approx([0.1, 0.2, 0.3])
    is_color = np.abs(read_plate(scene, "cam1")[0] - [0.1, 0.2, 0.3]).max(axis=2) < 1e-4
    assert is_color.mean() > 0.95  # never seen clear: the colour (bar a few pixels that look still by chance)
    # the textured backdrop of cam0 never shows that colour: all of it is kept as seen static content
    assert scene.backgrounds["cam0"].source == "color" and scene.backgrounds["cam0"].summary["object_fraction"] > 0.9
    plate, conf = read_plate(scene, "cam0")
    assert psnr(plate[conf >= 0.5], truth["cam0"][conf >= 0.5]) > CLI_PSNR  # elsewhere the colour, flagged unsure


def test_ground_truth_is_never_read(tmp_path):
    make_scene(tmp_path / "a")
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    (tmp_path / "b/videos/gt.mp4").write_bytes(b"garbage, not a video" * 50)
    ok("background", tmp_path / "a")
    ok("background", tmp_path / "b")
    for name in ("cam0.png", "cam0.confidence.png", "cam1.png", "cam1.confidence.png"):
        assert (tmp_path / "a/backgrounds" / name).read_bytes() == (tmp_path / "b/backgrounds" / name).read_bytes()


def test_existing_plates_need_overwrite(tmp_path):
    make_scene(tmp_path / "s")
    ok("background", tmp_path / "s")
    assert_clean_failure(invoke("background", tmp_path / "s"), "--overwrite")
    ok("background", tmp_path / "s", "--overwrite", "--plate", f"cam1={tmp_path / 's/backgrounds/cam0.png'}")
    assert load_scene(tmp_path / "s").backgrounds["cam1"].source == "plate"


def test_bad_plates(tmp_path):
    root = tmp_path / "s"
    make_scene(root)
    before = (root / "scene.json").read_bytes()
    cv2.imwrite(str(tmp_path / "small.png"), np.zeros((HEIGHT // 2, WIDTH, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "good.png"), np.zeros((HEIGHT, WIDTH, 3), np.uint8))
    assert_clean_failure(invoke("background", root, "--plate", f"cam0={tmp_path / 'small.png'}"),
                         "small.png", "--plate", f"{WIDTH}x{HEIGHT // 2}", f"{WIDTH}x{HEIGHT}")
    assert_clean_failure(invoke("background", root, "--plate", f"cam7={tmp_path / 'good.png'}"),
                         "--plate", "cam7", "unknown view")
    assert_clean_failure(invoke("background", root, "--plate", f"gt={tmp_path / 'good.png'}"), "'gt'")
    assert_clean_failure(invoke("background", root, "--color", "1,1"), "--color")
    assert_nothing_written(root, before)


def test_view_never_clear_is_refused(tmp_path):
    root = tmp_path / "s"
    make_scene(root, "bright", cover=("cam1",))
    before = (root / "scene.json").read_bytes()
    assert_clean_failure(invoke("background", root), "cam1", "never leaves any pixel", "--plate cam1=", "--color")
    assert_nothing_written(root, before)
    ok("background", root, "--color", "0.95,0.95,0.92")  # what the message asks for resolves it
    assert load_scene(root).backgrounds["cam1"].source == "color"


def test_loader_checks_the_record(tmp_path):
    root = tmp_path / "s"
    make_scene(root)
    ok("background", root)
    data = json.loads((root / "scene.json").read_text())
    cv2.imwrite(str(root / "backgrounds/cam0.png"), np.zeros((HEIGHT, WIDTH + 2, 3), np.uint8))
    with pytest.raises(InputError, match="cam0.png.*backgrounds.views.cam0.plate.*is 66x48"):
        load_scene(root)
    data["backgrounds"]["views"]["cam9"] = data["backgrounds"]["views"].pop("cam1")
    (root / "scene.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match="backgrounds.views.cam9: a plate for unknown view 'cam9'"):
        load_scene(root, check_videos=False)
