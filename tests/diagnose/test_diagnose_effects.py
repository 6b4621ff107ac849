"""diagnose finds an effect hidden in data made by a different solver (tests/diagnose/eulerian_plume.py).

Each test hides one effect (or two) at a magnitude drawn from a seeded range, runs diagnose on 48 frames (train
0:32, validate 32:48; the burst 90 frames, 0:60 and 60:90) and requires the right name. Each diagnose fits both
model structures and tries the candidates on the paper's gas and, where the air passes, on the air too, its fits
side by side in as many processes as there are cores (``--jobs``, at most 6), and refits a term that passes with
three times the rollouts (run.confirm): this file's fast tier about 430 s in one process on the 2-core VM of
2026-12-02 (the dissipation 178 s, entrainment 95, the plain plume 88, the paper's-gas control 58; BENCHMARKS.md,
"Diagnose: a model already scored is not rolled out again"). ``make test`` runs the fast tier (the plain plume, the
paper's-gas control, entrainment in the paper's gas, dissipation) and the visibility test; ``make test-slow`` runs
the rest (the wind among them: 422 s alone). Buoyancy decay, vorticity confinement, viscosity
and swirl are ``xfail``: their data differ from a plain plume with the same generator constants
(``test_hidden_effects_are_visible``), but diagnose does not name them. Buoyancy decay cannot be named from this
footage by any model: a plain plume with weaker buoyancy matches its training frames
(``test_nearest_plain_plume_on_the_training_frames``). In a burst (the source on for the first part of the window
only) it can (``test_nearest_plain_plume_in_a_burst``), and diagnose names it there, but with a tau 3x too long
(xfail). The measured reasons are in each marker and in BENCHMARKS.md ("Diagnose: designs measured and not kept").
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import optimize

from fluidnexus.diagnose.observe import image_error
from fluidnexus.diagnose.run import load_observed

from .eulerian_plume import Grid, PlumeEffects, simulate, write_scene
from .pbf_plume import simulate_pbf

ROOT = Path(__file__).resolve().parents[2]
FRAMES, TRAIN, VALIDATE = 48, "0:32", "32:48"
FAST = ["--height", "40", "--arch", "cpu"]
EVALS = 10  # rollouts per fit here; the CLI's default is 20 (the wind needs it)


def run_diagnose(template, tmp_path, effects: PlumeEffects, evals: int = EVALS) -> dict:
    return diagnose_density(template, tmp_path, simulate(FRAMES, effects), evals=evals)


def diagnose_density(template, tmp_path, density: np.ndarray, train: str = TRAIN, validate: str = VALIDATE,
                     window: tuple | None = None, evals: int = EVALS) -> dict:
    """Diagnose a scene of ``density`` [T, nx, ny, nz] on the generator's grid (``window``: the emission window
    the scene declares, None: none, and then the source must be on to the end) on the ``train`` and ``validate``
    frames; checks the outputs' form."""
    scene = write_scene(template, tmp_path / "scene", density, window=window)
    out = tmp_path / "diag"
    # in its own process, as a user runs it: the engine in float32 (the suite's runs in float64, and the wind
    # plume's structure gain sits at the bar: 22.5 % in float32, 19.6 % in float64; docs/diagnose.md)
    result = subprocess.run([sys.executable, "-m", "fluidnexus_cli", "diagnose", str(scene), "--out", str(out),
                             "--train-frames", train, "--validate-frames", validate, "--evals", str(evals), *FAST],
                            cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    report = json.loads((out / "report.json").read_text())
    assert set(report) == {"finding", "candidates", "windows", "views", "emission", "structure", "explanations",
                           "width_slope", "confirmation"}
    # a term holds when refitted with three times the rollouts (run.confirm); nothing is refitted without one
    confirmed = report["confirmation"]
    if confirmed is None:
        assert report["finding"]["effect"] == "none", report["finding"]
    else:
        assert confirmed["evals"] == 3 * evals, confirmed
        held = {(r["structure"], r["effect"]) for r in confirmed["explanations"] if r["holds"]}
        assert all(e["effect"] == "none" or (e["structure"], e["effect"]) in held for e in report["explanations"]), \
            (confirmed, report["explanations"])
    assert report["explanations"][0]["structure"] == report["structure"]["name"]
    assert report["explanations"][0]["effect"] == report["finding"]["effect"]
    assert report["structure"]["name"] in ("paper_gas", "ambient_air")
    model_file = json.loads((out / "model.json").read_text())
    assert model_file["model"]["structure"]["name"] == report["structure"]["name"]
    assert report["windows"] == {"train": [int(x) for x in train.split(":")],
                                 "validate": [int(x) for x in validate.split(":")]}
    # a declared window is used as declared; every plume here without one is continuous: no false stop
    assert report["emission"] == ({"window": list(window), "from": "scene"} if window else
                                  {"window": [0, None], "from": "footage"}), report["emission"]
    assert [model_file["source"][k] for k in ("window", "window_from")] == list(report["emission"].values())
    assert len(report["views"]) == 5
    assert {c["effect"] for c in report["candidates"]} == {"wind", "buoyancy_decay", "vorticity", "viscosity",
                                                           "dissipation", "swirl"} | (
        {"entrainment"} if report["structure"]["name"] == "paper_gas" else set())
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


def observe(template, folder, effects: PlumeEffects, grid: Grid = Grid(), frames: int = FRAMES,
            stop: int | None = None) -> np.ndarray:
    """Images [V, T, h, w] of a generated plume (``stop``: a burst, eulerian_plume.simulate) at diagnose's
    observation size."""
    scene = write_scene(template, folder, simulate(frames, effects, grid, stop), grid)
    return load_observed(scene, 0, frames, int(FAST[1])).images


def nearest_plain_plume(template, folder, images: np.ndarray, evals: int = 14, train: int = 32,
                        stop: int | None = None) -> tuple[float, float]:
    """How well a plume WITHOUT any effect can imitate ``images`` [V, T, h, w]: the generator's own buoyancy and
    inflow speed refitted on the training frames [0, ``train``) (Nelder-Mead over log factors, brightness gain in
    closed form), as diagnose fits its model; with ``stop`` the plain plume is the same burst. Returns the image
    errors (observe.image_error) of the best such plain plume on the training and on the validation frames (the
    rest). A training error near 0 means that no fit on the training frames can tell the effect from a change of
    the base parameters, whatever the model."""
    frames = images.shape[1]
    train, val = slice(0, train), slice(train, frames)
    best = [np.inf, np.inf]

    def loss(x):
        grid = Grid(buoyancy=Grid.buoyancy * float(np.exp(x[0])), inflow_speed=Grid.inflow_speed * float(np.exp(x[1])))
        plain = observe(template, folder, PlumeEffects(), grid, frames, stop)
        gain = (images[:, train] * plain[:, train]).sum() / (plain[:, train] ** 2).sum()
        err = image_error(images, gain * plain)
        if err[train].mean() < best[0]:
            best[:] = [float(err[train].mean()), float(err[val].mean())]
        return err[train].mean()

    optimize.minimize(loss, [0.0, 0.0], method="Nelder-Mead",
                      options={"initial_simplex": [[0.0, 0.0], [0.3, 0.0], [0.0, 0.3]], "maxfev": evals})
    return best[0], best[1]


#: Effects at the weak end of each test's seeded range below (seeded values are drawn inside these ranges).
WEAKEST = {"wind": PlumeEffects(wind=(0.08, 0.0, 0.0)), "dissipation": PlumeEffects(rate=0.4),
           "buoyancy_decay": PlumeEffects(tau=1.0), "vorticity": PlumeEffects(epsilon=10.0),
           "viscosity": PlumeEffects(nu=2e-3), "swirl": PlumeEffects(omega=12.0)}


def test_hidden_effects_are_visible(template, tmp_path):
    """Every hidden effect, at the weak end of its test's range, changes the validation footage at least as
    much as dissipation at the weak end of the range that diagnose must find in CI (measured 0.24 wind, 0.042
    dissipation, 0.12 decay, 0.15 vorticity, 0.11 viscosity, 0.27 swirl). This compares with the plain plume
    at the same generator constants; whether a fit can tell an effect from other constants is the question of
    ``test_nearest_plain_plume_on_the_training_frames``."""
    plain = observe(template, tmp_path / "plain", PlumeEffects())
    vis = {name: visibility(template, tmp_path / name, e, plain) for name, e in WEAKEST.items()}
    assert vis["dissipation"] > 0.03, vis
    assert all(v >= vis["dissipation"] for v in vis.values()), vis
    # an effect that is switched off changes nothing
    assert visibility(template, tmp_path / "off", PlumeEffects(), plain) < 1e-9


def test_diagnose_plain_plume_finds_none(template, tmp_path):
    """A plain grid plume rises in air: the gas in ambient air is the structure, and no term is found. The grid
    plume entrains physically; the paper's gas with entrainment is a candidate but loses (2026-11-26: validation
    error 0.647 with alpha 0.14, against 0.504 for the paper's gas and 0.259 in ambient air; the grid solver's
    inflow drives the air around the plume, which the air's inlet moves and entrainment cannot)."""
    report = run_diagnose(template, tmp_path, PlumeEffects())
    assert report["structure"]["name"] == "ambient_air", report["structure"]
    assert report["finding"]["effect"] == "none", report["candidates"]


def test_diagnose_pbf_gas_control_keeps_paper_gas(template, tmp_path, ti_engine):
    """The control: a plume made by the paper's PBF gas itself (tests/diagnose/pbf_plume.py: a finer lattice,
    jittered inflow) keeps the paper's gas as the structure, and no term is found."""
    report = diagnose_density(template, tmp_path, simulate_pbf(FRAMES))
    assert report["structure"]["name"] == "paper_gas", report["structure"]
    assert report["finding"]["effect"] == "none", report["candidates"]


def test_diagnose_finds_entrainment_in_the_paper_gas(template, tmp_path, ti_engine):
    """The paper's PBF gas on diagnose's own lattice (0.02 m) with a known entrainment coefficient 0.12
    (pbf_plume.py: jittered source and inflow, 6 solver iterations): ``entrainment`` named, on the paper's gas, the
    simulated width-against-height slope within 25 % of the observed one (measured +12 %), the coefficient within
    30 % (measured 0.124, +4 %, the buoyancy fitted with it -0.065 against the generator's -0.04; 2026-11-26). The
    footage pins the coefficient no closer: fitted with the buoyancy, drag and source rate refitted at fixed
    coefficients, the training error is flat within its noise over 0.09-0.135 here and over 0.08-0.20 on a plume
    of 0.16, whose coefficient comes out 0.114 (-29 %; BENCHMARKS.md "Entrainment")."""
    report = diagnose_density(template, tmp_path, simulate_pbf(FRAMES, entrainment=0.12, spacing=0.02))
    assert report["structure"]["name"] == "paper_gas", report["structure"]
    assert report["finding"]["effect"] == "entrainment", report["candidates"]
    assert abs(report["finding"]["params"]["alpha"] - 0.12) < 0.30 * 0.12, report["finding"]
    slope = report["width_slope"]
    assert abs(slope["chosen"] - slope["observed"]) < 0.25 * slope["observed"], slope


@pytest.mark.slow  # 422 s alone with its confirmation (2026-11-29; 100 s before it): the slow tier
def test_diagnose_finds_hidden_wind(template, tmp_path):
    """At the CLI's default budget (20 rollouts per fit; at 10 and 14 the base fit is not converged and the speed
    comes out 43-69 % high: BENCHMARKS.md, "Re-measured with the structure level"). The gas in air is the
    structure (22.5 % better than the paper's gas on the validation frames, 0.645 against 0.832; in the suite's
    float64 engine it was 19.6 %, under the bar: hence diagnose in its own process) and the wind is found on it."""
    rng = np.random.default_rng(11)
    speed, heading = rng.uniform(0.08, 0.14), rng.uniform(0, 2 * np.pi)
    wind = np.array([speed * np.cos(heading), 0.0, speed * np.sin(heading)])
    report = run_diagnose(template, tmp_path, PlumeEffects(wind=tuple(wind)), evals=20)
    assert report["structure"]["name"] == "ambient_air", report["structure"]
    assert report["finding"]["effect"] == "wind", report["candidates"]
    v = np.asarray(report["finding"]["params"]["velocity"])
    cos = v @ wind / (np.linalg.norm(v) * speed)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 25, (v, wind)
    assert abs(np.linalg.norm(v) - speed) < 0.4 * speed, (v, wind)
    assert report["finding"]["gain"]["after"] < report["finding"]["gain"]["before"]


def test_diagnose_finds_hidden_dissipation(template, tmp_path):
    """Named on either structure: the structure and the term are decided together (run.explain), so the air's
    base fit cannot absorb the fading and hide the term."""
    rate = np.random.default_rng(12).uniform(0.4, 0.9)
    report = run_diagnose(template, tmp_path, PlumeEffects(rate=rate))
    assert report["finding"]["effect"] == "dissipation", report["candidates"]
    assert abs(report["finding"]["params"]["rate"] - rate) < 0.4 * rate, (report["finding"], rate)


# ---------------------------------------------------------------- slow tier: the other effects
# The xfail reasons are measured on these tests' own draws (BENCHMARKS.md, "Effects diagnose does not find").
# "Nearest plain plume" is nearest_plain_plume: the generator without the effect, its buoyancy and inflow
# refitted on the training frames (training / validation image error). Common to all: the base fit lands in a
# high-drag regime (k 17-44 1/s, 22-33 layers/s) where the PBF plume is pushed up by its source, and its
# validation error follows its training error poorly.


def decay_tau() -> float:
    """The buoyancy decay test's seeded draw: tau [s] in 0.5-1.0."""
    return float(np.random.default_rng(13).uniform(0.5, 1.0))


def swirl_omega() -> float:
    """The swirl test's seeded draw: omega [rad/s], 12-18 with a random sign."""
    rng = np.random.default_rng(16)
    return float(rng.uniform(12.0, 18.0) * rng.choice([-1.0, 1.0]))


@pytest.mark.slow
@pytest.mark.parametrize("effects, identifiable", [(PlumeEffects(tau=decay_tau()), False),
                                                   (PlumeEffects(omega=swirl_omega()), True)],
                         ids=["buoyancy_decay", "swirl"])
def test_nearest_plain_plume_on_the_training_frames(template, tmp_path, effects, identifiable):
    """Can the training footage of a hidden effect be told from a plume without any effect at all? The closest
    plain plume is the generator itself with its buoyancy and inflow speed refitted on the training frames
    (nearest_plain_plume). Buoyancy decay (the decay test's draw, tau 0.93 s) is matched to an image error below
    2e-3 (measured 7e-4 with 14 evaluations, 1e-4 with 30, at 0.67-0.75x the buoyancy) and stays within 0.03 on
    the validation frames (measured 0.003-0.015): a plume whose buoyancy decays looks like a plume with less
    buoyancy, so no fit on the training frames can name the decay, whatever the model. Swirl (the swirl test's
    draw, 15.4 rad/s) is not matched (measured 0.11), so the measurement does tell effects apart."""
    images = observe(template, tmp_path / "effect", effects)
    train_err, val_err = nearest_plain_plume(template, tmp_path / "plain", images)
    if identifiable:
        assert train_err > 0.05, (train_err, val_err)
    else:
        assert train_err < 2e-3 and val_err < 0.03, (train_err, val_err)


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="not identifiable from this footage by any model: a plain plume with "
                   "0.67-0.75x the buoyancy matches the tau = 0.93 s plume to an image error of 1e-4 to 7e-4 on the "
                   "training frames and 0.003-0.015 on the validation frames (test_nearest_plain_plume_on_the_"
                   "training_frames); the decay search fits tau 0.53 s and raises the validation error by 41 % "
                   "(finding: none; wind gains 17.1 % at 1.6 cm/s, under the 20 % bar)")
def test_diagnose_finds_hidden_buoyancy_decay(template, tmp_path):
    tau = decay_tau()
    report = run_diagnose(template, tmp_path, PlumeEffects(tau=tau))
    assert report["finding"]["effect"] == "buoyancy_decay", report["candidates"]
    assert abs(report["finding"]["params"]["tau"] - tau) < 0.4 * tau, (report["finding"], tau)


# A burst: the source on for frames [0, BURST_STOP) only, then the puff rises on its own; diagnose's default
# windows (train 0:60, validate 60:90), so that most frames follow the stop (docs/diagnose.md, "Bursts").
BURST_FRAMES, BURST_STOP, BURST_TRAIN = 90, 24, 60


@pytest.mark.slow
def test_diagnose_burst_without_effect_finds_none(template, tmp_path):
    """A plain burst (the source stops at frame 24, nothing hidden; train 0:60, validate 60:90): no term is named.
    (A burst from another grid solver once got the gas in ambient air plus a 6 mm/s wind, whose training error was
    higher than the control's: search.Judgement.passes.)"""
    density = simulate(BURST_FRAMES, PlumeEffects(), stop=BURST_STOP)
    report = diagnose_density(template, tmp_path, density, f"0:{BURST_TRAIN}", f"{BURST_TRAIN}:{BURST_FRAMES}",
                              window=(0, BURST_STOP))
    assert report["finding"]["effect"] == "none", report["candidates"]


@pytest.mark.slow
def test_nearest_plain_plume_in_a_burst(template, tmp_path):
    """In a burst, buoyancy decay is told apart from a weaker buoyancy once the source stops: the closest plain
    burst (nearest_plain_plume, buoyancy and inflow refitted on frames 0:60; 24 evaluations, 14 stop short at a
    training error of 0.010) still matches the training frames closely (measured 0.0055; the continuous decay plume
    1e-4 to 7e-4 over 48 frames and 0.002 over 90) but misses the validation frames by 0.086 (continuous:
    0.003-0.015, 0.011 over 90 frames)."""
    images = observe(template, tmp_path / "effect", PlumeEffects(tau=decay_tau()), frames=BURST_FRAMES,
                     stop=BURST_STOP)
    train_err, val_err = nearest_plain_plume(template, tmp_path / "plain", images, evals=24, train=BURST_TRAIN,
                                             stop=BURST_STOP)
    assert train_err < 0.01 and val_err > 0.04, (train_err, val_err)


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="named but tau 2.9-3.4x too long (2026-11-24): the finding is "
                   "buoyancy_decay (validation gain 35.4 %, 46.1 % at 14 evaluations; the same burst without decay: "
                   "decay stays off, +0.2 %), but tau 2.67 s (3.2 s) for 0.93: the air structure's base fit takes an "
                   "inlet of 0.52 m/s (the generator's 0.25) in XSPH c 0.45 with alpha -0.08, so part of the slowing "
                   "is the inlet's momentum running out in viscous air and the decay refitted on top (with alpha "
                   "alone) is slower. Not the budget: at 20 evaluations tau 5.4 s (gain 35.9 %, vorticity 33.2 %). "
                   "Not the training window either (2026-11-25): over all 90 frames the air model fits best with that "
                   "inlet and tau 1.6-3.2 s (image error 0.089), the generator's inlet and tau give 0.099. With the "
                   "generator's inlet declared tau is 0.73 s, but the same burst without decay then names decay too "
                   "(tau 3.2 s, 25.7 %); with the inlet refitted in the decay candidate the decay stays off (10 "
                   "evaluations) or tau 5.8 s (20): the air model's puff does not slow like the grid solver's. "
                   "An air model whose smoke mixes and whose inlet's flux is exact (2026-11-26, not kept) fits the "
                   "training frames without decay (0.040 against 0.148 with the old inlet) and names none: the "
                   "window 0:60 does not pin the decay (BENCHMARKS.md, the eighth design)")
def test_diagnose_finds_buoyancy_decay_in_a_burst(template, tmp_path):
    """Hidden buoyancy decay (the decay test's draw, tau 0.93 s) in a burst whose scene declares its emission
    window: diagnose's plumes emit in it too (diagnose_density checks report.json's ``emission``), and it names
    ``buoyancy_decay`` with tau within 40 %."""
    tau = decay_tau()
    density = simulate(BURST_FRAMES, PlumeEffects(tau=tau), stop=BURST_STOP)
    report = diagnose_density(template, tmp_path, density, f"0:{BURST_TRAIN}", f"{BURST_TRAIN}:{BURST_FRAMES}",
                              window=(0, BURST_STOP))
    assert report["finding"]["effect"] == "buoyancy_decay", report["candidates"]
    assert abs(report["finding"]["params"]["tau"] - tau) < 0.4 * tau, (report["finding"], tau)


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="with the structure level (2026-11-24, 10 evaluations): the structure is "
                   "paper_gas (the air's validation error 0.334 against 0.197) and the finding none: confinement "
                   "(epsilon 0.01) raises the validation error by 10.7 %, and base fits within 5 % of the control's "
                   "training error differ by 20.5 % in validation error. The grid's confinement slows the plume "
                   "without widening it, the PBF term widens it without slowing it: less buoyancy explains it better")
def test_diagnose_finds_hidden_vorticity(template, tmp_path):
    epsilon = np.random.default_rng(14).uniform(10.0, 14.0)
    report = run_diagnose(template, tmp_path, PlumeEffects(epsilon=epsilon))
    assert report["finding"]["effect"] == "vorticity", report["candidates"]


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="with the structure level (2026-11-24, 10 evaluations): the structure is "
                   "ambient_air (validation error 0.246 -> 0.101, 59 %), whose XSPH (c 0.33) already takes the extra "
                   "momentum loss to still air; the viscosity candidate (c 0.39) gains 3.4 % and dissipation 8.5 %, "
                   "both under the 20 % a finding needs: none. Barely identifiable (the nearest plain plume matches "
                   "the training frames to 0.004)")
def test_diagnose_finds_hidden_viscosity(template, tmp_path):
    nu = np.random.default_rng(15).uniform(2e-3, 4e-3)
    report = run_diagnose(template, tmp_path, PlumeEffects(nu=nu))
    assert report["finding"]["effect"] == "viscosity", report["candidates"]


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="with the structure level (2026-11-24, 10 evaluations): the structure is "
                   "ambient_air (validation error 0.589 -> 0.356, 39.5 %); the swirl search reaches omega 5.0 from 0 "
                   "(hidden 15.4 rad/s) and gains 7.9 %, while a wind of 0.073 m/s gains 24.8 % and is named: with "
                   "the paper's gas swirled particles left in an open cone (validation error doubled); in the air "
                   "swirl helps, but the footage's swirl is explained better by a drift")
def test_diagnose_finds_hidden_swirl(template, tmp_path):
    report = run_diagnose(template, tmp_path, PlumeEffects(omega=swirl_omega()))
    assert report["finding"]["effect"] == "swirl", report["candidates"]


@pytest.mark.slow
def test_diagnose_two_effects_names_the_stronger(template, tmp_path):
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
