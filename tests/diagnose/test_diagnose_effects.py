"""diagnose finds an effect hidden in data made by a different solver (tests/diagnose/eulerian_plume.py).

Each test hides one effect (or two) at a magnitude drawn from a seeded range, runs diagnose on 48 frames (train
0:32, validate 32:48) and requires the right name. CI runs the no-effect control, wind and dissipation; the
other effects are ``slow``. Buoyancy decay, vorticity confinement, viscosity and swirl are ``xfail``: their
data differ clearly from a plain plume (``test_hidden_effects_are_visible``), but diagnose does not name them;
the measured reasons are in each marker and in docs/diagnose.md.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from cli.main import main
from fluidnexus.diagnose.observe import image_error
from fluidnexus.diagnose.run import load_observed

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


def visibility(template, tmp_path, effects: PlumeEffects, plain: np.ndarray) -> float:
    """How much ``effects`` change the footage diagnose sees: image error (observe.image_error) on the
    validation frames between the plume with the effects and ``plain`` [V, T, h, w] (the plain plume's images),
    with the best brightness gain, at diagnose's observation size."""
    images = observe(template, tmp_path / "vis", effects)[:, 32:48]
    ref = plain[:, 32:48]
    gain = (images * ref).sum() / (ref * ref).sum()
    return float(image_error(images, gain * ref).mean())


def observe(template, folder, effects: PlumeEffects) -> np.ndarray:
    scene = write_scene(template, folder, simulate(FRAMES, effects))
    return load_observed(scene, 0, FRAMES, int(FAST[1])).images


#: Effects at the weak end of each test's seeded range below (seeded values are drawn inside these ranges).
WEAKEST = {"wind": PlumeEffects(wind=(0.08, 0.0, 0.0)), "dissipation": PlumeEffects(rate=0.4),
           "buoyancy_decay": PlumeEffects(tau=1.0), "vorticity": PlumeEffects(epsilon=10.0),
           "viscosity": PlumeEffects(nu=2e-3), "swirl": PlumeEffects(omega=12.0)}


def test_hidden_effects_are_visible(template, tmp_path):
    """Every hidden effect, at the weak end of its test's range, changes the validation footage at least as
    much as dissipation at the weak end of the range that diagnose must find in CI: the effects that the xfail
    tests hide are not too small to see (measured 0.24 wind, 0.042 dissipation, 0.12 decay, 0.15 vorticity,
    0.11 viscosity, 0.27 swirl)."""
    plain = observe(template, tmp_path / "plain", PlumeEffects())
    vis = {name: visibility(template, tmp_path / name, e, plain) for name, e in WEAKEST.items()}
    assert vis["dissipation"] > 0.03, vis
    assert all(v >= vis["dissipation"] for v in vis.values()), vis
    # an effect that is switched off changes nothing
    assert visibility(template, tmp_path / "off", PlumeEffects(), plain) < 1e-9


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


# ---------------------------------------------------------------- slow tier: the other effects
# The xfail reasons are measured (docs/diagnose.md, "Effects diagnose does not find"; numbers from these tests'
# own draws unless marked "oracle", which is a 3-parameter base fit on all 48 frames). Common cause: the base fit
# lands in a high-drag regime (k 17-44 1/s, 22-33 layers/s) where the PBF plume is pushed up by its source and
# its buoyancy hardly acts; what it misses on every generated plume is the buoyant acceleration of the front.


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="absorbed by the base model: oracle fits of a tau = 0.5 s plume have "
                   "image error 0.067 without the decay term and 0.083 with the true one; at tau = 0.93 s the decay "
                   "search fits tau 0.53 s on the training frames but raises the validation error by 41 % "
                   "(finding: none; wind gains 17.1 % at 1.6 cm/s, under the 20 % bar)")
def test_diagnose_finds_hidden_buoyancy_decay(template, tmp_path, ti_engine):
    tau = np.random.default_rng(13).uniform(0.5, 1.0)
    report = run_diagnose(template, tmp_path, PlumeEffects(tau=tau))
    assert report["finding"]["effect"] == "buoyancy_decay", report["candidates"]
    assert abs(report["finding"]["params"]["tau"] - tau) < 0.4 * tau, (report["finding"], tau)


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="grid vorticity confinement changes the footage by < 0.02 below epsilon "
                   "8; at epsilon 13.3 the base refit absorbs it (control validation error 0.21, a plain plume 0.46) "
                   "and the PBF confinement search gains 0.3 % (epsilon 0.0075)")
def test_diagnose_finds_hidden_vorticity(template, tmp_path, ti_engine):
    epsilon = np.random.default_rng(14).uniform(10.0, 14.0)
    report = run_diagnose(template, tmp_path, PlumeEffects(epsilon=epsilon))
    assert report["finding"]["effect"] == "vorticity", report["candidates"]


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="grid viscosity carries momentum into the still air, which the PBF drag "
                   "already models (control validation error 0.31, a plain plume 0.46); at nu = 3.4e-3 m^2/s the "
                   "XSPH search gains 14.3 % (c 0.075), inside the -11 % to +15 % that XSPH gains on a plain "
                   "plume across base-fit starts")
def test_diagnose_finds_hidden_viscosity(template, tmp_path, ti_engine):
    nu = np.random.default_rng(15).uniform(2e-3, 4e-3)
    report = run_diagnose(template, tmp_path, PlumeEffects(nu=nu))
    assert report["finding"]["effect"] == "viscosity", report["candidates"]


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="PBF gas has no ambient air to hold a swirl in, so its swirling "
                   "particles fly outwards: at omega 15.4 rad/s the swirl search fits omega 8 on the training "
                   "frames and doubles the validation error (0.49 -> 0.98); oracle: only from a low-drag base "
                   "that the fit does not choose does a quarter to half of the generator's omega help (up to a third)")
def test_diagnose_finds_hidden_swirl(template, tmp_path, ti_engine):
    rng = np.random.default_rng(16)
    omega = rng.uniform(12.0, 18.0) * rng.choice([-1.0, 1.0])
    report = run_diagnose(template, tmp_path, PlumeEffects(omega=omega))
    assert report["finding"]["effect"] == "swirl", report["candidates"]


@pytest.mark.slow
def test_diagnose_two_effects_names_the_stronger(template, tmp_path, ti_engine):
    """Wind and dissipation together: the finding is the effect that changes the footage more (measured
    alone against the plain plume)."""
    rng = np.random.default_rng(17)
    speed, heading = rng.uniform(0.08, 0.14), rng.uniform(0, 2 * np.pi)
    wind = (speed * np.cos(heading), 0.0, speed * np.sin(heading))
    rate = rng.uniform(0.4, 0.9)
    plain = observe(template, tmp_path / "plain", PlumeEffects())
    vis = {"wind": visibility(template, tmp_path / "w", PlumeEffects(wind=wind), plain),
           "dissipation": visibility(template, tmp_path / "d", PlumeEffects(rate=rate), plain)}
    stronger = max(vis, key=vis.get)
    report = run_diagnose(template, tmp_path, PlumeEffects(wind=wind, rate=rate))
    assert report["finding"]["effect"] == stronger, (vis, report["candidates"])
    weaker = {c["effect"]: c for c in report["candidates"]}[min(vis, key=vis.get)]
    assert weaker["validate_after"] < weaker["validate_before"], report["candidates"]  # it helps too
