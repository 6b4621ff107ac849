"""``predict --model`` with the entrainment term (engine/entrainment.py): at alpha 0 the paper's gas to the byte, with
alpha the future's gas widens; recon refuses such a model."""
from __future__ import annotations

import numpy as np
from clirun import assert_clean_failure

from fluidnexus.engine import Entrainment, ModelConfig
from fluidnexus.runs import open_run

from .conftest import invoke, model_file, ok
from .test_predict_ambient import TERMS, _digest, paper_gas_future


def _width(run_dir, frame: int) -> float:
    p = open_run(run_dir).state(frame).physical_positions
    return float(np.hypot(p[:, 0].std(), p[:, 2].std()))


def test_predict_rolls_the_entrainment_out(start_run, tmp_path):
    futures = {}
    for alpha in (0.0, 0.3):
        out = futures[alpha] = tmp_path / f"alpha{alpha}"
        ok("predict", start_run, "--frames", 3, "--out", out, "--no-refit", "--arch", "cpu", "--model",
           model_file(tmp_path / f"m{alpha}.json", ModelConfig(TERMS, entrainment=Entrainment(alpha))))
        assert open_run(out).config["model"]["entrainment"] == {"alpha": alpha}
    # alpha 0: the same frames as the paper's gas without the term
    assert _digest(futures[0.0]) == _digest(paper_gas_future(start_run, tmp_path / "without"))
    assert _width(futures[0.3], 3) > _width(futures[0.0], 3)


def test_recon_refuses_a_model_with_entrainment(start_run, tmp_path):
    model = model_file(tmp_path / "m.json", ModelConfig(TERMS, entrainment=Entrainment(0.1)))
    result = invoke("recon", start_run.parent / "scene", "--out", tmp_path / "r", "--model", model, "--arch", "cpu")
    assert_clean_failure(result, "entrainment", "recon")
    assert not (tmp_path / "r").exists()
