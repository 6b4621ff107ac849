"""A phone video calibrated with the camera's height and tilt (no source, no arc distance): synth finds the plume's
foot on the floor where it stands (tests/gen/floor_plume.py)."""
import numpy as np
import pytest

from clirun import ok
from gen.floor_plume import FOOT, FOV_DEG, HEIGHT, TILT_DEG, camera_rays, render
from fluidnexus.scene import load_scene
from fluidnexus.video import write_video

FOOT_TOLERANCE_M = 0.03  # one image row at the foot covers 2.5 cm of floor along the view (1.2 m away, 28 degrees)


@pytest.fixture(scope="module")
def floor_scene(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("floor")
    video = write_video(tmp / "phone.mp4", render(*camera_rays()), 24.0, crf=0)
    scene = tmp / "scene"
    ok("calibrate", "--video", video, "--fov-deg", FOV_DEG, "--camera-height", HEIGHT, "--tilt-deg", TILT_DEG,
       "--views", 3, "--arc-deg", 90, "--out", scene)
    ok("synth", scene)
    return scene


def test_synth_finds_the_foot_on_the_floor_of_a_tilted_phone(floor_scene):
    scene = load_scene(floor_scene)
    assert scene.source is None and scene.floor is not None
    foot = scene.with_role("novel")[0].provenance["synth"]["plume_foot"]
    assert "cast onto the floor" in foot["method"], foot
    error = float(np.linalg.norm(np.subtract(foot["center"], FOOT)))
    assert error < FOOT_TOLERANCE_M, (error, foot)

