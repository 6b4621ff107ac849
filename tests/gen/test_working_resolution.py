"""synth and refine at the working resolution: they write what recon reads (docs/scale.md)."""
from __future__ import annotations

import numpy as np

from clirun import ok
from fluidnexus.recon.observations import load_observations
from fluidnexus.scene import load_scene
from fluidnexus.video import probe_video, read_video


def test_synth_and_refine_write_the_working_resolution(tmp_path):
    scene_dir = tmp_path / "s"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "single-view", "--out", scene_dir)
    ok("synth", scene_dir, "--resolution", "0.25")
    scene = load_scene(scene_dir)  # a novel video at half its camera's size is accepted
    novel = scene.with_role("novel")
    want = novel[0].camera.scaled(0.25)  # 68 x 120
    for view in novel:
        info = probe_video(scene.video_path(view))
        assert (info.width, info.height) == (want.width, want.height)
        assert view.provenance["synth"]["resolution"] == 0.25
        assert view.provenance["synth"]["axis_sigma_m"] == 0.03  # ScalarFlow's length scale is 1
    ok("refine", scene_dir, "--resolution", "0.25")
    scene = load_scene(scene_dir)
    view = scene.with_role("novel")[0]
    assert view.provenance["refine"]["resolution"] == 0.25
    info = probe_video(scene.video_path(view))
    assert (info.width, info.height) == (want.width, want.height)
    # recon at the same resolution reads the refined video at the size it was written
    obs = load_observations(scene, (0, 2), 0.25, 1)
    k = obs.names.index(view.name)
    raw = read_video(scene.video_path(view), frames=slice(0, 2), gray=True)
    assert obs.images.shape[2:4] == (want.height, want.width)
    assert np.array_equal(obs.images[k], raw)

