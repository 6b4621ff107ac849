"""What the viewer takes from run folders (cameras and their roles, obstacles of every origin, frames read on
demand) and how it lays out two runs; the scene is served by viser without a browser."""
import json

import numpy as np
import pytest

from fluidnexus.viewer.sources import RunContent

from handmade_run import write_run
from handmade_scene import ring_camera, write_scene
from view.ports import free_port
from view.test_view_cli import tiny_state


@pytest.fixture
def two_runs(tmp_path):
    """A recon run (frames 0-3; a declared ball, a found one) and an interact run continuing it (frames 4-6, a
    ball added)."""
    scene = write_scene(tmp_path / "scene", [("front", "input", ring_camera(0), None),
                                             ("side", "novel", ring_camera(90), None)],
                        ground_truth=[("back", ring_camera(200), "videos/back.mp4")], frame_count=8,
                        obstacles=[{"kind": "sphere", "center": [0.2, 0.5, 0.0], "radius": 0.05}])
    recon = write_run(tmp_path / "recon", scene, [tiny_state(t) for t in range(4)], h=0.1, dt=1 / 25)
    info = json.loads((recon / "run.json").read_text())
    info["found_obstacles"] = [{"center": [-0.2, 0.4, 0.1], "radius": 0.07, "sphere_like": True}]
    info["source"] = {"center": [0.1, 0.02, 0.0], "radius": 0.03, "direction": [1.0, 0.0, 0.0], "speed": 0.5}
    (recon / "run.json").write_text(json.dumps(info))
    future = write_run(tmp_path / "future", scene, [tiny_state(t) for t in range(4, 7)], h=0.1, dt=1 / 25)
    info = json.loads((future / "run.json").read_text())
    info.update(kind="interact", parent=str(recon.resolve()),
                interaction={"obstacle": {"kind": "ball", "center": [0.0, 0.8, 0.0], "radius": 0.06}})
    (future / "run.json").write_text(json.dumps(info))
    return recon, future


def test_cameras_bodies_and_frames_of_a_run(two_runs):
    recon, future = (RunContent.open(p) for p in two_runs)
    assert [(m.name, m.role) for m in recon.cameras()] == [("front", "input"), ("side", "synthesised"),
                                                           ("back", "held-out")]
    assert [(b.origin, b.radius) for b in recon.bodies()] == [("declared", 0.05), ("found", 0.07)]
    assert [(b.origin, b.radius) for b in future.bodies()] == [("declared", 0.05), ("found", 0.07),
                                                               ("interaction", 0.06)]  # found: the parent's
    assert future.state(2) is None and future.state(5).frame == 5
    assert recon.source().center == (0.1, 0.02, 0.0) and recon.source().radius == 0.03  # the one recon used
    assert future.source().radius == 0.1  # none recorded: the scene's
    assert recon.static_layer_file() is None


def test_two_runs_side_by_side_or_toggled(two_runs):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'fluidnexus[view]')")
    from fluidnexus.viewer import open_viewer

    port = free_port()
    served = open_viewer(list(two_runs), port=port)
    try:
        viewer = served.viewer
        assert viewer.times == list(range(7)) and viewer.shown == 0
        assert "A: 8 Gaussians" in viewer.status.content and "B: no frame 0" in viewer.status.content
        np.testing.assert_allclose(viewer.nodes[1].group.position, [1.25, 0, 0])  # beside A: 1.25 volume widths
        viewer.frame.value = 5
        assert viewer.shown == 5 and "A: no frame 5" in viewer.status.content and "B: 8 Gaussians" in \
            viewer.status.content
        assert viewer.nodes[0].smoke is None and viewer.nodes[1].smoke is not None
        viewer.layout.value = "toggle"
        np.testing.assert_allclose(viewer.nodes[1].group.position, [0, 0, 0])
        assert viewer.nodes[0].group.visible and not viewer.nodes[1].group.visible
        viewer.switch.value = True  # a click, as the page sends it
        assert not viewer.nodes[0].group.visible and viewer.nodes[1].group.visible
        viewer.particles_on.value = True
        assert viewer.nodes[1].particles is not None and viewer.nodes[0].particles is None
    finally:
        served.stop()


def test_frusta_show_their_videos_frame_at_the_slider(tmp_path, make_video):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'fluidnexus[view]')")
    from fluidnexus.video import read_video
    from fluidnexus.viewer import open_viewer

    make_video(tmp_path / "scene" / "videos" / "front.mp4", frames=4, width=64, height=48, channels=3)
    scene = write_scene(tmp_path / "scene", [("front", "input", ring_camera(0), "videos/front.mp4")])
    run = write_run(tmp_path / "run", scene, [tiny_state(t) for t in range(4)], h=0.1, dt=1 / 25)
    port = free_port()
    served = open_viewer([run], port=port)
    try:
        viewer = served.viewer
        viewer.thumbnails[0].join(30)
        expected = read_video(tmp_path / "scene" / "videos" / "front.mp4", size=(192, 144), channels=3)
        for t in (0, 3):
            viewer.frame.value = t
            shown = viewer.nodes[0].frusta["front"].image
            assert shown.shape == (144, 192, 3)
            np.testing.assert_allclose(shown / 255.0, expected[t], atol=1 / 255)
        assert np.abs(expected[3] - expected[0]).max() > 0.1  # the frames differ, so the check can fail
    finally:
        served.stop()


def test_the_static_layer_is_shown_once_read(tmp_path):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'fluidnexus[view]')")
    from fluidnexus.scenery.static_layer import STATIC_FILE, StaticLayer, save_static
    from fluidnexus.viewer import open_viewer
    from fluidnexus.viewer.sources import STATIC_LAYER_FILE

    assert STATIC_LAYER_FILE == STATIC_FILE
    scene = write_scene(tmp_path / "scene", [("front", "input", ring_camera(0), None)])
    run = write_run(tmp_path / "run", scene, [tiny_state(0)], h=0.1, dt=1 / 25)
    n = 5
    save_static(run, StaticLayer(np.zeros((n, 3), np.float32), np.full((n, 3), 0.1, np.float32),
                                 np.tile([1.0, 0, 0, 0], (n, 1)).astype(np.float32), np.full(n, 0.5, np.float32),
                                 np.full((n, 1), 0.3, np.float32), np.zeros(1, np.float32),
                                 {"volume": [[0] * 3, [1] * 3]}))
    port = free_port()
    served = open_viewer([run], port=port)
    try:
        assert served.viewer.static_loaded.wait(60)
        handle = served.viewer.static[0]
        assert handle is not None and handle.buffer.shape == (n, 8)
        served.viewer.static_on.value = False
        assert not served.viewer.nodes[0].parts["static"].visible
    finally:
        served.stop()


def test_an_empty_frame_shows_nothing(tmp_path):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'fluidnexus[view]')")
    from fluidnexus.state import FrameState
    from fluidnexus.viewer import open_viewer

    e3, e4 = np.zeros((0, 3), np.float32), np.zeros((0, 4), np.float32)
    empty = FrameState(1, e3, e3, e3, np.zeros((0, 1), np.float32), e3, e4, np.zeros(0, np.float32))
    scene = write_scene(tmp_path / "scene", [("front", "input", ring_camera(0), None)])
    run = write_run(tmp_path / "run", scene, [tiny_state(0), empty], h=0.1, dt=1 / 25)
    port = free_port()
    served = open_viewer([run], port=port)
    try:
        viewer = served.viewer
        viewer.particles_on.value = True
        assert viewer.nodes[0].smoke is not None and viewer.nodes[0].particles is not None
        viewer.frame.value = 1
        assert viewer.nodes[0].smoke is None and viewer.nodes[0].particles is None
        assert "0 Gaussians, 0 particles" in viewer.status.content
    finally:
        served.stop()
