"""Single-video arc rig."""
import math

import numpy as np
import pytest
from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.calibrate.arc import arc_rig
from fluidnexus.errors import InputError
from fluidnexus.scene import load_scene


def test_arc_geometry():
    rig = arc_rig(270, 480, fov_deg=30.0, views=5, arc_deg=120.0, distance=1.2)
    cams = {"input": rig.input_camera, **rig.novel}
    assert sorted(rig.azimuths_deg.values()) == [-60, -30, 0, 30, 60]
    assert rig.azimuths_deg["input"] == 0
    fx = 0.5 * 270 / math.tan(math.radians(15))
    h = rig.input_camera.center[1]
    target = np.array([0.0, h, 0.0])
    for name, cam in cams.items():
        assert cam.K[0, 0] == pytest.approx(fx)
        c = cam.center
        assert math.hypot(c[0], c[2]) == pytest.approx(1.2)  # on the circle around the plume axis
        assert c[1] == pytest.approx(h)  # at the input camera's height
        uv, _ = cam.project(target[None])
        np.testing.assert_allclose(uv[0], [135, 240], atol=1e-9)  # all look at the same point
        azimuth = math.degrees(math.atan2(c[0], c[2]))
        assert azimuth == pytest.approx(rig.azimuths_deg[name])
    # the source (world origin, the foot of the axis) sits at 90 % of the input image's height, centred
    uv, depth = rig.input_camera.project(np.zeros((1, 3)))
    np.testing.assert_allclose(uv[0], [135, 0.9 * 480], atol=1e-9)
    assert depth[0] == pytest.approx(1.2)
    # the volume is what the input camera sees at the axis: its top corners project onto the image border
    top = np.array([[rig.volume.min[0], rig.volume.max[1], 0.0], [rig.volume.max[0], rig.volume.max[1], 0.0]])
    uv, _ = rig.input_camera.project(top)
    np.testing.assert_allclose(uv, [[0, 0], [270, 0]], atol=1e-9)


@pytest.mark.parametrize("kwargs, option", [({"fov_deg": 0.0}, "--fov-deg"), ({"views": 1}, "--views"),
                                             ({"distance": -1.0}, "--distance"),
                                             ({"arc_deg": float("nan")}, "--arc-deg")])
def test_impossible_rig(kwargs, option):
    args = dict(width=64, height=48, fov_deg=40.0) | kwargs
    with pytest.raises(InputError) as err:
        arc_rig(**args)
    assert err.value.field == option


def test_calibrate_video_cli(tmp_path, make_video):
    video = make_video(tmp_path / "phone.mp4", frames=6, width=24, height=32)
    out = tmp_path / "scene"
    result = CliRunner().invoke(main, ["calibrate", "--video", str(video), "--fov-deg", "50", "--rig", "arc",
                                       "--views", "5", "--arc-deg", "120", "--out", str(out)])
    assert result.exit_code == 0, result.output
    scene = load_scene(out)
    assert [v.name for v in scene.with_role("input")] == ["phone"]
    assert len(scene.with_role("novel")) == 4 and scene.frame_count == 6
    assert scene.source.center == (0.0, 0.0, 0.0)
    assert {v.provenance["azimuth_deg"] for v in scene.with_role("novel")} == {-60, -30, 30, 60}


def test_rig_on_a_floor_from_height_and_tilt():
    """--camera-height and --tilt-deg: the input camera pitched down by the tilt, its centre ray meeting the floor at
    the origin, the arc around it; the scene declares the floor y = 0 and no source."""
    h, tilt = 0.9, 25.0
    rig = arc_rig(96, 128, fov_deg=50.0, views=3, arc_deg=90.0, camera_height=h, tilt_deg=tilt)
    assert rig.source is None and rig.floor.point == (0.0, 0.0, 0.0) and rig.floor.normal == (0.0, 1.0, 0.0)
    d = h / math.tan(math.radians(tilt))
    for cam in (rig.input_camera, *rig.novel.values()):
        np.testing.assert_allclose([math.hypot(cam.center[0], cam.center[2]), cam.center[1]], [d, h], atol=1e-12)
        pitch = math.degrees(math.asin(-cam.forward[1]))
        assert pitch == pytest.approx(tilt)
        uv, _ = cam.project(np.zeros((1, 3)))  # the centre ray meets the floor at the origin
        np.testing.assert_allclose(uv[0], [48, 64], atol=1e-9)
    # the horizon row says the same tilt: tan(tilt) = (H / 2 - row) / fy
    fy = rig.input_camera.K[1, 1]
    row = 64 - fy * math.tan(math.radians(tilt))
    by_row = arc_rig(96, 128, fov_deg=50.0, views=3, arc_deg=90.0, camera_height=h, horizon_row=row)
    np.testing.assert_allclose(by_row.input_camera.w2c, rig.input_camera.w2c, atol=1e-12)
    # the volume stands on the floor and holds what the image's bottom edge sees of it
    assert rig.volume.min[1] == 0.0
    bottom = rig.input_camera.unproject(np.array([[48.0, 128.0]]), 1.0)[0] - rig.input_camera.center
    hit = rig.floor.hit(rig.input_camera.center, bottom)
    assert np.all(hit >= np.asarray(rig.volume.min) - 1e-9) and np.all(hit <= np.asarray(rig.volume.max) + 1e-9)


@pytest.mark.parametrize("extra, needles", [
    (["--camera-height", "1", "--tilt-deg", "0"], ["--tilt-deg", "never meets the floor"]),
    (["--camera-height", "1", "--tilt-deg", "-10"], ["--tilt-deg", "never meets the floor"]),
    (["--camera-height", "1", "--horizon-row", "20"], ["--horizon-row", "never meets the floor"]),
    (["--camera-height", "1", "--tilt-deg", "90"], ["--tilt-deg", "straight down"]),
    (["--camera-height", "-1", "--tilt-deg", "20"], ["--camera-height", "impossible value"]),
    (["--camera-height", "1", "--tilt-deg", "20", "--horizon-row", "3"], ["--horizon-row", "not both"]),
    (["--tilt-deg", "20"], ["--camera-height", "required"]),
    (["--camera-height", "1", "--tilt-deg", "20", "--distance", "2"], ["--distance", "follows from"]),
])
def test_floor_rig_bad_input(tmp_path, make_video, extra, needles):
    from clirun import assert_clean_failure, invoke

    video = make_video(tmp_path / "phone.mp4", frames=3, width=24, height=32)
    out = tmp_path / "scene"
    assert_clean_failure(invoke("calibrate", "--video", video, "--fov-deg", "50", *extra, "--out", out), *needles)
    assert not out.exists()


def test_calibrate_video_on_a_floor_cli(tmp_path, make_video):
    video = make_video(tmp_path / "phone.mp4", frames=3, width=24, height=32)
    out = tmp_path / "scene"
    result = CliRunner().invoke(main, ["calibrate", "--video", str(video), "--fov-deg", "50", "--camera-height", "1.5",
                                       "--tilt-deg", "30", "--out", str(out)])
    assert result.exit_code == 0, result.output
    scene = load_scene(out)
    assert scene.source is None and scene.floor is not None and scene.ground() == scene.floor
    rig = scene.extra["rig"]
    assert rig["tilt_deg"] == 30 and rig["camera_height"] == 1.5
    assert rig["distance"] == pytest.approx(1.5 / math.tan(math.radians(30)))


def test_tilt_applies_to_a_video_only(tmp_path):
    from clirun import assert_clean_failure, invoke

    assert_clean_failure(invoke("calibrate", "--sample", "scalarflow", "--tilt-deg", "20", "--out", tmp_path / "s"),
                         "--tilt-deg", "--video only")
