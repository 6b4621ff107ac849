"""The viewer's arrays (no browser, no viser): splat covariances, quaternions, frusta, speed colours, shapes."""
import numpy as np

from fluidnexus.camera import Camera
from fluidnexus.viewer.content import (SPEED_STOPS, box_segments, disk_mesh, frustum_pose, gaussian_splats,
                                       matrix_to_quat, quat_to_matrix, speed_colors)


def random_quats(n, seed=0):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_quaternions_round_trip_through_matrices():
    q = random_quats(200)
    R = quat_to_matrix(q)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    back = np.array([matrix_to_quat(r) for r in R])
    np.testing.assert_allclose(back, q * np.sign(q[:, :1]), atol=1e-9)


def test_covariance_is_the_rotated_scales_squared():
    half = np.sqrt(0.5)
    q = np.array([[half, 0.0, 0.0, half]])  # 90 degrees about z: body x -> world y
    s = gaussian_splats(np.zeros((1, 3)), np.array([[0.4]]), np.array([[0.1, 0.2, 0.3]]), q, np.array([0.7]))
    np.testing.assert_allclose(s.covariances[0], np.diag([0.04, 0.01, 0.09]), atol=1e-7)
    np.testing.assert_allclose(s.rgbs, [[0.4, 0.4, 0.4]])
    np.testing.assert_allclose(s.opacities, [[0.7]])
    # a random Gaussian: the covariance's eigenvalues are the squared scales, along the rotated axes
    q = random_quats(1, seed=3)
    s = gaussian_splats(np.zeros((1, 3)), np.ones((1, 3)), np.array([[0.1, 0.2, 0.3]]), q, np.array([1.0]))
    axes = quat_to_matrix(q)[0]
    for k, sigma in enumerate((0.1, 0.2, 0.3)):
        np.testing.assert_allclose(s.covariances[0] @ axes[:, k], sigma ** 2 * axes[:, k], atol=1e-7)


def test_frustum_pose_reproduces_the_cameras_projection():
    cam = Camera.look_at(64, 48, 50.0, eye=(1.0, 0.8, 2.0), target=(0.0, 0.4, 0.0))
    pose = frustum_pose(cam)
    pts = np.random.default_rng(1).normal(size=(20, 3)) * 0.2 + [0.0, 0.4, 0.0]
    uv, _ = cam.project(pts)
    local = (pts - pose.position) @ quat_to_matrix(pose.wxyz[None])[0]  # world -> camera (x right, y down, z fwd)
    f = 0.5 * cam.height / np.tan(0.5 * pose.fov)
    ours = np.stack([0.5 * cam.width + f * local[:, 0] / local[:, 2],
                     0.5 * cam.height + f * local[:, 1] / local[:, 2]], 1)
    np.testing.assert_allclose(ours, uv, atol=1e-6)
    assert pose.aspect == 64 / 48


def test_speed_colours_run_from_blue_to_red():
    u = np.array([[0.0, 0, 0], [0, 0.5, 0], [0, 0, 1.0], [3.0, 0, 0]])
    c = speed_colors(u, top_speed=1.0)
    assert c.dtype == np.uint8 and c.shape == (4, 3)
    np.testing.assert_array_equal(c[0], SPEED_STOPS[0])
    np.testing.assert_array_equal(c[2], SPEED_STOPS[-1])
    np.testing.assert_array_equal(c[3], SPEED_STOPS[-1])  # faster than the top: red
    assert c[1, 2] < c[0, 2] and c[1, 0] > c[0, 0]  # half way: less blue, more red than still


def test_box_and_disk_shapes():
    seg = box_segments((0, 0, 0), (1, 2, 3))
    assert seg.shape == (12, 2, 3)
    lengths = np.sort(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1))
    np.testing.assert_allclose(lengths, [1] * 4 + [2] * 4 + [3] * 4)
    v, f = disk_mesh((0.1, 0.2, 0.3), 0.05, (0, 0, 2.0), segments=16)
    assert v.shape == (17, 3) and f.shape == (32, 3) and f.max() == 16
    np.testing.assert_allclose(v[:, 2], 0.3, atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(v[1:, :2] - [0.1, 0.2], axis=1), 0.05, atol=1e-6)
