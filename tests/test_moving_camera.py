"""A ground-truth camera that moves during the video (PINF's ``transform_matrix_list``): ``eval`` scores it and
``render --compare`` draws it frame by frame; the stages that need still cameras refuse one."""
import json

import numpy as np
import pytest

from clirun import invoke, ok
from fluidnexus.frames import render_state
from fluidnexus.metrics import psnr
from fluidnexus.scene import load_ground_truth
from fluidnexus.state import FrameState
from fluidnexus.video import read_video, write_frames

from calibrate.pinf_capture import entry, ring_camera, tiny_video, write_capture
from handmade_run import write_run

SIZE, FRAMES = 32, 4


def smoke_state(frame: int) -> FrameState:
    """A still, lopsided cloud of Gaussians around the ring's target (y-up world), so views differ by angle."""
    pos = np.array([[0.0, -0.3, 0.0], [0.7, 0.2, 0.1], [-0.2, 0.6, -0.5], [0.3, -0.8, 0.6], [-0.9, 0.0, 0.4]])
    n = len(pos)
    return FrameState(frame, pos.astype(np.float32), np.zeros((n, 3), np.float32), pos.astype(np.float32),
                      np.linspace(0.5, 1.0, n, dtype=np.float32)[:, None],
                      np.tile([0.25, 0.15, 0.2], (n, 1)).astype(np.float32),
                      np.tile([1.0, 0, 0, 0], (n, 1)).astype(np.float32), np.full(n, 0.9, np.float32))


@pytest.fixture(scope="module")
def moving_scene(tmp_path_factory, ti_engine):
    """A y-up capture whose test04 camera swings 60 degrees round the smoke, its footage rendered from the
    cloud (PNG frames, exact but for 8-bit rounding); and a run holding that cloud at every frame."""
    tmp = tmp_path_factory.mktemp("moving")
    path = write_capture(tmp / "cap", frames=FRAMES, size=SIZE, rot=None, videos=False,
                         frame_bkg_color=[0.0, 0.0, 0.0])  # the footage is rendered over black
    tiny_video(tmp / "cap" / "train00.mp4", FRAMES, SIZE)
    poses = [ring_camera(200.0 + 20.0 * t, SIZE, "Y") for t in range(FRAMES)]
    write_frames(tmp / "cap" / "test04", [render_state(smoke_state(t), cam) for t, cam in enumerate(poses)])
    info = json.loads(path.read_text())
    info["test_videos"] = [entry("test04", poses[0], FRAMES, poses)]
    path.write_text(json.dumps(info))
    ok("calibrate", "--from-pinf", path, "--input", "train00", "--ground-truth", "test04", "--out", tmp / "S")
    run = write_run(tmp / "run", tmp / "S", [smoke_state(t) for t in range(FRAMES)], h=0.3, dt=1 / 25)
    return tmp / "S", run, poses


def test_eval_follows_the_moving_camera(moving_scene, tmp_path):
    scene, run, poses = moving_scene
    gt = load_ground_truth(scene)[0]
    assert gt.poses.shape == (FRAMES, 4, 4)
    truth = read_video(scene / gt.video, channels=1)
    # the camera really moves: its first pose sees the last frame's smoke elsewhere
    assert psnr(render_state(smoke_state(3), gt.camera), truth[3]) < 30
    ok("eval", run, "--json", tmp_path / "e.json", "--arch", "cpu")
    scores = json.loads((tmp_path / "e.json").read_text())
    assert scores["novel_view"]["per_view"]["test04"]["psnr"] > 40  # 8-bit rounding only
    assert scores["resimulation"]["psnr"] > 40  # still smoke advected by zero velocity


def test_render_compare_draws_the_moving_camera(moving_scene, tmp_path):
    _, run, _ = moving_scene
    ok("render", run, "--views", "test04", "--compare", "--png", "--out", tmp_path, "--arch", "cpu")
    frames = read_video(tmp_path / "test04_compare", channels=1)
    assert frames.shape == (FRAMES, SIZE, 2 * SIZE + 4, 1)
    for frame in frames:  # left: the render from the frame's pose; right: the real frame
        np.testing.assert_allclose(frame[:, :SIZE], frame[:, SIZE + 4:], atol=1.5 / 255)


def test_stages_refuse_a_moving_input_camera(moving_scene, tmp_path):
    scene, _, _ = moving_scene
    data = json.loads((scene / "scene.json").read_text())
    gt = data["ground_truth"][0]
    data["views"].append({"name": gt["name"], "role": "input", "camera": gt["camera"], "video": gt["video"],
                          "poses": gt["poses"]})
    (tmp_path / "S").mkdir()
    (tmp_path / "S" / "scene.json").write_text(json.dumps(data))
    (tmp_path / "S" / "ground_truth").symlink_to(scene / "ground_truth")
    (tmp_path / "S" / "videos").symlink_to(scene / "videos")
    for command in (["recon", tmp_path / "S", "--out", tmp_path / "R", "--arch", "cpu"], ["synth", tmp_path / "S"],
                    ["refine", tmp_path / "S"]):
        result = invoke(*command)
        lines = [line for line in result.output.splitlines() if line.strip()]
        assert result.exit_code == 2 and len(lines) == 1, result.output
        assert "scene.json" in lines[0] and "views[1].poses" in lines[0] and "moves" in lines[0], lines[0]
    assert not (tmp_path / "R").exists()


def test_diagnose_leaves_a_moving_camera_out(moving_scene):
    from fluidnexus.diagnose.run import load_observed

    scene, _, _ = moving_scene
    assert load_observed(scene, 0, 2, 16).names == ("train00",)
