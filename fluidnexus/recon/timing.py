"""Where a reconstruction spends its time: named wall-clock accumulators."""
from __future__ import annotations

import contextlib
import time
from collections import defaultdict


class Stopwatch:
    """Accumulates seconds per name; nested names are counted in each enclosing name too."""

    def __init__(self):
        self._totals = defaultdict(float)

    @contextlib.contextmanager
    def measure(self, name: str):
        tic = time.perf_counter()
        try:
            yield
        finally:
            self._totals[name] += time.perf_counter() - tic

    def totals(self) -> dict[str, float]:
        return {k: round(v, 3) for k, v in sorted(self._totals.items())}
