"""``predict`` and ``interact`` with a model.json of either structure (docs/prediction.md, "The gas in ambient air")."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from fluidnexus.engine import ModelConfig
from fluidnexus.engine.forces import Buoyancy, Viscosity
from fluidnexus.runs import open_run

from .conftest import ok

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "predict_paper_gas.json"
TERMS = (Buoyancy(alpha=-0.1), Viscosity(c=0.3))  # diagnose's kind of model: buoyancy and XSPH, no drag


def _model_file(folder: Path, model: ModelConfig) -> Path:
    path = folder / f"{model.structure}.json"
    path.write_text(json.dumps({"format": "fluidnexus-model/1", "model": model.to_dict()}))
    return path


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


def test_paper_gas_model_file_gives_the_same_bytes_as_before(start_run, tmp_path, regen_golden):
    """The paper's gas through --model: frames byte for byte as the code before the ambient-air rollout wrote
    them (golden digests; ``--regen-golden`` rewrites them)."""
    out = tmp_path / "paper"
    ok("predict", start_run, "--frames", 3, "--out", out, "--no-refit", "--arch", "cpu",
       "--model", _model_file(tmp_path, ModelConfig(TERMS)))
    digest = _digest(out)
    if regen_golden:
        GOLDEN.write_text(json.dumps(digest, indent=1) + "\n")
    assert len(digest) == 3 and digest == json.loads(GOLDEN.read_text())
    assert open_run(out).config["model"]["structure"] == {"name": "paper_gas"}
