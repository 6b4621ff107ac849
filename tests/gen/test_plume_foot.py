"""Where the plume stands from one view (fluidnexus/gen/plume_foot.py): the foot of the earliest smoke cast onto the
floor, the fallback for a camera at the floor's height, and the refusals. The footage is a column of smoke drawn
by projecting points (numpy), off-centre in its box."""
from pathlib import Path

import numpy as np
import pytest

from fluidnexus.camera import Camera
from fluidnexus.errors import InputError
from fluidnexus.gen.plume_foot import MIN_GRAZING_DEG, plume_foot
from fluidnexus.scene import Floor, Scene, View, Volume

VOLUME = Volume((-0.5, 0.0, -0.5), (0.5, 1.0, 0.5))
FOOT = np.array([0.22, 0.0, -0.17])  # off the box's centre (0, 0, 0)
RADIUS = 0.03
W, H = 160, 120


def column(foot, radius: float, bottom: float, top: float, n: int = 4000, seed: int = 0) -> np.ndarray:
    """[n, 3] points filling an upright cylinder of smoke over ``foot``."""
    rng = np.random.default_rng(seed)
    r, a = radius * np.sqrt(rng.uniform(size=n)), rng.uniform(0, 2 * np.pi, n)
    y = rng.uniform(bottom, top, n)
    return np.stack([foot[0] + r * np.cos(a), y, foot[2] + r * np.sin(a)], axis=1)


def footage(camera: Camera, points: np.ndarray, frames: int = 3) -> np.ndarray:
    """[frames, H, W, 1]: frame 0 empty, the smoke from frame 1 on (each point lights its pixel)."""
    video = np.zeros((frames, camera.height, camera.width, 1), np.float32)
    uv, depth = camera.project(points)
    ok = (depth > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < camera.width) & (uv[:, 1] >= 0) & (uv[:, 1] < camera.height)
    cols, rows = uv[ok, 0].astype(int), uv[ok, 1].astype(int)
    video[1:, rows, cols, 0] = 0.8
    return video


def scene_for(camera: Camera, floor: Floor | None = None) -> Scene:
    return Scene(Path("/nonexistent"), 30.0, 3, (View("cam", "input", camera, "videos/cam.mp4"),), VOLUME,
                 floor=floor)


def find(camera: Camera, points: np.ndarray, floor: Floor | None = None):
    return plume_foot(scene_for(camera, floor), "cam", camera, footage(camera, points), None, Path("cam.mp4"))


def test_an_elevated_camera_finds_the_foot_on_the_floor():
    camera = Camera.look_at(W, H, 150.0, eye=(0.3, 0.7, 1.6), target=(0.1, 0.2, 0.0))
    found = find(camera, column(FOOT, RADIUS, 0.0, 0.25))
    assert found.record["frame"] == 1 and found.record["grazing_deg"] > MIN_GRAZING_DEG
    assert "cast onto the floor" in found.record["method"]
    np.testing.assert_allclose(found.source.center, FOOT, atol=0.02)  # 2 % of the box
    assert found.source.radius == pytest.approx(RADIUS, rel=0.5)


def test_a_declared_floor_is_the_one_cast_onto():
    camera = Camera.look_at(W, H, 150.0, eye=(0.3, 0.9, 1.6), target=(0.1, 0.4, 0.0))
    raised = np.array([FOOT[0], 0.2, FOOT[2]])
    found = find(camera, column(raised, RADIUS, 0.2, 0.45), Floor((0.0, 0.2, 0.0)))
    np.testing.assert_allclose(found.source.center, raised, atol=0.02)
    assert found.record["floor_declared"]


def test_a_camera_at_the_floors_height_takes_the_box_centre_plane_and_says_so():
    camera = Camera.look_at(W, H, 150.0, eye=(0.0, 0.02, 1.6), target=(0.0, 0.3, 0.0))
    found = find(camera, column(np.array([0.1, 0.0, 0.0]), RADIUS, 0.0, 0.3))
    assert found.record["grazing_deg"] < MIN_GRAZING_DEG and "does not fix the depth" in found.record["method"]
    assert abs(found.source.center[2]) < 0.02  # on the upright plane through the box's centre, facing the camera
    assert found.source.center[0] == pytest.approx(0.1, abs=0.02)


def test_no_smoke_is_refused_naming_the_video():
    camera = Camera.look_at(W, H, 150.0, eye=(0.3, 0.7, 1.6), target=(0.1, 0.2, 0.0))
    with pytest.raises(InputError, match="shows no smoke") as err:
        plume_foot(scene_for(camera), "cam", camera, np.zeros((3, H, W, 1), np.float32), None, Path("cam.mp4"))
    assert err.value.path == "cam.mp4"


def test_a_foot_ray_that_misses_the_floor_or_meets_it_outside_the_volume_is_refused():
    floating = column(np.array([0.0, 0.0, 0.0]), RADIUS, 0.5, 0.8)
    upward = Camera.look_at(W, H, 150.0, eye=(0.0, 0.05, 1.5), target=(0.0, 0.6, 0.0))
    with pytest.raises(InputError, match="misses the floor"):
        find(upward, floating)
    downward = Camera.look_at(W, H, 150.0, eye=(0.0, 1.0, 1.5), target=(0.0, 0.6, 0.0))
    with pytest.raises(InputError, match="outside the volume"):
        find(downward, floating)


def test_a_floor_record_is_checked_and_its_normal_made_unit():
    with pytest.raises(InputError, match="zero length"):
        Floor.from_dict({"point": [0.0, 0.0, 0.0], "normal": [0, 0, 0]}, "scene.json")
    assert Floor.from_dict({"point": [0.0, 0.5, 0.0], "normal": [0, 2, 0]}, "scene.json").normal == (0, 1, 0)


def test_a_stated_source_height_is_the_plane_cast_onto_and_the_floor_stays():
    camera = Camera.look_at(W, H, 150.0, eye=(0.3, 0.9, 1.6), target=(0.1, 0.4, 0.0))
    raised = np.array([FOOT[0], 0.2, FOOT[2]])
    scene = Scene(Path("/nonexistent"), 30.0, 3, (View("cam", "input", camera, "videos/cam.mp4"),), VOLUME,
                  source_height=0.2)
    found = plume_foot(scene, "cam", camera, footage(camera, column(raised, RADIUS, 0.2, 0.45)), None,
                       Path("cam.mp4"))
    np.testing.assert_allclose(found.source.center, raised, atol=0.02)
    assert "the plane 0.2 above the floor" in found.record["method"] and found.record["source_height"] == 0.2
    np.testing.assert_allclose(scene.ground().point, VOLUME.bottom_center)  # the static layer's floor stays


def puff_footage(camera: Camera, nozzle: np.ndarray, frames: int = 6) -> np.ndarray:
    """[frames, H, W, 1]: frame 0 empty, then a column of smoke hanging from ``nozzle`` that grows downward."""
    video = np.zeros((frames, camera.height, camera.width, 1), np.float32)
    for t in range(1, frames):
        video[t:t + 1] = footage(camera, column(nozzle, RADIUS, nozzle[1] - 0.06 * t, nozzle[1], seed=t), 2)[1:]
    return video


@pytest.mark.parametrize("eye", [(0.3, 0.2, 1.6), (0.3, 1.3, 1.6)], ids=["below-the-nozzle", "above-it"])
def test_a_puff_from_a_nozzle_above_is_cast_from_its_top(eye):
    # a downward puff: its foot moves away from the nozzle, so the end cast onto the nozzle's stated plane is its
    # top, seen from below the plane (a level camera under a ceiling nozzle) and from above it
    nozzle = np.array([FOOT[0], 0.8, FOOT[2]])
    camera = Camera.look_at(W, H, 150.0, eye=eye, target=(0.1, 0.6, 0.0))
    scene = Scene(Path("/nonexistent"), 30.0, 3, (View("cam", "input", camera, "videos/cam.mp4"),), VOLUME,
                  source_height=0.8)
    found = plume_foot(scene, "cam", camera, puff_footage(camera, nozzle), None, Path("cam.mp4"))
    assert found.record["end"] == "top" and "top of the earliest smoke" in found.record["method"]
    np.testing.assert_allclose(found.source.center, nozzle, atol=0.02)  # 2 % of the box
    assert found.source.radius == pytest.approx(RADIUS, rel=0.5)


def test_a_column_that_grows_upward_keeps_its_foot():
    camera = Camera.look_at(W, H, 150.0, eye=(0.3, 0.7, 1.6), target=(0.1, 0.2, 0.0))
    video = np.zeros((6, H, W, 1), np.float32)
    for t in range(1, 6):
        video[t:t + 1] = footage(camera, column(FOOT, RADIUS, 0.0, 0.06 * t, seed=t), 2)[1:]
    found = plume_foot(scene_for(camera), "cam", camera, video, None, Path("cam.mp4"))
    assert found.record["end"] == "foot"
    np.testing.assert_allclose(found.source.center, FOOT, atol=0.02)


def jet_footage(camera: Camera, nozzle: np.ndarray, direction: np.ndarray, frames: int = 6) -> np.ndarray:
    """[frames, H, W, 1]: frame 0 empty, then a horizontal cylinder of smoke that grows from ``nozzle`` along the
    unit ``direction`` (a sideways jet; its nozzle's disk faces ``direction``, centred on ``nozzle``)."""
    video = np.zeros((frames, camera.height, camera.width, 1), np.float32)
    side = np.cross(direction, (0.0, 1.0, 0.0))
    for t in range(1, frames):
        rng = np.random.default_rng(t)
        r, a = RADIUS * np.sqrt(rng.uniform(size=4000)), rng.uniform(0, 2 * np.pi, 4000)
        s = rng.uniform(0.0, 0.06 * t, 4000)
        points = nozzle + s[:, None] * direction + (r * np.cos(a))[:, None] * side + (r * np.sin(a))[:, None] * \
            np.array([0.0, 1.0, 0.0])
        video[t:t + 1] = footage(camera, points, 2)[1:]
    return video


@pytest.mark.parametrize("direction", [(1.0, 0.0, 0.0), (-0.8, 0.0, 0.6)], ids=["right", "left-and-towards"])
def test_a_sideways_jet_is_cast_from_the_middle_of_its_trailing_side(direction):
    # a jet leaves its nozzle sideways: the end it leaves from is the side it moves away from, and the middle of
    # that side (not its lowest smoke, a radius under the nozzle's plane) meets the nozzle's stated plane
    nozzle = np.array([-0.1, 0.4, -0.1])
    direction = np.asarray(direction) / np.linalg.norm(direction)
    camera = Camera.look_at(W, H, 150.0, eye=(0.3, 1.2, 1.6), target=(0.0, 0.4, 0.0))
    scene = Scene(Path("/nonexistent"), 30.0, 3, (View("cam", "input", camera, "videos/cam.mp4"),), VOLUME,
                  source_height=0.4)
    found = plume_foot(scene, "cam", camera, jet_footage(camera, nozzle, direction), None, Path("cam.mp4"))
    assert found.record["end"] == "side" and "side of the earliest smoke" in found.record["method"]
    np.testing.assert_allclose(found.source.center, nozzle, atol=0.02)  # 2 % of the box
    assert found.source.radius == pytest.approx(RADIUS, rel=0.5)
