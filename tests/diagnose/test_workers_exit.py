"""diagnose --jobs: a worker process ends when the process that started it is killed (diagnose/parallel.py)."""
from __future__ import annotations

import os
import signal
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import pytest


def _watched() -> None:  # the pool's initializer, as diagnose's ``_start`` begins
    from fluidnexus.diagnose.parallel import _exit_with

    _exit_with(os.getppid(), every=0.1)


def _unwatched() -> None:
    pass


def _pid() -> int:
    return os.getpid()


def _parent(path: str, initializer) -> None:
    """Starts one worker, writes its pid to ``path``, and keeps it busy with the pool open, as diagnose does."""
    with ProcessPoolExecutor(1, mp_context=get_context("spawn"), initializer=initializer) as pool:
        Path(path).write_text(str(pool.submit(_pid).result()))
        pool.submit(time.sleep, 120)
        time.sleep(120)


def _ended(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return True
    return "State:\tZ" in state  # a zombie has ended; its new parent reaps it


def _worker_after_parent_killed(tmp_path, initializer, wait: float) -> bool:
    """Whether the worker had ended ``wait`` seconds after its parent was killed with SIGKILL."""
    path = tmp_path / f"{initializer.__name__}.pid"
    parent = get_context("spawn").Process(target=_parent, args=(str(path), initializer))
    parent.start()
    deadline = time.time() + 120
    while not (path.is_file() and path.read_text()) and time.time() < deadline:
        time.sleep(0.1)
    worker = int(path.read_text())
    os.kill(parent.pid, signal.SIGKILL)
    parent.join()
    deadline = time.time() + wait
    while not _ended(worker) and time.time() < deadline:
        time.sleep(0.1)
    ended = _ended(worker)
    if not ended:
        os.kill(worker, signal.SIGKILL)
    return ended


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="reads /proc")
def test_a_worker_ends_with_its_killed_parent(tmp_path):
    """Killed, a parent never shuts its pool down: a worker without the watch outlives it (and a worker blocked
    writing a result kept its caller's output pipe open, so a test waiting on diagnose's output hung); with it the
    worker ends within a second."""
    assert _worker_after_parent_killed(tmp_path, _watched, wait=5.0)
    assert not _worker_after_parent_killed(tmp_path, _unwatched, wait=2.0)
