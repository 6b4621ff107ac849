"""Options shared by several commands."""
from __future__ import annotations

import click
import numpy as np

from fluidnexus.errors import InputError

arch_option = click.option("--arch", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
                           help="Where the Taichi engine runs.")

max_memory_option = click.option(
    "--max-memory", default="auto", show_default=True,
    help="Refuse to start when the run's estimated memory is above this (e.g. 8G, 1500M); "
         "auto: 80 % of the memory available now.")


def start_engine(arch: str) -> str:
    """Resolve ``--arch`` and start the engine (float32); returns the arch used.

    An engine already running on that arch in this process (e.g. under the test suite) is used as it is.
    The engine (taichi, torch) is imported here, so that importing a command stays light.
    """
    from fluidnexus import engine

    resolved = engine.resolve_arch(arch)
    try:
        if engine.is_running(resolved):
            return resolved
        engine.init(arch=resolved)
    except RuntimeError as err:  # e.g. --arch cuda on a machine without a usable GPU
        raise InputError(None, "--arch", f"cannot start the engine on {resolved}: {err}") from None
    return resolved


def parse_color(text: str | None, option: str) -> np.ndarray | None:
    """``R,G,B`` with each value in [0, 1] (an ``option`` such as ``--color``); None when not given."""
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in text.split(",")], np.float32)
    except ValueError:
        values = np.array([])
    if values.shape != (3,) or not np.all(np.isfinite(values)) or values.min() < 0 or values.max() > 1:
        raise InputError(None, option, f"expected R,G,B with each value in [0, 1] (e.g. 1,1,1 for white), "
                                       f"got {text!r}")
    return values
