"""The source frame of an imported scene (fluidnexus/world_frame.py) and ``export --frame source|scene``:
a z-up scene in its own unit goes in, exports come back in the file's coordinates."""
import numpy as np
import pytest

from clirun import ok
from fluidnexus.camera import Camera
from fluidnexus.errors import InputError
from fluidnexus.export.npz import read_frame_npz
from fluidnexus.export.ply import read_gaussians_ply
from fluidnexus.export.vti import read_vti
from fluidnexus.state import FrameState
from fluidnexus.world_frame import SourceFrame

from calibrate.pinf_capture import source_box, write_capture
from handmade_run import write_run

Z_TO_Y = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])


def quat_matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_z_up_frame_maps_z_to_y_and_scales():
    frame = SourceFrame.for_import("Z", 0.5)
    np.testing.assert_array_equal(frame.to_scene([[0.0, 0.0, 2.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]),
                                  [[0, 1, 0], [1, 0, 0], [0, 0, -1]])
    p = np.random.default_rng(0).normal(size=(20, 3))
    np.testing.assert_allclose(frame.from_scene(frame.to_scene(p)), p, atol=1e-15)
    assert frame.length_to_scene(3.0) == 1.5 and frame.length_from_scene(1.5) == 3.0
    assert frame.density_from_scene(8.0) == 1.0  # 8 per m^3 = 1 per (0.5 m)^3
    with pytest.raises(InputError, match="rot"):
        SourceFrame.for_import("X")
    with pytest.raises(InputError, match="metres_per_unit"):
        SourceFrame.for_import("Y", 0.0)
    assert SourceFrame.identity().is_identity and not frame.is_identity


def test_cameras_see_the_same_image_in_both_frames():
    frame = SourceFrame.for_import("Z", 0.1)
    cam = Camera.look_at(64, 48, 50.0, [3.0, -20.0, 8.0], [0.0, 0.0, 2.0], up=(0, 0, 1))
    scene_cam = frame.camera_to_scene(cam)
    pts = np.random.default_rng(1).uniform(-3, 3, size=(10, 3))
    uv, depth = cam.project(pts)
    uv2, depth2 = scene_cam.project(frame.to_scene(pts))
    np.testing.assert_allclose(uv2, uv, atol=1e-9)
    np.testing.assert_allclose(depth2, 0.1 * depth, atol=1e-12)  # camera space is in metres too
    np.testing.assert_allclose(scene_cam.center, frame.to_scene(cam.center), atol=1e-12)
    assert -scene_cam.R[1][1] > 0.9  # the file's up (+z) is the scene's up (+y)
    np.testing.assert_allclose(frame.camera_from_scene(scene_cam).w2c, cam.w2c, atol=1e-12)


def test_quaternions_rotate_into_the_source_frame():
    frame = SourceFrame.for_import("Z", 2.0)
    rng = np.random.default_rng(2)
    q = rng.normal(size=(6, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    for a, b in zip(frame.quaternions_from_scene(q), q):
        np.testing.assert_allclose(quat_matrix(a), Z_TO_Y.T @ quat_matrix(b), atol=1e-12)
        assert np.linalg.norm(a) == pytest.approx(1.0)


def test_record_round_trip_and_bad_record():
    frame = SourceFrame.for_import("Z", 0.25)
    back = SourceFrame.from_dict(frame.to_dict(), "scene.json")
    np.testing.assert_array_equal(back.rotation, frame.rotation)
    assert back.metres_per_unit == 0.25
    for bad, needle in (({"rotation": np.eye(3).tolist()}, "source_frame"),
                        ({"rotation": (2 * np.eye(3)).tolist(), "metres_per_unit": 1}, "source_frame"),
                        ({"rotation": np.diag([1.0, 1.0, -1.0]).tolist(), "metres_per_unit": 1}, "rotation"),
                        ({"rotation": np.eye(3).tolist(), "metres_per_unit": -2}, "metres_per_unit")):
        with pytest.raises(InputError, match=needle) as err:
            SourceFrame.from_dict(bad, "scene.json")
        assert err.value.path == "scene.json"


@pytest.fixture(scope="module")
def z_up_run(tmp_path_factory):
    """A Sphere-shaped z-up capture imported at 0.5 m per unit, and a one-frame run of particles whose
    positions are known in the file's own coordinates: the 8 corners of PINF's box and points inside it."""
    tmp = tmp_path_factory.mktemp("zup")
    info = write_capture(tmp / "cap", frames=1)
    ok("calibrate", "--from-pinf", info, "--input", "train00,train01", "--metres-per-unit", "0.5",
       "--out", tmp / "S")
    lo, hi = source_box()
    rng = np.random.default_rng(3)
    corners = np.array([np.where(np.array(p, bool), hi, lo) for p in np.ndindex(2, 2, 2)])
    source_points = np.concatenate([corners, rng.uniform(lo, hi, size=(40, 3))])
    scene_points = 0.5 * source_points[:, [0, 2, 1]] * [1.0, 1.0, -1.0]  # the rule, spelled out: (x, z, -y) m
    n = len(scene_points)
    rotations = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))  # axis-aligned in the scene
    state = FrameState(0, scene_points.astype(np.float32), np.tile([0.0, 1.0, 0.0], (n, 1)).astype(np.float32),
                       scene_points.astype(np.float32), np.full((n, 1), 0.7, np.float32),
                       np.tile([0.1, 0.2, 0.3], (n, 1)).astype(np.float32), rotations.astype(np.float32),
                       np.full(n, 0.5, np.float32))
    run = write_run(tmp / "run", tmp / "S", [state], h=0.4, dt=0.04)
    return run, source_points


def test_export_ply_and_npz_in_the_source_frame(z_up_run, tmp_path, ti_engine):
    run, source_points = z_up_run
    ok("export", run, "--format", "ply", "--frame", "source", "--out", tmp_path / "ply")
    ok("export", run, "--format", "ply", "--out", tmp_path / "viewer")
    ok("export", run, "--format", "npz", "--frame", "source", "--voxel", "0.3", "--out", tmp_path / "npz",
       "--arch", "cpu")
    ply = read_gaussians_ply(tmp_path / "ply" / "000000.ply")
    np.testing.assert_allclose(ply["visual_positions"], source_points, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(ply["visual_scales"], np.tile([0.2, 0.4, 0.6], (len(source_points), 1)), rtol=1e-6)
    for q in ply["visual_rotations"]:  # the Gaussians' scene-up axis (body y) points along the file's up (+z)
        np.testing.assert_allclose(quat_matrix(q) @ [0, 1, 0], [0, 0, 1], atol=1e-6)
    viewer = read_gaussians_ply(tmp_path / "viewer" / "000000.ply")  # the default stays the scene frame
    np.testing.assert_allclose(viewer["visual_positions"],
                               0.5 * source_points[:, [0, 2, 1]] * [1, 1, -1], rtol=1e-6, atol=1e-6)
    npz = read_frame_npz(tmp_path / "npz" / "000000.npz")
    np.testing.assert_allclose(npz["physical_positions"], source_points, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(npz["physical_velocities"], np.tile([0, 0, 2.0], (len(source_points), 1)),
                               atol=1e-6)  # 1 m/s up is 2 units/s along +z
    lo, hi = source_box()
    np.testing.assert_allclose(npz["grid_origin"], lo, atol=1e-9)
    np.testing.assert_allclose(npz["grid_origin"] + npz["grid_spacing"] * (
        np.array(npz["grid_density"].shape[::-1]) - 1), hi, atol=1e-9)


def test_export_vti_in_the_source_frame_is_the_scene_grid_turned(z_up_run, tmp_path, ti_engine):
    run, _ = z_up_run
    ok("export", run, "--format", "vti", "--voxel", "0.3", "--out", tmp_path / "scene", "--arch", "cpu")
    ok("export", run, "--format", "vti", "--voxel", "0.3", "--frame", "source", "--out", tmp_path / "src",
       "--arch", "cpu")
    o_s, sp_s, scene = read_vti(tmp_path / "scene" / "000000.vti")
    o, sp, src = read_vti(tmp_path / "src" / "000000.vti")
    lo, _ = source_box()
    np.testing.assert_allclose(o, lo, atol=1e-6)
    np.testing.assert_allclose(sp, sp_s / 0.5, rtol=1e-6)
    # source node (i, j, k) is scene node (i, k, nj - 1 - j): the scene's arrays [z, y, x] = [-y_src, z_src, x_src]
    turned = scene["density"][::-1].transpose(1, 0, 2)
    assert src["density"].shape == turned.shape and turned.max() > 0
    np.testing.assert_allclose(src["density"], turned * 0.5 ** 3, rtol=1e-4, atol=1e-6 * turned.max())
    v = scene["velocity"][::-1].transpose(1, 0, 2, 3)
    np.testing.assert_allclose(src["velocity"], np.stack([v[..., 0], -v[..., 2], v[..., 1]], -1) / 0.5,
                               atol=1e-5)
