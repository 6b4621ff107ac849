"""Diagnose's independent fits side by side (``diagnose --jobs N``).

The base fits of the two structures do not depend on each other, and the candidates' refits on the chosen base do
not either: each is one task. With one job the tasks run here, in order. With more, that many worker processes
start (spawned: a forked Taichi runtime is not safe), each with the engine started as in this process and its own
plume simulator and fitter built from the same inputs; a rollout does not depend on the process it runs in, so the
report does not depend on ``jobs`` (a test compares). A task can be started before earlier ones have finished (the
paper's gas's candidates while the gas in ambient air is still being fitted); every model a worker scored comes back
with its task's result, and results are collected in the order the tasks were started, so the fits join the
fitter's record in the order of a serial run and the search spread (``search.search_spread``) sees the same fits.
The workers stay for the confirmation's refits (``FitPool.renew``): a worker's start (imports, Taichi, the
kernels loaded) costs several seconds.

The training errors of the models scored (``Fitter.known``) are handed on, so that a search does not roll out a
model already scored: each task sees those of the tasks whose results were collected before it was started, with
one job as with several, so which models are rolled out does not depend on ``jobs`` either.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

from fluidnexus.memory import RUNTIME_BYTES, Estimate, check

from .plume import PlumeSimulator
from .search import Fitter

#: Most worker processes worth starting: one base fit per structure, then at most six candidates at once.
MAX_JOBS = 6

_fitter: Fitter | None = None  # a worker's own fitter
_phase = 0  # the phase (FitPool.renew) of the worker's fitter


def plan_jobs(requested: int | None, arch: str, limit: int) -> int:
    """``--jobs``: the number given, or by default on the CPU the cores this process may use (at most
    :data:`MAX_JOBS`) and no more workers than fit under ``limit`` bytes, on a GPU 1 (several processes sharing one
    GPU are not measured). Each worker holds a runtime of its own (``memory.RUNTIME_BYTES``; the plume's fields are
    small beside it). A number given that does not fit is refused (InputError naming ``--jobs``)."""
    if requested is None:
        if arch != "cpu":
            return 1
        try:
            cores = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            cores = os.cpu_count() or 1
        fit = int(limit // RUNTIME_BYTES) - 1  # this process's runtime first
        return max(1, min(MAX_JOBS, cores, fit))
    estimate = Estimate("diagnose")
    if requested > 1:
        estimate.add("worker processes", requested * RUNTIME_BYTES, "--jobs")
    check(estimate, limit)
    return requested


class FitPool:
    """Runs fit tasks ``fn(fitter, *args)`` (module-level functions) for ``fitter``, in ``jobs`` processes.

    Use as a context manager; the workers start on entry and stop on exit.
    """

    def __init__(self, fitter: Fitter, jobs: int):
        if jobs < 1:
            raise ValueError(f"jobs must be at least 1, got {jobs}")
        self.fitter, self.jobs = fitter, jobs
        self._pool: ProcessPoolExecutor | None = None
        self._phase = 0
        #: the training errors of the models scored by the tasks collected so far (``Fitter.known``)
        self.known: dict[str, float] = dict(fitter.known)

    def renew(self) -> Fitter:
        """A new phase of the search (diagnose's confirmation): tasks submitted from now on fit for a fresh fitter
        (``Fitter.fresh``), which is returned. Each worker renews its own fitter at its first task of the phase, so
        it starts from an empty record as a newly started worker would (the record decides which rollouts run past
        the training frames), and keeps its compiled kernels. The training errors known so far (``known``) stay
        known: the phase's fitter has the same simulator, footage and training window."""
        self.fitter = self.fitter.fresh()
        self._phase += 1
        return self.fitter

    def __enter__(self) -> "FitPool":
        if self.jobs > 1:
            from fluidnexus import engine

            f = self.fitter
            self._pool = ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_start,
                                             initargs=(engine.current(), f.sim.setup, f.observed, f.cameras, f.sigma,
                                                       f.train))
        return self

    def __exit__(self, *exc) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def submit(self, fn, args: tuple) -> "Task":
        """Start ``fn(fitter, *args)``: in a worker, or here and now with one job. Call the tasks' ``result`` in
        the order they were started: that is when a worker's scored models join ``fitter.scored`` (and its rollouts
        ``fitter.evaluations``)."""
        if self._pool is None:
            self.fitter.known = dict(self.known)
            result = fn(self.fitter, *args)
            return Task(self, done=(result, [], 0, _new(self.fitter.known, self.known)))
        return Task(self, future=self._pool.submit(_run, fn, args, self._phase, dict(self.known)))

    def map(self, fn, arglists: list[tuple]) -> list:
        """``[fn(fitter, *args) for args in arglists]``, side by side."""
        return [task.result() for task in [self.submit(fn, args) for args in arglists]]


class Task:
    """A started fit task: its result, from a worker's future or computed here (``done``: the result, the models
    scored, the rollouts run and the training errors learned, as ``_run`` returns them)."""

    def __init__(self, pool: FitPool, done: tuple | None = None, future=None):
        self._pool, self._fitter, self._done, self._future = pool, pool.fitter, done, future
        self._collected = False

    def result(self):
        if not self._collected:  # its record joins the pool's
            result, scored, evaluations, known = self._done if self._future is None else self._future.result()
            self._fitter.scored.extend(scored)
            self._fitter.evaluations += evaluations
            self._pool.known.update(known)
            self._result, self._collected = result, True
        return self._result


def _new(known: dict, before: dict) -> dict:
    """The entries of ``known`` that ``before`` lacks."""
    return {key: err for key, err in known.items() if key not in before}


def _start(config, setup, observed, cameras, sigma, train) -> None:
    """A worker's initialiser: the engine as in the parent, then its own simulator and fitter."""
    global _fitter
    _exit_with(os.getppid())
    from fluidnexus import engine

    engine.init(arch=config.arch, precision=config.precision, debug=config.debug)
    import taichi as ti

    # workers that exit together race for the kernel cache's lock; the loser skips writing its (same) kernels and
    # would print a warning for each try
    ti.set_logging_level(ti.ERROR)
    _fitter = Fitter(PlumeSimulator(setup), observed, cameras, sigma, train)


def _exit_with(parent: int, every: float = 1.0) -> None:
    """Ends this worker within ``every`` seconds of its parent process ``parent`` ending. A parent killed by a
    signal (SIGTERM, SIGKILL) never shuts its pool down: its workers stayed, one blocked writing a result that no one
    reads, and kept the pipes that the parent's caller reads its output from open, so that caller waited forever."""
    import threading
    import time

    def watch():
        while os.getppid() == parent:
            time.sleep(every)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _run(fn, args: tuple, phase: int, known: dict):
    """One task of the pool's phase ``phase`` in a worker, knowing the training errors ``known``: its result, the
    models it scored, the rollouts it ran and the training errors it learned."""
    global _fitter, _phase
    if phase != _phase:
        _fitter, _phase = _fitter.fresh(), phase
    scored, evaluations = len(_fitter.scored), _fitter.evaluations
    _fitter.known = dict(known)
    result = fn(_fitter, *args)
    return result, _fitter.scored[scored:], _fitter.evaluations - evaluations, _new(_fitter.known, known)
