"""diagnose finds an effect hidden in data made by a different solver (tests/diagnose/eulerian_plume.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from cli.main import main

from .eulerian_plume import PlumeEffects, simulate, write_scene

FRAMES, TRAIN, VALIDATE = 48, "0:32", "32:48"
FAST = ["--height", "40", "--evals", "10", "--arch", "cpu"]


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    out = tmp_path_factory.mktemp("tpl") / "four"
    result = CliRunner().invoke(main, ["calibrate", "--sample", "scalarflow", "--protocol", "four-view",
                                       "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out


def run_diagnose(template, tmp_path, effects: PlumeEffects) -> dict:
    scene = write_scene(template, tmp_path / "scene", simulate(FRAMES, effects))
    out = tmp_path / "diag"
    result = CliRunner().invoke(main, ["diagnose", str(scene), "--out", str(out), "--train-frames", TRAIN,
                                       "--validate-frames", VALIDATE, *FAST])
    assert result.exit_code == 0, result.output + repr(result.exception)
    report = json.loads((out / "report.json").read_text())
    assert set(report) == {"finding", "candidates", "windows", "views"}
    assert report["windows"] == {"train": [0, 32], "validate": [32, 48]}
    assert len(report["views"]) == 5
    assert {c["effect"] for c in report["candidates"]} == {"wind", "buoyancy_decay", "vorticity", "viscosity",
                                                           "dissipation", "swirl"}
    assert (out / "model.json").exists() and (out / "report.md").exists() and (out / "image_error.png").exists()
    return report


def test_diagnose_plain_plume_finds_none(template, tmp_path, ti_engine):
    report = run_diagnose(template, tmp_path, PlumeEffects())
    assert report["finding"]["effect"] == "none", report["candidates"]


def test_diagnose_finds_hidden_wind(template, tmp_path, ti_engine):
    rng = np.random.default_rng(11)
    speed, heading = rng.uniform(0.08, 0.14), rng.uniform(0, 2 * np.pi)
    wind = np.array([speed * np.cos(heading), 0.0, speed * np.sin(heading)])
    report = run_diagnose(template, tmp_path, PlumeEffects(wind=tuple(wind)))
    assert report["finding"]["effect"] == "wind", report["candidates"]
    v = np.asarray(report["finding"]["params"]["velocity"])
    cos = v @ wind / (np.linalg.norm(v) * speed)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 25, (v, wind)
    assert abs(np.linalg.norm(v) - speed) < 0.4 * speed, (v, wind)
    assert report["finding"]["gain"]["after"] < report["finding"]["gain"]["before"]


def test_diagnose_finds_hidden_dissipation(template, tmp_path, ti_engine):
    rate = np.random.default_rng(12).uniform(0.4, 0.9)
    report = run_diagnose(template, tmp_path, PlumeEffects(rate=rate))
    assert report["finding"]["effect"] == "dissipation", report["candidates"]
    assert abs(report["finding"]["params"]["rate"] - rate) < 0.4 * rate, (report["finding"], rate)
