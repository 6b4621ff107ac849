"""Small datasets shipped inside the package, loaded by name (``--sample scalarflow``).

Each sample is a folder ``fluidnexus/samples/<name>/`` holding its videos, an ``info.json`` and a ``README.md``
with its licence. Known samples:

- ``scalarflow``: the real ScalarFlow smoke plume sim_000000, 5 views x 120 frames at 1/4 resolution
  (270 x 480, 30 fps, gray on black), PINF camera metadata in ``info.json``. CC BY-NC-SA 4.0, see its README.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import InputError

SAMPLES_DIR = Path(__file__).resolve().parent


def sample_names() -> list[str]:
    """Names of the samples installed with the package (folders holding an ``info.json``)."""
    return sorted(p.name for p in SAMPLES_DIR.iterdir() if (p / "info.json").is_file())


def sample_path(name: str) -> Path:
    """The folder of the sample called ``name``.

    Raises:
        InputError: no sample has that name (field ``--sample``); the message lists the known ones.
    """
    known = sample_names()
    if name not in known:
        raise InputError(None, "--sample", f"unknown sample {name!r}; known samples: {', '.join(known)}")
    return SAMPLES_DIR / name
