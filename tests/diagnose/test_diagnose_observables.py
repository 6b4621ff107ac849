"""The observation model and the selection test of diagnose on cases with known answers."""
from __future__ import annotations

import numpy as np
import pytest

from fluidnexus.camera import Camera
from fluidnexus.diagnose.observe import observables, splat_points, triangulate
from fluidnexus.diagnose.plume import PlumeParams
from fluidnexus.diagnose.search import Fit, Fitter, judge, search_spread


def cameras():
    target = np.array([0.3, 0.3, -0.2])
    return [Camera.look_at(48, 64, 60.0, target + 1.2 * np.array([np.cos(a), 0.0, np.sin(a)]), target)
            for a in (0.0, 1.2, 2.5)]


def test_triangulate_recovers_a_point_seen_by_three_cameras():
    p = np.array([0.35, 0.42, -0.18])
    cams = cameras()
    uv = np.array([c.project(p[None])[0][0] for c in cams])
    np.testing.assert_allclose(triangulate(cams, uv), p, atol=1e-9)


def test_observables_track_a_moving_blob():
    cams, fps = cameras(), 30.0
    rng = np.random.default_rng(0)
    blob = rng.normal(0.0, 0.01, (400, 3))
    centres = np.array([[0.3, 0.2 + 0.01 * t, -0.2 + 0.005 * t] for t in range(6)])
    images = np.array([[splat_points(c, blob + centres[t], np.ones(len(blob)), 1.0) for t in range(6)]
                       for c in cams])
    obs = observables(images, cams, fps)
    np.testing.assert_allclose(obs.centroid, centres + blob.mean(0), atol=4e-3)
    np.testing.assert_allclose(obs.intensity, 400.0, rtol=0.02)  # all of the blob is in view
    assert np.all(np.abs(obs.rise_speed[1:-1] - 0.3) < 0.1)  # front rises 1 cm per frame = 0.3 m/s


def test_judge_passes_a_clear_gain_and_refuses_noise():
    rng = np.random.default_rng(1)
    before = 0.5 + 0.05 * rng.random(30)
    assert judge(before, 0.6 * before).passes
    assert not judge(before, before).passes
    assert not judge(before, before * (1 + 0.05 * rng.normal(size=30))).passes


def test_search_spread_counts_base_fits_the_training_frames_cannot_tell_apart():
    train, validate = np.arange(4), np.arange(4, 6)
    fitter = Fitter(None, np.zeros((1, 6, 2, 2)), [], 1.0, train)

    def errors(tr, va):
        return np.array([tr] * 4 + [va] * 2, float)

    control = Fit(PlumeParams(), None, None, errors(0.10, 0.50))
    fitter.scored += [("paper_gas", (), control.errors),
                      ("paper_gas", (), errors(0.104, 0.40)),           # as good on training, 20 % better on validation
                      ("paper_gas", (), errors(0.20, 0.10)),            # better on validation, but not on training
                      ("paper_gas", ("swirl",), errors(0.09, 0.05)),    # an extension: not the base model
                      ("ambient_air", (), errors(0.10, 0.05))]          # the other structure: not this base model
    count, drop = search_spread(fitter, control, validate)
    assert count == 2 and drop == pytest.approx(0.2)
    # a control better on training than every scored base fit: nothing to compare, no spread
    assert search_spread(fitter, Fit(PlumeParams(), None, None, errors(0.05, 0.5)), validate) == (0, 0.0)


def test_gains_within_the_search_spread_are_named_with_the_footage_that_would_tell():
    """A candidate's gain no larger than the spread of equally good base fits is not told apart from the base
    model; the report says what footage would tell it (one hint per extension)."""
    from fluidnexus.diagnose.plume import EXTENSIONS
    from fluidnexus.diagnose.search import FOOTAGE_HINTS, Judgement, indistinct

    judged = {"wind": Judgement(1.0, 0.6, 0.40, 1e-6), "dissipation": Judgement(1.0, 0.85, 0.15, 1e-3),
              "swirl": Judgement(1.0, 1.1, -0.10, 0.9)}
    assert indistinct(judged, (5, 0.2)) == ["dissipation"]
    assert indistinct(judged, (5, 0.0)) == []
    assert set(FOOTAGE_HINTS) == set(EXTENSIONS)
