"""A tiny reconstruction setting shared by the recon, render, eval and export tests."""
from __future__ import annotations

import pytest

from clirun import invoke, ok  # noqa: F401  (re-exported to the tests of this folder)

TINY = ["--frames", "0:3", "--resolution", "0.25", "--init-iters", "4", "--dynamics-iters", "2",
        "--appearance-iters", "2", "--stabilization-steps", "2", "--arch", "cpu"]


@pytest.fixture(scope="session")
def four_view_scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene") / "four"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--out", out)
    return out


@pytest.fixture(scope="session")
def tiny_run(four_view_scene, tmp_path_factory, ti_engine):
    """A 3-frame reconstruction of the sample at 68x120 with a handful of iterations."""
    out = tmp_path_factory.mktemp("runs") / "tiny"
    ok("recon", four_view_scene, "--out", out, *TINY)
    return out
