"""A declared obstacle keeps every physical and visual particle out over a 20-frame reconstruction, and the
prediction after it goes around the same body."""
import json

import numpy as np

from fluidnexus.state import load_frame

from .conftest import ok

CENTER, RADIUS = (0.34, 0.09, -0.23), 0.035  # in the sample's plume, a few centimetres above its inflow
FAST = ["--resolution", "0.25", "--init-iters", "2", "--dynamics-iters", "1", "--appearance-iters", "1",
        "--stabilization-steps", "2", "--arch", "cpu"]


def test_declared_obstacle_keeps_every_particle_out_over_20_frames(tmp_path, ti_engine):
    scene = tmp_path / "scene"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--link", "--out", scene,
       "--obstacle", "sphere:" + ",".join(map(str, (*CENTER, RADIUS))))
    run = tmp_path / "run"
    ok("recon", scene, "--out", run, "--frames", "0:20", *FAST)
    info = json.loads((run / "run.json").read_text())
    assert info["obstacles"] == [{"kind": "sphere", "center": list(CENTER), "radius": RADIUS}]
    config = json.loads((run / "config.json").read_text())
    assert config["recon"]["lambda_next"] == 0.0  # a step with an obstacle has no gradient
    near = 0
    for t in range(20):
        state = load_frame(run / "frames" / f"{t:06d}.npz")
        for name in ("physical_positions", "visual_positions"):
            d = np.linalg.norm(getattr(state, name) - np.asarray(CENTER), axis=1)
            assert d.min() >= RADIUS - 1e-5, (t, name, d.min())  # float32 storage of a point on the surface
            near += int((d < RADIUS + 0.01).sum())
    assert near > 100  # the gas did reach the body: the test is not vacuous
    future = tmp_path / "future"
    ok("predict", run, "--frames", "3", "--out", future, "--no-refit", "--no-calibrate", "--arch", "cpu")
    for t in range(20, 23):
        state = load_frame(future / "frames" / f"{t:06d}.npz")
        for name in ("physical_positions", "visual_positions"):
            assert np.linalg.norm(getattr(state, name) - np.asarray(CENTER), axis=1).min() >= RADIUS - 1e-5
