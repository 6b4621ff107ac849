"""diagnose's emission window: the scene's declared one, or when new smoke stops appearing at the source in the
footage (fluidnexus/diagnose/emission.py), and a simulated plume that emits only inside it."""
from __future__ import annotations

import numpy as np
import pytest

from fluidnexus.diagnose.emission import Emission, emission_window, stop_from_footage
from fluidnexus.diagnose.plume import PlumeParams, PlumeSetup, PlumeSimulator
from fluidnexus.diagnose.run import load_observed
from fluidnexus.scene import load_scene

from .eulerian_plume import Grid, simulate, write_scene

FRAMES = 48


def test_stop_from_footage_on_known_signals():
    fill = np.minimum(np.arange(30) / 11, 1.0)  # the region fills until frame 11
    assert stop_from_footage(fill) is None  # filled and replenished to the end
    assert stop_from_footage(0.8 + 0.2 * np.cos(np.arange(30))) is None  # fluctuating, never empty
    burst = np.concatenate([fill[:12], np.exp(-np.arange(1, 19) / 4.0)])  # fills, peaks at frame 11, empties
    assert stop_from_footage(burst) == 12
    dark_end = fill.copy()
    dark_end[-1] = 0.1  # one dark last frame is not a stop
    assert stop_from_footage(dark_end) is None
    assert stop_from_footage(np.zeros(30)) is None  # no smoke at the source at all: nothing to say


def _emission(template, folder, stop, window=None) -> Emission:
    scene = write_scene(template, folder, simulate(FRAMES, stop=stop), window=window)
    source = load_scene(scene).source
    return emission_window(source, load_observed(scene, 0, FRAMES, 40), source.center, source.radius)


@pytest.mark.parametrize("stop", [8, 12, 16, 24])
def test_footage_finds_when_a_burst_stops(template, tmp_path, stop):
    """A burst of the test generator (source on for frames [0, stop)) in a scene that does not declare it: the
    footage gives the stop (measured exact for 8-24)."""
    found = _emission(template, tmp_path / "burst", stop)
    assert found.source == "footage" and found.start == 0
    assert found.stop is not None and abs(found.stop - stop) <= 2, found


def test_a_continuous_plume_emits_to_the_end(template, tmp_path):
    assert _emission(template, tmp_path / "plain", None) == Emission(0, None, "footage")


def test_a_declared_window_is_used_as_declared(template, tmp_path):
    """The scene's ``source.window`` wins over the footage (here it even contradicts it)."""
    assert _emission(template, tmp_path / "declared", None, window=(0, 20)) == Emission(0, 20, "scene")
    assert _emission(template, tmp_path / "open", 12, window=(0, None)) == Emission(0, None, "scene")


def test_the_simulated_plume_emits_only_inside_the_window(ti_engine):
    """Both structures: the smoke particle count grows while the window is open and not after it."""
    g = Grid()
    emitting = np.arange(10) < 4
    setup = PlumeSetup(g.source, g.source_radius, 0.03, g.fps, 10, tuple(np.asarray(g.source) - 0.3),
                       tuple(np.asarray(g.source) + 0.6), np.zeros((0, 3)), np.zeros((0, 3)), emitting=emitting)
    sim = PlumeSimulator(setup)
    for params in (PlumeParams(alpha=-0.3, k=3.0, layers=30.0), PlumeParams(alpha=-0.15, c=0.4, inflow=0.3,
                                                                            structure="ambient_air")):
        counts = np.array([len(p) for p in sim.rollout(params).positions])
        assert counts[3] > 0 and np.all(np.diff(counts[:4]) >= 0), (params.structure, counts)
        assert np.all(counts[4:] == counts[3]), (params.structure, counts)
