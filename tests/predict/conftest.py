"""A one-frame run folder built without fitting (initial smoke over the sample's source), for fast tests."""
from __future__ import annotations

import json

import numpy as np
import pytest

from clirun import invoke, ok  # noqa: F401  (re-exported to the tests of this folder)


def model_file(path, model):
    """``path`` written as a model file (``predict --model``) holding ``model`` (an engine ModelConfig)."""
    path.write_text(json.dumps({"format": "fluidnexus-model/1", "model": model.to_dict()}))
    return path


@pytest.fixture(scope="session")
def start_run(tmp_path_factory, ti_engine):
    """Run folder with frame 0: stabilised physical particles and a visual cylinder over the source (68x120)."""
    from fluidnexus.recon.config import ReconConfig
    from fluidnexus.recon.initial import initial_smoke, initial_visual
    from fluidnexus.recon.setup import capacities, default_setup, scene_source
    from fluidnexus.recon.workspace import Workspace
    from fluidnexus.runs import RUN_FORMAT
    from fluidnexus.scene import load_scene
    from fluidnexus.state import frame_path, save_frame

    root = tmp_path_factory.mktemp("predict")
    scene_dir = root / "scene"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "single-view", "--out", scene_dir)
    scene = load_scene(scene_dir)
    cfg = ReconConfig(frames=(0, 1), resolution=0.25, stabilization_steps=3, dynamics_iters=2, appearance_iters=2)
    setup = default_setup(scene, cfg)
    source = scene_source(scene, setup.config.length_scale)
    seeds = initial_visual(source, np.zeros((0, 3)), cfg)
    ws = Workspace(*capacities(1, setup, source, len(seeds)), setup.solver, setup.model)
    smoke = initial_smoke(source, seeds, cfg, ws, 0)
    run = root / "run"
    (run / "frames").mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({"format": RUN_FORMAT, "kind": "recon", "scene": str(scene_dir),
                                              "frames": [0, 1]}))
    (run / "config.json").write_text(json.dumps(setup.to_dict()))
    (run / "summary.json").write_text(json.dumps({"source": source.to_dict()}))
    save_frame(frame_path(run, 0), smoke.to_state())
    return run
