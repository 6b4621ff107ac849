import math

import numpy as np
import pytest

from fluidnexus.camera import GL_TO_CV, Camera
from fluidnexus.errors import InputError


def random_camera(rng, width=64, height=48):
    eye = rng.normal(size=3) * 2 + np.array([0, 0, 3.0])
    target = rng.normal(size=3) * 0.1
    cam = Camera.look_at(width, height, 50.0 + 10 * rng.random(), eye, target)
    K = cam.K.copy()
    K[1, 1] *= 1.1  # non-square pixels
    K[0, 2] += 1.5  # off-centre principal point
    return Camera(width, height, K, cam.w2c)


def test_project_unproject_round_trip():
    rng = np.random.default_rng(0)
    cam = random_camera(rng)
    pts = rng.normal(size=(20, 3)) * 0.3
    uv, depth = cam.project(pts)
    assert np.all(depth > 0)
    np.testing.assert_allclose(cam.unproject(uv, depth), pts, atol=1e-12)


def test_project_matches_opencv_formula():
    rng = np.random.default_rng(1)
    cam = random_camera(rng)
    X = np.array([0.1, -0.2, 0.05])
    x = cam.K @ (cam.R @ X + cam.t)
    uv, depth = cam.project(X[None])
    np.testing.assert_allclose(uv[0], x[:2] / x[2])
    assert depth[0] == pytest.approx((cam.R @ X + cam.t)[2])


def test_look_at_centres_target_and_keeps_world_up_up():
    cam = Camera.look_at(100, 80, 90.0, eye=[0, 1, 5], target=[0, 1, 0])
    uv, _ = cam.project(np.array([[0, 1, 0], [0, 1.5, 0], [0.5, 1, 0]]))
    np.testing.assert_allclose(uv[0], [50, 40])
    assert uv[1, 1] < uv[0, 1]  # higher in the world -> smaller v (image y points down)
    assert uv[2, 0] > uv[0, 0]  # +x is to the right for a camera looking down -z
    np.testing.assert_allclose(cam.center, [0, 1, 5], atol=1e-12)
    np.testing.assert_allclose(cam.forward, [0, 0, -1], atol=1e-12)


@pytest.mark.parametrize("factor", [0.25, 0.5, 2.0])
def test_scaled_maps_pixel_corners_exactly(factor):
    cam = random_camera(np.random.default_rng(2), 64, 48)
    small = cam.scaled(factor)
    assert (small.width, small.height) == (round(64 * factor), round(48 * factor))
    pts = np.random.default_rng(3).normal(size=(10, 3)) * 0.2
    uv, _ = cam.project(pts)
    uv_s, _ = small.project(pts)
    np.testing.assert_allclose(uv_s, uv * factor, atol=1e-9)
    np.testing.assert_array_equal(small.w2c, cam.w2c)


def test_resized_scales_each_axis():
    cam = Camera.look_at(100, 50, 80.0, [0, 0, 3], [0, 0, 0])
    r = cam.resized(50, 100)
    np.testing.assert_allclose(r.K, [[40, 0, 25], [0, 160, 50], [0, 0, 1]])


def test_nerf_round_trip_is_exact():
    rng = np.random.default_rng(4)
    cam = random_camera(rng)
    nerf = cam.to_nerf()
    back = Camera.from_nerf(nerf["transform_matrix"], nerf["w"], nerf["h"], nerf["camera_angle_x"],
                            nerf["fl_x"], nerf["fl_y"], nerf["cx"], nerf["cy"])
    np.testing.assert_allclose(back.K, cam.K, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.w2c, cam.w2c, rtol=0, atol=1e-12)


def test_nerf_axes_and_fov():
    # an OpenGL camera at (0, 0, 2) with identity rotation looks down -z at the origin
    c2w = np.eye(4)
    c2w[2, 3] = 2.0
    cam = Camera.from_nerf(c2w, 200, 100, camera_angle_x=math.radians(90))
    assert cam.K[0, 0] == pytest.approx(100.0)
    np.testing.assert_allclose(cam.K[:2, 2], [100, 50])
    uv, depth = cam.project(np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]]))
    np.testing.assert_allclose(uv[0], [100, 50])
    assert depth[0] == pytest.approx(2.0)
    assert uv[1, 1] < 50  # +y (up) appears above the centre
    np.testing.assert_allclose(cam.c2w, c2w @ GL_TO_CV, atol=1e-15)


def test_pycolmap_round_trip_is_exact():
    cam = random_camera(np.random.default_rng(5))
    pc_cam, pose = cam.to_pycolmap(camera_id=3)
    assert pc_cam.model.name == "PINHOLE" and pc_cam.camera_id == 3
    back = Camera.from_pycolmap(pc_cam, pose)
    np.testing.assert_allclose(back.K, cam.K, atol=1e-12)
    np.testing.assert_allclose(back.w2c, cam.w2c, atol=1e-12)
    # pycolmap projects like we do
    X = np.array([0.05, 0.1, -0.1])
    uv, _ = cam.project(X[None])
    np.testing.assert_allclose(pc_cam.img_from_cam(pose * X), uv[0], atol=1e-9)


def test_pycolmap_distortion_is_refused():
    import pycolmap

    cam = pycolmap.Camera(model="SIMPLE_RADIAL", width=10, height=8, params=[5, 5, 4, 0.1])
    with pytest.raises(InputError, match="distortion"):
        Camera.from_pycolmap(cam, pycolmap.Rigid3d())


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d["K"][0].__setitem__(0, float("nan")), "K"),
    (lambda d: d["K"][0].__setitem__(0, -5.0), "K"),
    (lambda d: d["world_to_camera"][0].__setitem__(0, 2.0), "world_to_camera"),
    (lambda d: d.pop("K"), "K"),
    (lambda d: d.__setitem__("width", 0), "width"),
])
def test_bad_camera_fields_name_file_and_field(mutate, field):
    d = Camera.look_at(10, 10, 5.0, [0, 0, 1], [0, 0, 0]).to_dict()
    mutate(d)
    with pytest.raises(InputError) as err:
        Camera.from_dict(d, "scene.json", "views[1].camera")
    assert err.value.path == "scene.json"
    assert err.value.field.startswith("views[1].camera") and field in str(err.value)


def test_mirror_rotation_is_not_a_rotation():
    d = Camera.look_at(10, 10, 5.0, [0, 0, 1], [0, 0, 0]).to_dict()
    d["world_to_camera"][0] = [-x for x in d["world_to_camera"][0][:3]] + [d["world_to_camera"][0][3]]
    with pytest.raises(InputError, match="not a rotation"):
        Camera.from_dict(d)
