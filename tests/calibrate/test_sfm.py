"""Structure-from-motion calibration on a synthetic textured scene rendered with known cameras."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fluidnexus.calibrate.sfm import UP_FROM_IMAGE_UP, UP_FROM_X_AXES, calibrate_images
from fluidnexus.camera import Camera
from fluidnexus.errors import InputError

from .synthetic_scene import TexturedScene, render, rig_cameras, surface_distance

RIG_NAMES = [f"cam{i}" for i in range(6)]
TARGET = np.array([0.0, 0.5, 0.0])  # where rig_cameras() aim; calibrate_images puts the look-at point at 0
MAX_ROTATION_DEG = 1.0
MAX_CENTRE_FRACTION = 0.01  # of the rig size


def to_bgr8(image: np.ndarray) -> np.ndarray:
    return np.round(np.clip(image[..., ::-1], 0, 1) * 255).astype(np.uint8)


def write_video(path: Path, frames: list[np.ndarray]) -> Path:
    """Write [H, W, 3] float frames losslessly (FFV1), so the test checks geometry, not codec artefacts."""
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 10, (w, h))
    assert writer.isOpened()
    for frame in frames:
        writer.write(to_bgr8(frame))
    writer.release()
    return path


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Similarity (s, R, t) minimising sum |dst - (s R src + t)|^2 for [N, 3] point sets (Umeyama 1991)."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = np.trace(np.diag(S) @ D) / (a**2).sum(1).mean()
    return s, R, mu_d - s * R @ mu_s


def rotation_angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


def rig_size(cameras) -> float:
    centres = np.stack([c.center for c in cameras])
    return float(np.linalg.norm(centres[:, None] - centres[None], axis=-1).max())


def pose_errors(recovered, truth):
    """Per-camera rotation error (deg) and centre error (fraction of rig size) after the best similarity."""
    rec_c = np.stack([c.center for c in recovered])
    gt_c = np.stack([c.center for c in truth])
    s, R, t = umeyama(rec_c, gt_c)
    rot = [rotation_angle_deg(g.R.T @ r.R @ R.T) for r, g in zip(recovered, truth)]
    centre = np.linalg.norm(s * rec_c @ R.T + t - gt_c, axis=1) / rig_size(truth)
    return np.array(rot), centre, (s, R, t)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """Six rendered rig views (PNG files), their true cameras and the scene."""
    folder = tmp_path_factory.mktemp("rig")
    scene, cameras = TexturedScene.random(0), rig_cameras()
    images = [render(scene, cam, supersample=2) for cam in cameras]
    paths = []
    for name, image in zip(RIG_NAMES, images):
        paths.append(folder / f"{name}.png")
        cv2.imwrite(str(paths[-1]), to_bgr8(image))
    return {"cameras": cameras, "paths": paths, "images": images}


@pytest.fixture(scope="module")
def metric_result(rig, tmp_path_factory):
    gt = rig["cameras"]
    distance = float(np.linalg.norm(gt[0].center - gt[5].center))
    return calibrate_images(rig["paths"], tmp_path_factory.mktemp("work"), scale_distance=("cam0", "cam5", distance))


def test_rig_poses_match_ground_truth_up_to_similarity(rig, metric_result):
    recovered = [metric_result.cameras[name] for name in RIG_NAMES]
    rot, centre, _ = pose_errors(recovered, rig["cameras"])
    assert rot.max() < MAX_ROTATION_DEG, rot
    assert centre.max() < MAX_CENTRE_FRACTION, centre
    assert metric_result.mean_reprojection_error_px < 0.5


def test_rig_intrinsics_are_recovered_per_camera(rig, metric_result):
    for name, truth in zip(RIG_NAMES, rig["cameras"]):
        cam = metric_result.cameras[name]
        assert (cam.width, cam.height) == (truth.width, truth.height)
        np.testing.assert_allclose(cam.K[:2, 2], truth.K[:2, 2])
        np.testing.assert_allclose(np.diag(cam.K)[:2], np.diag(truth.K)[:2], rtol=0.01)


def test_world_is_aligned_up_heading_and_origin(rig, metric_result):
    truth = rig["cameras"]
    # The scene discriminates: the rig looks down, so its mean image-up vector leans > 10 deg off vertical.
    mean_image_up = np.mean([-c.R[1] for c in truth], axis=0)
    assert np.degrees(np.arccos(mean_image_up[1] / np.linalg.norm(mean_image_up))) > 10.0
    assert metric_result.up_axis_source == UP_FROM_X_AXES

    recovered = [metric_result.cameras[name] for name in RIG_NAMES]
    _, _, (_, R, _) = pose_errors(recovered, truth)
    assert np.degrees(np.arccos(np.clip(R[1, 1], -1, 1))) < 2.0  # recovered +y is the true +y
    # Mean heading along -z and the look-at point at the origin: the true rig, shifted by -TARGET, is recovered
    # without any further alignment.
    size = rig_size(truth)
    for cam, gt in zip(recovered, truth):
        assert rotation_angle_deg(gt.R.T @ cam.R) < MAX_ROTATION_DEG
        assert np.linalg.norm(cam.center - (gt.center - TARGET)) < MAX_CENTRE_FRACTION * size


def test_scale_distance_makes_all_distances_metric(rig, metric_result):
    assert metric_result.metric
    rec = np.stack([metric_result.cameras[name].center for name in RIG_NAMES])
    gt = np.stack([c.center for c in rig["cameras"]])
    np.testing.assert_allclose(np.linalg.norm(rec[0] - rec[5]), np.linalg.norm(gt[0] - gt[5]), rtol=1e-9)
    iu = np.triu_indices(len(gt), 1)
    rec_d = np.linalg.norm(rec[:, None] - rec[None], axis=-1)[iu]
    gt_d = np.linalg.norm(gt[:, None] - gt[None], axis=-1)[iu]
    np.testing.assert_allclose(rec_d, gt_d, rtol=0.01)


def test_sparse_points_lie_on_the_scene(rig, metric_result):
    points = metric_result.points
    assert metric_result.num_points == len(points) > 500
    size = rig_size(rig["cameras"])
    distance = surface_distance(points + TARGET)  # the result is already metric and aligned: no fit here
    # The boxes near the look-at point are triangulated from wide angles; the far room walls (3-8 m away, seen
    # at grazing angles) are less certain (measured: 90 % within 0.09 % and 0.8 % of the rig size).
    near = np.linalg.norm(points, axis=1) < 1.5
    assert near.sum() > 100
    assert np.quantile(distance[near], 0.9) < 0.0025 * size, np.quantile(distance[near], [0.5, 0.9])
    assert np.quantile(distance, 0.9) < 0.015 * size, np.quantile(distance, [0.5, 0.9])


def test_videos_use_their_first_frame_and_scale_stays_unknown(rig, tmp_path):
    images, paths = rig["images"], list(rig["paths"])
    # Later frames show another camera's view: using them instead of frame 0 would break the poses.
    paths[0] = write_video(tmp_path / "cam0.avi", [images[0], images[3], images[3]])
    paths[2] = write_video(tmp_path / "cam2.avi", [images[2], images[5]])
    result = calibrate_images(paths, tmp_path / "work")
    assert not result.metric
    rot, centre, _ = pose_errors([result.cameras[name] for name in RIG_NAMES], rig["cameras"])
    assert rot.max() < MAX_ROTATION_DEG and centre.max() < MAX_CENTRE_FRACTION, (rot, centre)


def test_sweep_video_gives_one_shared_camera_per_sampled_frame(tmp_path):
    scene = TexturedScene.random(1)
    truth = rig_cameras(num=7, width=320, height=240, arc_deg=70.0, focal_spread=0.0)
    video = write_video(tmp_path / "sweep.avi", [render(scene, cam, supersample=2) for cam in truth])
    stages = []
    result = calibrate_images([video], tmp_path / "work", frames_per_video=4, progress=stages.append)
    assert any("mapping" in stage for stage in stages)
    frames = [0, 2, 4, 6]
    assert sorted(result.cameras) == [f"sweep_f{i:04d}" for i in frames]
    Ks = [result.cameras[f"sweep_f{i:04d}"].K for i in frames]
    for K in Ks[1:]:
        np.testing.assert_array_equal(K, Ks[0])
    rot, centre, _ = pose_errors([result.cameras[f"sweep_f{i:04d}"] for i in frames], [truth[i] for i in frames])
    assert rot.max() < MAX_ROTATION_DEG and centre.max() < MAX_CENTRE_FRACTION, (rot, centre)


def test_parallel_cameras_fall_back_to_image_up_and_point_median(tmp_path):
    # A straight rail of level cameras all looking along -z: their x axes are parallel (up is undetermined by
    # them) and their optical axes never meet (no look-at point).
    scene = TexturedScene.random(2)
    truth = [Camera.look_at(320, 240, 300.0, (x, 1.0, 3.0), (x, 1.0, 0.0)) for x in np.linspace(-0.9, 0.9, 4)]
    paths = []
    for i, cam in enumerate(truth):
        paths.append(tmp_path / f"rail{i}.png")
        cv2.imwrite(str(paths[-1]), to_bgr8(render(scene, cam, supersample=2)))
    result = calibrate_images(paths, tmp_path / "work", scale_distance=("rail0", "rail3", 1.8))
    assert result.up_axis_source == UP_FROM_IMAGE_UP
    # The origin is the per-axis median of the points in SfM's frame: ~0 after the rotation to +y up.
    assert np.abs(np.median(result.points, axis=0)).max() < 0.01
    recovered = [result.cameras[f"rail{i}"] for i in range(4)]
    # Level cameras: the mean image-up is the true up, and the heading is -z, so no fit is needed.
    for cam, gt in zip(recovered, truth):
        assert rotation_angle_deg(gt.R.T @ cam.R) < MAX_ROTATION_DEG
    rec_c = np.stack([c.center for c in recovered])
    gt_c = np.stack([c.center for c in truth])
    offsets = (rec_c - rec_c[0]) - (gt_c - gt_c[0])
    assert np.linalg.norm(offsets, axis=1).max() < MAX_CENTRE_FRACTION * rig_size(truth)


def _noise_png(path: Path, seed: int, size=(240, 320)) -> Path:
    noise = cv2.GaussianBlur(np.random.default_rng(seed).random(size), (0, 0), 1.5)
    cv2.imwrite(str(path), np.round(255 * (noise - noise.min()) / np.ptp(noise)).astype(np.uint8))
    return path


def test_unregistered_input_is_named(rig, tmp_path):
    stranger = _noise_png(tmp_path / "stranger.png", 3)
    with pytest.raises(InputError, match=r"could not register .*stranger\.png") as err:
        calibrate_images(rig["paths"][:5] + [stranger], tmp_path / "work")
    assert "cam0" not in str(err.value)


def test_no_reconstruction_is_an_input_error(tmp_path):
    inputs = [_noise_png(tmp_path / "a.png", 1), _noise_png(tmp_path / "b.png", 2)]
    with pytest.raises(InputError, match=r"no reconstruction.*a\.png.*b\.png"):
        calibrate_images(inputs, tmp_path / "work")


def test_bad_inputs_are_input_errors(rig, tmp_path):
    paths = rig["paths"]
    corrupt = tmp_path / "corrupt.png"
    corrupt.write_text("not an image")
    corrupt_video = tmp_path / "corrupt.mp4"
    corrupt_video.write_text("not a video")
    other = tmp_path / "other"
    other.mkdir()
    duplicate = other / "cam0.png"
    duplicate.write_bytes(paths[0].read_bytes())
    cases = [
        ([], None, "at least 2 images"),
        ([paths[0]], "cam0.png", "at least 2 images"),
        ([paths[0], tmp_path / "missing.png"], "missing.png", "no such file"),
        ([paths[0], corrupt], "corrupt.png", "cannot read"),
        ([paths[0], tmp_path / "missing.mp4"], "missing.mp4", "no such file"),
        ([paths[0], corrupt_video], "corrupt.mp4", "cannot open the video"),
        ([corrupt_video], "corrupt.mp4", "cannot open the video"),
        ([paths[0], duplicate], None, "same file stem"),
    ]
    for inputs, named, message in cases:
        with pytest.raises(InputError, match=message) as err:
            calibrate_images(inputs, tmp_path / "work")
        if named:
            assert named in str(err.value)


@pytest.mark.parametrize("scale, message", [
    (("cam0", "camX", 1.0), "unknown camera name"),
    (("cam0", "cam0", 1.0), "two different cameras"),
    (("cam0", "cam1", -2.0), "> 0"),
    (("cam0", "cam1", float("nan")), "> 0"),
    (("cam0", "cam1", "two"), "> 0"),
])
def test_bad_scale_distance_is_rejected_before_sfm(rig, tmp_path, scale, message):
    with pytest.raises(InputError, match=message) as err:
        calibrate_images(rig["paths"], tmp_path / "work", scale_distance=scale)
    assert err.value.field == "--scale-distance"
    assert not (tmp_path / "work").exists()  # failed before any SfM work


def test_calibrate_images_command_writes_a_metric_y_up_scene(rig, tmp_path):
    """`fluidnexus calibrate --images ... --media DIR --scale-distance` end to end."""
    from click.testing import CliRunner

    from fluidnexus_cli.main import main
    from fluidnexus.scene import load_scene
    from fluidnexus.video import write_video

    media = tmp_path / "footage"
    media.mkdir()
    for path, image in zip(rig["paths"], rig["images"]):
        write_video(media / f"{path.stem}.mp4", np.repeat(image[None], 3, axis=0), fps=25.0)
    truth = rig["cameras"]
    distance = float(np.linalg.norm(truth[0].center - truth[5].center))
    args = ["calibrate", "--images", *map(str, rig["paths"]), "--media", str(media),
            "--scale-distance", f"cam0,cam5,{distance}", "--out", str(tmp_path / "scene")]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    scene = load_scene(tmp_path / "scene")
    assert scene.view_names() == [p.stem for p in rig["paths"]]
    assert all(v.role == "input" for v in scene.views) and scene.fps == 25.0 and scene.frame_count == 3
    calib = scene.extra["calibration"]
    assert calib["metric"] is True and 0 < calib["mean_reprojection_error_px"] < 0.5
    rot, centre, (s, _, _) = pose_errors([v.camera for v in scene.views], truth)
    assert rot.max() < 1.0 and centre.max() < 0.01
    assert s == pytest.approx(1.0, rel=0.01)  # metric: no scale left to fit


def test_still_images_without_footage_are_refused(rig, tmp_path):
    from click.testing import CliRunner

    from fluidnexus_cli.main import main

    result = CliRunner().invoke(main, ["calibrate", "--images", *map(str, rig["paths"]), "--out", str(tmp_path / "s")])
    assert result.exit_code == 2 and "--media" in result.output
    assert not (tmp_path / "s").exists()
