"""The one progress helper: a rich progress bar on a terminal, periodic log lines elsewhere."""
from __future__ import annotations

import contextlib
import logging
import sys
import time
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")
log = logging.getLogger("fluidnexus")


class Progress:
    """A running task: ``advance()`` it, ``status(**numbers)`` to show the current losses."""

    def __init__(self, bar, task, total: int, label: str):
        self._bar, self._task, self.total, self.label = bar, task, total, label
        self.done = 0
        self.start = time.perf_counter()
        self._last_log = self.start
        self._status = ""

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def status(self, **numbers: float) -> None:
        self._status = "  ".join(f"{k}={v:.4g}" for k, v in numbers.items())
        if self._bar is not None:
            self._bar.update(self._task, status=self._status)

    def advance(self, n: int = 1) -> None:
        self.done += n
        if self._bar is not None:
            self._bar.update(self._task, advance=n)
        elif time.perf_counter() - self._last_log > 10 or self.done == self.total:
            self._last_log = time.perf_counter()
            log.info("%s %d/%d (%.0f s) %s", self.label, self.done, self.total, self.elapsed, self._status)


@contextlib.contextmanager
def progress(label: str, total: int, enabled: bool | None = None) -> Iterator[Progress]:
    """Show progress of ``total`` units of work.

    A bar with elapsed time and the latest ``status`` numbers on an interactive stderr; otherwise (CI, logs)
    an INFO log line at most every 10 s. ``enabled=False`` silences the bar (log lines remain).
    """
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        yield Progress(None, None, total, label)
        return
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
    from rich.progress import Progress as RichProgress

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
               TextColumn("{task.fields[status]}"))
    with RichProgress(*columns, transient=False) as bar:
        task = bar.add_task(label, total=total, status="")
        yield Progress(bar, task, total, label)


def track(items: Iterable[T], label: str, total: int | None = None) -> Iterator[T]:
    """Iterate ``items`` while showing progress."""
    items = list(items) if total is None else items
    with progress(label, total if total is not None else len(items)) as p:
        for item in items:
            yield item
            p.advance()
