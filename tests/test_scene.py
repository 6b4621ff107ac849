import json

import numpy as np
import pytest

from fluidnexus.camera import Camera
from fluidnexus.errors import InputError
from fluidnexus.scene import (FORMAT, GroundTruth, Scene, Source, View, Volume, load_ground_truth, load_scene,
                              save_scene)


def cam(width=16, height=12, x=0.0):
    return Camera.look_at(width, height, 20.0, [x, 0.3, 1.5], [0, 0.3, 0])


@pytest.fixture
def scene_dir(tmp_path, make_video):
    (tmp_path / "videos").mkdir()
    (tmp_path / "gt").mkdir()
    make_video(tmp_path / "videos" / "a.mp4")
    make_video(tmp_path / "gt" / "b.mp4")
    scene = Scene(tmp_path, 30.0, 4, (View("a", "input", cam(), "videos/a.mp4"), View("b", "novel", cam(x=0.5))),
                  Volume((-0.2, 0, -0.2), (0.2, 0.6, 0.2)), Source((0, 0, 0), 0.03))
    save_scene(scene, (GroundTruth("b", cam(x=0.5), "gt/b.mp4"),))
    return tmp_path


def edit(scene_dir, change):
    path = scene_dir / "scene.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def test_round_trip(scene_dir):
    scene = load_scene(scene_dir)
    assert scene.fps == 30 and scene.frame_count == 4
    assert scene.view_names() == ["a", "b"]
    assert [v.name for v in scene.usable_views()] == ["a"]
    assert [v.name for v in scene.with_role("novel")] == ["b"]
    np.testing.assert_allclose(scene.view("b").camera.w2c, cam(x=0.5).w2c)
    assert scene.volume.max == (0.2, 0.6, 0.2) and scene.source.radius == 0.03
    assert json.loads((scene_dir / "scene.json").read_text())["format"] == FORMAT


def test_pipeline_loader_does_not_expose_ground_truth(scene_dir):
    scene = load_scene(scene_dir)
    assert not any(name.startswith("ground") or "truth" in name for name in vars(scene))
    assert "gt/b.mp4" not in repr(scene)
    gts = load_ground_truth(scene_dir)
    assert [g.name for g in gts] == ["b"] and gts[0].video == "gt/b.mp4"


@pytest.mark.parametrize("change, field", [
    (lambda d: d.__setitem__("format", "fluidnexus-scene/9"), "format"),
    (lambda d: d.__setitem__("fps", -1), "fps"),
    (lambda d: d.__setitem__("frame_count", 2.5), "frame_count"),
    (lambda d: d["views"][1].__setitem__("role", "ground_truth"), "views[1].role"),
    (lambda d: d["views"][1].__setitem__("name", "a"), "views[1].name"),
    (lambda d: d["views"][0]["camera"]["K"][1].__setitem__(1, float("inf")), "views[0].camera.K"),
    (lambda d: d["volume"].__setitem__("max", [0.2, -1, 0.2]), "volume"),
    (lambda d: d.__setitem__("views", []), "views"),
    (lambda d: d.__setitem__("source_height", "high"), "source_height"),
    (lambda d: d.__setitem__("source_height", True), "source_height"),
    (lambda d: d.__setitem__("source_height", 0.9), "source_height"),  # the raised plane misses the volume
    (lambda d: d.__setitem__("floor", {"point": [0, 2, 0]}), "floor"),  # a plume on it would start above the box
])
def test_bad_scene_json_names_the_field(scene_dir, change, field):
    edit(scene_dir, change)
    with pytest.raises(InputError) as err:
        load_scene(scene_dir)
    assert err.value.path.endswith("scene.json")
    assert err.value.field == field


def test_not_json(scene_dir):
    (scene_dir / "scene.json").write_text("{nope")
    with pytest.raises(InputError, match="not valid JSON"):
        load_scene(scene_dir)


def test_missing_scene(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_scene(tmp_path)


def test_frame_count_mismatch_names_the_video(scene_dir, make_video):
    make_video(scene_dir / "videos" / "a.mp4", frames=3)
    with pytest.raises(InputError) as err:
        load_scene(scene_dir)
    assert err.value.path.endswith("a.mp4") and err.value.field == "frame_count"


def test_resolution_mismatch_with_camera(scene_dir, make_video):
    make_video(scene_dir / "videos" / "a.mp4", width=20)
    with pytest.raises(InputError) as err:
        load_scene(scene_dir)
    assert err.value.field == "resolution" and "16x12" in str(err.value)


def test_views_with_different_resolutions(scene_dir, make_video):
    make_video(scene_dir / "videos" / "c.mp4", width=20, height=14)
    edit(scene_dir, lambda d: d["views"].append(
        {"name": "c", "role": "input", "camera": cam(20, 14).to_dict(), "video": "videos/c.mp4"}))
    with pytest.raises(InputError, match="share one resolution"):
        load_scene(scene_dir)


def test_missing_video(scene_dir):
    (scene_dir / "videos" / "a.mp4").unlink()
    with pytest.raises(InputError) as err:
        load_scene(scene_dir)
    assert err.value.path.endswith("a.mp4") and "views[0].video" in str(err.value)


def test_ground_truth_checked_by_its_loader(scene_dir, make_video):
    make_video(scene_dir / "gt" / "b.mp4", frames=2)
    load_scene(scene_dir)  # the pipeline never looks at it
    with pytest.raises(InputError, match="frame_count"):
        load_ground_truth(scene_dir)


def test_save_views_keeps_ground_truth(scene_dir, make_video):
    from dataclasses import replace

    from fluidnexus.scene import save_views

    scene = load_scene(scene_dir)
    make_video(scene_dir / "videos" / "b.mp4")
    novel = replace(scene.view("b"), video="videos/b.mp4", provenance={"method": "test"})
    save_views(scene_dir, (scene.view("a"), novel))
    again = load_scene(scene_dir)
    assert [v.name for v in again.usable_views()] == ["a", "b"]
    assert again.view("b").provenance == {"method": "test"}
    assert [g.name for g in load_ground_truth(scene_dir)] == ["b"]


def test_a_floor_below_the_volume_and_a_source_height_above_it(scene_dir):
    """A room's floor may lie below the volume (the static layer lays the ground there); the plume leaves from the
    plane ``source_height`` above it, which must cross the volume."""
    edit(scene_dir, lambda d: d.update(floor={"point": [0, -0.5, 0]}, source_height=0.6))
    scene = load_scene(scene_dir)
    assert scene.ground().point == (0.0, -0.5, 0.0)
    np.testing.assert_allclose(scene.source_plane().point, (0.0, 0.1, 0.0))
    save_scene(scene)
    assert load_scene(scene_dir).source_height == 0.6
