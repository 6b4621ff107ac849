"""Shared test options and fixtures.

Options:
    --arch cpu|cuda     Taichi arch for engine tests (default cpu).
    --ti-debug          start Taichi in debug mode (bounds-checked field access).
    --regen-golden      rewrite golden files instead of comparing against them.
"""
from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scalarflow_sim000000"


def pytest_addoption(parser):
    parser.addoption("--arch", default="cpu", choices=["cpu", "cuda"], help="Taichi arch for engine tests")
    parser.addoption("--ti-debug", action="store_true", help="run Taichi with bounds checks")
    parser.addoption("--regen-golden", action="store_true", help="rewrite golden files")


@pytest.fixture(scope="session")
def ti_engine(request):
    """Taichi started once for the whole session in float64 (gradient checks need it)."""
    from fluidnexus import engine

    engine.init(arch=request.config.getoption("--arch"), precision="f64",
                debug=request.config.getoption("--ti-debug"))
    return engine


@pytest.fixture(scope="session")
def regen_golden(request) -> bool:
    return request.config.getoption("--regen-golden")


@pytest.fixture(scope="session")
def shared_scalarflow() -> Path:
    """The full ScalarFlow capture in ../shared (skips where a machine has no ../shared)."""
    if not SHARED_DATA.exists():
        pytest.skip("../shared/data/scalarflow_sim000000 is not present on this machine")
    return SHARED_DATA


@pytest.fixture
def make_video():
    """``make_video(path, frames=4, width=16, height=12, channels=1, fps=30)`` writes a small H.264 MP4 of a
    moving gradient and returns its path."""
    import numpy as np

    from fluidnexus.video import write_video

    def make(path, frames=4, width=16, height=12, channels=1, fps=30.0):
        t = np.arange(frames, dtype=np.float32)[:, None, None, None]
        y = np.linspace(0, 1, height, dtype=np.float32)[None, :, None, None]
        x = np.linspace(0, 1, width, dtype=np.float32)[None, None, :, None]
        video = np.clip(0.5 * x + 0.3 * y + 0.05 * t, 0, 1) * np.ones((1, 1, 1, channels), np.float32)
        write_video(path, video, fps)
        return Path(path)

    return make
