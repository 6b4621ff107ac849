"""``predict`` and ``interact`` with a model.json of either structure (docs/prediction.md, "The gas in ambient air")."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from clirun import assert_clean_failure

from fluidnexus.engine import AmbientAir, ModelConfig
from fluidnexus.engine.forces import Buoyancy, Viscosity
from fluidnexus.runs import open_run

from .conftest import invoke, model_file, ok

TERMS = (Buoyancy(alpha=-0.1), Viscosity(c=0.3))  # diagnose's kind of model: buoyancy and XSPH, no drag
AIR = ModelConfig(TERMS, AmbientAir())


def _digest(run_dir: Path) -> dict:
    """SHA-256 of every array of every frame file (name -> hex)."""
    out = {}
    for path in sorted((run_dir / "frames").glob("*.npz")):
        h = hashlib.sha256()
        with np.load(path) as data:
            for key in sorted(data.files):
                h.update(key.encode() + np.ascontiguousarray(data[key]).tobytes())
        out[path.name] = h.hexdigest()
    return out


def paper_gas_future(start_run, folder: Path) -> Path:
    """``predict --no-refit`` of 3 frames with the paper's gas (:data:`TERMS`) as its model.json."""
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / "paper"
    ok("predict", start_run, "--frames", 3, "--out", out, "--no-refit", "--arch", "cpu",
       "--model", model_file(folder / "paper_gas.json", ModelConfig(TERMS)))
    return out


def test_paper_gas_model_file_gives_the_bytes_of_the_runs_own_model(start_run, tmp_path):
    """The paper's gas through --model: frames byte for byte as predict writes them for a run whose own model is the
    same gas (the model file takes the path of the paper's gas, not one of the ambient air's). Compared in the same
    process, not against stored digests: the bytes differ between CPUs (Taichi compiles for the host's vector
    units; the digests of 2026-11-24 no longer matched on an AVX-512 VM on 2026-12-01)."""
    out = paper_gas_future(start_run, tmp_path)
    own = tmp_path / "own_run"
    shutil.copytree(start_run, own)
    config = json.loads((own / "config.json").read_text())
    config["model"] = ModelConfig(TERMS).to_dict()
    (own / "config.json").write_text(json.dumps(config))
    ok("predict", own, "--frames", 3, "--out", tmp_path / "own_future", "--no-refit", "--arch", "cpu")
    digest = _digest(out)
    assert len(digest) == 3 and digest == _digest(tmp_path / "own_future")
    assert open_run(out).config["model"]["structure"] == {"name": "paper_gas"}


@pytest.fixture(scope="module")
def air_future(start_run, tmp_path_factory):
    """``predict --no-refit`` of 4 frames with the ambient-air model.json."""
    root = tmp_path_factory.mktemp("air")
    ok("predict", start_run, "--frames", 4, "--out", root / "future", "--no-refit", "--arch", "cpu",
       "--model", model_file(root / "ambient_air.json", AIR))
    return root / "future"


def _start(run_dir):
    from fluidnexus.predict.rollout import RunContext
    from fluidnexus.recon.smoke import Smoke

    run = open_run(run_dir)
    return RunContext.of(run), Smoke.from_state(run.state(0), torch.float64)


def test_ambient_air_model_writes_a_run_of_rising_smoke(start_run, air_future, tmp_path):
    """Frames hold the smoke (the reconstructed smoke and what the inlet made smoke), never the air around it
    (about 22 k particles); its centroid and the Gaussians' rise every frame; render and eval read the run."""
    pred, start = open_run(air_future), open_run(start_run).state(0)
    assert pred.frames == [1, 2, 3, 4]
    assert ModelConfig.from_dict(pred.config["model"]) == AIR
    assert ModelConfig.from_dict(pred.config["fit_model"]) == ModelConfig.from_dict(open_run(start_run).config["model"])
    states = [start] + [pred.state(t) for t in pred.frames]
    n0 = len(start.physical_positions)
    for state in states[1:]:
        assert n0 <= len(state.physical_positions) < 1.1 * n0
    smoke_y = [s.physical_positions[:, 1].mean() for s in states]
    visual_y = [s.visual_positions[:, 1].mean() for s in states]
    assert np.all(np.diff(smoke_y) > 1e-3) and visual_y[-1] > visual_y[0] + 5e-3, (smoke_y, visual_y)
    view = json.loads((pred.scene_dir / "scene.json").read_text())["views"][0]["name"]
    ok("render", air_future, "--views", view, "--out", tmp_path / "render", "--arch", "cpu")
    assert (tmp_path / "render" / f"{view}.mp4").stat().st_size > 0
    ok("eval", air_future, "--json", tmp_path / "scores.json", "--arch", "cpu")
    scores = json.loads((tmp_path / "scores.json").read_text())["prediction"]
    assert scores["frames"] == [1, 5] and 0 < scores["input_view"]["psnr"] < 100


def test_air_stays_bounded_within_the_estimate(start_run):
    """Over 6 frames the smoke and air never exceed 1.25 x the lattice sites of the region around the smoke
    (open boundaries), nor the workspace's estimate (it never grows)."""
    from fluidnexus.predict.air import air_domain
    from fluidnexus.predict.rollout import rollout, workspace_for

    ctx, start = _start(start_run)
    ws = workspace_for(start, 6, ctx, AIR)
    capacity, domain = ws.sim.capacity, air_domain(ctx, AIR.air)
    counts = []
    for smoke in rollout(start, 6, ws, ctx):
        sites = len(domain.sites(*domain.outer(*domain.region(smoke.p.numpy()))))
        counts.append(ws.sim.n)
        assert ws.sim.n <= 1.25 * sites + len(smoke.p), (ws.sim.n, sites)
    assert ws.sim.capacity == capacity and max(counts) > 4 * len(start.p), counts


def test_interact_wind_moves_the_air_plume_downwind(start_run, air_future, tmp_path):
    """--wind on the ambient-air model is the force term on smoke and air alike: frame 2 lies downwind of the
    calm prediction's; the re-fit's model is the run's paper gas with the same wind term."""
    out = tmp_path / "windy"
    ok("interact", start_run, "--wind", "3,0,0", "--frames", 2, "--out", out, "--no-refit", "--arch", "cpu",
       "--model", model_file(tmp_path / "ambient_air.json", AIR))
    windy, calm = open_run(out).state(2), open_run(air_future).state(2)
    for a, b in ((windy.physical_positions, calm.physical_positions), (windy.visual_positions, calm.visual_positions)):
        shift = a.mean(0) - b.mean(0)
        assert shift[0] > 2e-3 and abs(shift[2]) < 0.3 * shift[0], shift
    config = open_run(out).config
    assert ModelConfig.from_dict(config["model"]).air == AIR.air
    fit = ModelConfig.from_dict(config["fit_model"])
    assert fit.air is None and [t.kind for t in fit.terms] == ["buoyancy", "drag", "wind"]
    assert fit.term("wind").accel == (3.0, 0.0, 0.0)


def test_calibration_in_air_searches_alpha_alone(start_run):
    """Footage made by the ambient-air model with twice its buoyancy: the backtest (alpha alone, no drag k)
    chooses it."""
    from fluidnexus.frames import render_state
    from fluidnexus.predict.calibrate import search, with_buoyancy_drag
    from fluidnexus.predict.rollout import rollout, workspace_for

    ctx, start = _start(start_run)
    ctx = dataclasses.replace(ctx, model=AIR)
    hidden = with_buoyancy_drag(AIR, 2 * AIR.term("buoyancy").alpha, None)
    states = list(rollout(start, 5, workspace_for(start, 5, ctx, hidden), ctx))
    run = open_run(start_run)
    cameras = [v.camera.scaled(run.resolution) for v in run.scene(check_videos=False).views[:2]]
    truth = [np.stack([render_state(s.to_state(), cam) for s in states]) for cam in cameras]
    model, candidates = search(start, cameras, truth, ctx)
    assert model == hidden and all(c["k"] is None for c in candidates) and len(candidates) == 4, candidates


def test_memory_estimate_counts_the_air(start_run, tmp_path):
    """The air (about 22 k particles around 5 k of smoke) is in the estimate; a limit between the paper's gas's
    estimate and the air's refuses the air model before anything is written."""
    from fluidnexus.memory import physical_bytes
    from fluidnexus.predict.air import air_domain
    from fluidnexus.predict.memory import future_estimate

    ctx, start = _start(start_run)
    paper, air = (future_estimate("predict", start, 4, ctx, m, [], False) for m in (ModelConfig(TERMS), AIR))
    n_air = air_domain(ctx, AIR.air).initial(start.p.numpy()).n
    assert air.parts["smoke and air particles"] >= physical_bytes(n_air, ctx.solver.iterations)
    limit = (paper.total + air.total) // 2
    result = invoke("predict", start_run, "--frames", 4, "--out", tmp_path / "x", "--no-refit", "--arch", "cpu",
                    "--no-calibrate", "--model", model_file(tmp_path / "ambient_air.json", AIR), "--max-memory", limit)
    assert_clean_failure(result, "smoke and air particles")
    assert not (tmp_path / "x").exists()


def test_recon_refuses_the_ambient_air_model(start_run, tmp_path):
    result = invoke("recon", start_run.parent / "scene", "--out", tmp_path / "r", "--model",
                    model_file(tmp_path / "ambient_air.json", AIR), "--arch", "cpu")
    assert_clean_failure(result, "ambient_air", "recon")
    assert not (tmp_path / "r").exists()


def test_refit_model_is_the_runs_paper_gas_with_the_wind():
    from fluidnexus.predict.rollout import RunContext, refit_model, with_wind

    paper = ModelConfig.scalarflow()
    ctx = RunContext(None, None, paper, None, fit_model=paper)
    windy = with_wind(AIR, (1.0, 0.0, 0.0), "uniform", 0.0, 1.0)
    assert refit_model(paper, ctx) is paper and refit_model(AIR, ctx) == paper
    assert refit_model(windy, ctx) == with_wind(paper, (1.0, 0.0, 0.0), "uniform", 0.0, 1.0)


@pytest.mark.slow
def test_ambient_air_refit_writes_a_run(start_run, tmp_path):
    """The re-fit after refining runs the run's paper gas on the air rollout's renders."""
    out = tmp_path / "refit"
    ok("predict", start_run, "--frames", 2, "--out", out, "--arch", "cpu", "--model",
       model_file(tmp_path / "ambient_air.json", AIR))
    pred = open_run(out)
    assert pred.frames == [1, 2] and ModelConfig.from_dict(pred.config["fit_model"]).air is None
    n0 = len(open_run(start_run).state(0).physical_positions)
    assert len(pred.state(2).physical_positions) < 1.1 * n0  # the re-fitted smoke, no air
