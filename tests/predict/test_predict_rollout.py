"""``predict --no-refit`` is the simulator run from the last state; the re-fit path writes a scoreable run."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from fluidnexus import engine
from fluidnexus.recon.initial import emit
from fluidnexus.recon.smoke import Smoke
from fluidnexus.runs import open_run

from .conftest import invoke, ok


def direct_simulation(run_dir, frames):
    """The reference: the PBF step and Eq. 2 advection called by hand from the run's last state."""
    from fluidnexus.predict.rollout import RunContext, workspace_for

    run = open_run(run_dir)
    ctx = RunContext.of(run)
    smoke = Smoke.from_state(run.state(run.frames[-1]), torch.float64)
    ws = workspace_for(smoke, frames, ctx, ctx.model)
    out = []
    for _ in range(frames):
        t = smoke.frame + 1
        smoke = dataclasses.replace(smoke)  # emit appends in place; keep the frames already collected intact
        emit(smoke, ctx.source, ctx.config, t)
        p, u = engine.simulate_step(smoke.p, smoke.u, ws.theta, ws.sim, smoke.age)
        x = smoke.x + ws.dt * engine.velocity_at(smoke.x, p, u, ws.advect_query)
        keep = ~ws.isolated(p)
        smoke = Smoke(t, p[keep], u[keep], (smoke.age + ws.dt)[keep], x, smoke.color, smoke.scale, smoke.rotation,
                      smoke.opacity)
        out.append(smoke)
    return out


def test_predict_no_refit_equals_direct_simulation(start_run, tmp_path):
    ok("predict", start_run, "--frames", 3, "--out", tmp_path / "future", "--no-refit", "--arch", "cpu")
    pred = open_run(tmp_path / "future")
    assert pred.frames == [1, 2, 3] and pred.info["kind"] == "predict" and pred.info["start_frame"] == 0
    with torch.no_grad():
        reference = direct_simulation(start_run, 3)
    for ref in reference:
        state = pred.state(ref.frame)
        np.testing.assert_allclose(state.physical_positions, ref.p.numpy(), atol=1e-6)
        np.testing.assert_allclose(state.physical_velocities, ref.u.numpy(), atol=1e-4)
        np.testing.assert_allclose(state.visual_positions, ref.x.numpy(), atol=1e-6)
    assert not np.allclose(pred.state(3).visual_positions[:50], open_run(start_run).state(0).visual_positions[:50])


@pytest.mark.slow
def test_predict_refit_writes_a_scoreable_run(start_run, tmp_path):
    out = tmp_path / "refit"
    ok("predict", start_run, "--frames", 2, "--out", out, "--arch", "cpu")
    pred = open_run(out)
    assert pred.frames == [1, 2] and pred.info["anchor"] is True
    views = [v["name"] for v in json.loads((pred.scene_dir / "scene.json").read_text())["views"]]
    for name in views:
        assert (out / "videos" / f"refined_{name}.mp4").exists()
    ok("eval", out, "--json", tmp_path / "scores.json", "--arch", "cpu")
    scores = json.loads((tmp_path / "scores.json").read_text())["prediction"]
    assert scores["frames"] == [1, 3]
    assert set(scores["input_view"]["per_view"]) == {"train02"}
    assert set(scores["novel_views"]["per_view"]) == {"train00", "train01", "train03", "train04"}
    assert 0 < scores["input_view"]["psnr"] < 100 and 0 < scores["repeat_last_input_view"]["psnr"] < 100


def test_predict_rejects_bad_frames(start_run, tmp_path):
    for n in (0, -3):
        result = invoke("predict", start_run, "--frames", n, "--out", tmp_path / "x", "--no-refit")
        assert result.exit_code == 2 and "--frames" in result.output
    assert not (tmp_path / "x").exists()
