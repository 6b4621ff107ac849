"""One error type for bad user input.

Every problem with what a user hands the tool (a file, a field in it, a command-line value) is raised as
:class:`InputError`, which names the file and the field. The CLI prints it as one line and exits with code 2.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


class InputError(Exception):
    """Bad input, located by file and field.

    Args:
        path: the file or folder the bad value came from (None for a command-line value).
        field: the field inside it, e.g. ``views[2].camera.K`` or ``--frames``.
        message: what is wrong, in plain words.
    """

    def __init__(self, path: str | Path | None, field: str | None, message: str):
        self.path = None if path is None else str(path)
        self.field = field
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        where = [p for p in (self.path, self.field) if p]
        return ": ".join(where + [self.message])

    def at(self, path: str | Path | None = None, prefix: str | None = None) -> "InputError":
        """Return a copy located in ``path`` with ``prefix`` put before the field name."""
        field = self.field
        if prefix:
            field = f"{prefix}.{field}" if field else prefix
        return InputError(path if path is not None else self.path, field, self.message)


def require_finite(value, path, field: str) -> np.ndarray:
    """Return ``value`` as a float64 array, or raise if any entry is NaN or infinite."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(path, field, f"expected numbers, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise InputError(path, field, "contains non-finite values (NaN or inf)")
    return arr


def require_positive(value: float, path, field: str) -> float:
    """Return ``value`` as float, or raise if it is not a finite number > 0."""
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise InputError(path, field, f"must be a finite number > 0, got {value!r}")
    return v


class RunError(Exception):
    """A long run stopped on its own (divergence, a full disk); the message says what was kept.

    The CLI prints it as one line and exits with code 1.
    """
