"""The future's model: ``--model`` from a file, and the backtest calibration of buoyancy and drag."""
from __future__ import annotations

import json

import numpy as np
import torch

from fluidnexus.engine import ModelConfig
from fluidnexus.engine.forces import Buoyancy, Drag, Vorticity
from fluidnexus.runs import open_run

from .conftest import invoke, ok


def test_with_buoyancy_drag_replaces_only_alpha_and_k():
    from fluidnexus.predict.calibrate import with_buoyancy_drag

    model = ModelConfig((Buoyancy(alpha=-0.03, decay=0.2), Drag(k=3.0, v_env=(0.1, 0.0, 0.0)), Vorticity(0.02)))
    out = with_buoyancy_drag(model, -0.01, 40.0)
    assert out.terms == (Buoyancy(alpha=-0.01, decay=0.2), Drag(k=40.0, v_env=(0.1, 0.0, 0.0)), Vorticity(0.02))


def test_search_recovers_a_hidden_drag(start_run):
    """Footage made by the model with k = 40: the backtest must choose k = 40 and keep alpha."""
    from fluidnexus.frames import render_state
    from fluidnexus.predict.calibrate import search, with_buoyancy_drag
    from fluidnexus.predict.rollout import RunContext, rollout, workspace_for
    from fluidnexus.recon.smoke import Smoke

    run = open_run(start_run)
    ctx = RunContext.of(run)
    start = Smoke.from_state(run.state(0), torch.float64)
    hidden = with_buoyancy_drag(ctx.model, ctx.model.term("buoyancy").alpha, 40.0)
    frames = 6
    states = list(rollout(start, frames, workspace_for(start, frames, ctx, hidden), ctx))
    scene = run.scene(check_videos=False)
    cameras = [v.camera.scaled(run.resolution) for v in scene.views[:2]]
    truth = [np.stack([render_state(s.to_state(), cam) for s in states]) for cam in cameras]
    model, candidates = search(start, cameras, truth, ctx)
    assert model == hidden, candidates
    given = next(c for c in candidates if c["k"] == ctx.model.term("drag").k and
                 c["alpha"] == ctx.model.term("buoyancy").alpha)
    assert max(c["psnr"] for c in candidates) > given["psnr"] + 3, candidates


def test_predict_uses_a_model_file(start_run, tmp_path):
    model = ModelConfig((Buoyancy(alpha=-0.01), Drag(k=20.0)))
    path = tmp_path / "model.json"
    path.write_text(json.dumps({"format": "fluidnexus-model/1", "model": model.to_dict()}))
    out = tmp_path / "future"
    ok("predict", start_run, "--frames", 2, "--out", out, "--no-refit", "--model", path, "--arch", "cpu")
    pred = open_run(out)
    assert ModelConfig.from_dict(pred.config["model"]) == model
    assert pred.info["model_file"] == str(path.resolve())
    assert pred.info["calibration"] is None  # one reconstructed frame: nothing to backtest on


def test_predict_emits_only_inside_the_model_files_window(start_run, tmp_path):
    """A burst diagnosed as stopped (model.json's ``source.window``, e.g. found in the footage): the future emits
    no new smoke after the stop, as it does with the window open to the end; the window is recorded in the run."""
    model = ModelConfig((Buoyancy(alpha=-0.01), Drag(k=20.0)))
    counts = {}
    for name, window in (("stopped", [0, 1]), ("open", [0, None])):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps({"format": "fluidnexus-model/1", "model": model.to_dict(),
                                    "source": {"window": window, "window_from": "footage"}}))
        out = tmp_path / name
        ok("predict", start_run, "--frames", 2, "--out", out, "--no-refit", "--model", path, "--arch", "cpu")
        pred = open_run(out)
        assert pred.info["source"]["window"] == window
        counts[name] = [pred.state(t).num_physical for t in pred.frames]
    first = open_run(start_run).state(0).num_physical
    assert set(counts["stopped"]) == {first} and counts["open"][-1] > counts["open"][0] > first, counts


def test_predict_rejects_bad_model_options(start_run, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"model": {"terms": [{"kind": "no-such-term"}]}}))
    result = invoke("predict", start_run, "--frames", 2, "--out", tmp_path / "x", "--no-refit", "--model", bad)
    assert result.exit_code == 2 and "bad.json" in result.output and "model" in result.output
    model = ModelConfig((Buoyancy(alpha=-0.01),)).to_dict()
    bad.write_text(json.dumps({"model": model, "source": {"window": [5, 2]}}))
    result = invoke("predict", start_run, "--frames", 2, "--out", tmp_path / "w", "--no-refit", "--model", bad)
    assert result.exit_code == 2 and "bad.json" in result.output and "source.window" in result.output
    result = invoke("predict", start_run, "--frames", 2, "--out", tmp_path / "y", "--no-refit",
                    "--calibrate-window", 0)
    assert result.exit_code == 2 and "--calibrate-window" in result.output
    assert not any((tmp_path / name).exists() for name in ("x", "y", "w"))


def test_new_smoke_looks_like_the_recent_inflow(start_run):
    """The future's emitter gives new Gaussians the median look of the last 30 frames' emissions."""
    from fluidnexus.predict.rollout import RunContext, inflow_look
    from fluidnexus.recon.initial import visual_source
    from fluidnexus.recon.smoke import Smoke

    run = open_run(start_run)
    ctx = RunContext.of(run)
    smoke = Smoke.from_state(run.state(0), torch.float64)
    recent = 30 * visual_source(ctx.source, ctx.config).count
    smoke.add_visual(torch.zeros((recent, 3), dtype=torch.float64), 0.25, 0.004, 0.01)
    smoke.opacity[-1] = 0.9  # one outlier does not move the median
    color, scale, opacity = inflow_look(smoke, ctx)
    assert torch.allclose(color, torch.tensor([0.25], dtype=torch.float64))
    assert (scale, opacity) == (0.004, 0.01)
