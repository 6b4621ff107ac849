"""diagnose's emission window: the scene's declared one, or when new smoke stops appearing at the source in the
footage (fluidnexus/diagnose/emission.py), and a simulated plume that emits only inside it."""
from __future__ import annotations

import numpy as np
import pytest

from fluidnexus.diagnose.emission import Emission, emission_window, start_from_footage, stop_from_footage
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


def test_start_from_footage_on_known_signals():
    fill = np.minimum(np.arange(30) / 11, 1.0)  # on from the first frame: the region takes 11 frames to fill
    assert start_from_footage(fill) == 0
    assert start_from_footage(0.8 + 0.2 * np.cos(np.arange(30))) == 0
    late = np.concatenate([np.zeros(9), np.minimum(np.arange(1, 22) / 4, 1.0)])  # new smoke from frame 9
    assert start_from_footage(late) == 9
    drift = late + np.concatenate([np.linspace(0, 0.2, 9), np.full(21, 0.2)])  # smoke drifting in before it
    assert start_from_footage(drift) == 9
    assert start_from_footage(np.concatenate([[0.0, 0.0], late[9:]])) == 0  # two empty frames are no late start
    assert start_from_footage(np.zeros(30)) == 0  # no smoke at the source at all: nothing to say


def _emission(template, folder, stop, window=None, start=0) -> Emission:
    scene = write_scene(template, folder, simulate(FRAMES, stop=stop, start=start), window=window)
    source = load_scene(scene).source
    return emission_window(source, load_observed(scene, 0, FRAMES, 40), source.center, source.radius)


@pytest.mark.parametrize("stop", [8, 12, 16, 24])
def test_footage_finds_when_a_burst_stops(template, tmp_path, stop):
    """A burst of the test generator (source on for frames [0, stop)) in a scene that does not declare it: the
    footage gives the stop (measured exact for 8-24)."""
    found = _emission(template, tmp_path / "burst", stop)
    assert found.source == "footage" and found.start == 0
    assert found.stop is not None and abs(found.stop - stop) <= 2, found


@pytest.mark.parametrize("start, stop", [(10, None), (20, None), (8, 30)])
def test_footage_finds_when_a_source_starts(template, tmp_path, start, stop):
    """A source switched on late (and a burst of it) in a scene that does not declare it: the footage gives the
    start (and the stop)."""
    found = _emission(template, tmp_path / "late", stop, start=start)
    assert found.source == "footage" and abs(found.start - start) <= 1, found
    assert (found.stop is None) if stop is None else abs(found.stop - stop) <= 2, found


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
        counts = np.array([len(p) for p, _ in sim.frames(params)])
        assert counts[3] > 0 and np.all(np.diff(counts[:4]) >= 0), (params.structure, counts)
        assert np.all(counts[4:] == counts[3]), (params.structure, counts)


def test_report_says_when_the_source_starts_and_stops():
    from fluidnexus.diagnose.report import _emission_text

    late = _emission_text(Emission(8, 30, "footage"), 0, 47)
    assert "first appears at the source at frame 8" in late and "after frame 29" in late
    assert "from frame 8 to frame 29 only" in late
    assert "first appears" not in _emission_text(Emission(0, None, "footage"), 0, 47)
    assert "from frame 10 on" in _emission_text(Emission(10, None, "footage"), 0, 47)
