"""Every candidate extension at its null value reproduces the base model's rollout exactly, on both structures: a
candidate can only win by its term (no other difference on its path, during or after the training frames)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fluidnexus.diagnose.plume import EXTENSIONS, PlumeParams, PlumeSetup, PlumeSimulator, Rollout

from .eulerian_plume import Grid

BASES = {"paper_gas": PlumeParams(alpha=-0.3, k=3.0, layers=30.0),
         "ambient_air": PlumeParams(alpha=-0.15, c=0.4, inflow=0.3, structure="ambient_air")}


@pytest.fixture(scope="module")
def simulator(ti_engine):
    g = Grid()
    setup = PlumeSetup(g.source, g.source_radius, 0.03, g.fps, 14, tuple(np.asarray(g.source) - 0.3),
                       tuple(np.asarray(g.source) + 0.6), np.zeros((0, 3)), np.zeros((0, 3)))
    sim = PlumeSimulator(setup)
    return sim, {name: Rollout.start(sim.frames(p)) for name, p in BASES.items()}


def null_value(name: str, base: PlumeParams) -> dict:
    """The candidate's parameters with its term switched off: the defaults of EXTENSIONS, except the viscosity of
    the gas in ambient air, whose base has XSPH already (the candidate refits it from the base's c)."""
    if name == "viscosity" and base.structure == "ambient_air":
        return {"c": base.c}
    return dict(EXTENSIONS[name])


@pytest.mark.parametrize("structure", sorted(BASES))
@pytest.mark.parametrize("name", sorted(EXTENSIONS))
def test_a_null_candidate_reproduces_the_base(simulator, structure, name):
    sim, base_rollouts = simulator
    base = BASES[structure]
    ref = base_rollouts[structure]
    got = Rollout.start(sim.frames(replace(base, extensions={name: null_value(name, base)})))
    assert len(ref) == len(got) and len(ref.positions[-1]) > 0
    for a, b, ea, eb in zip(ref.positions, got.positions, ref.ages, got.ages):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(ea, eb)
