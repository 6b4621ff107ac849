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
                                             ({"distance": -1.0}, "--distance"), ({"arc_deg": float("nan")}, "--arc-deg")])
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
