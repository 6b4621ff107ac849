"""The one place that starts Taichi.

``ti.init`` is process-global and resets every field, so the package calls it only through :func:`init`,
never at import time. Library code receives an already-resolved arch name; only the CLI turns
``--arch auto`` into ``cpu`` or ``cuda`` (:func:`resolve_arch`).
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "False")
import taichi as ti  # noqa: E402

log = logging.getLogger(__name__)

ARCHES = ("cpu", "cuda")
#: Taichi's offline kernel cache keeps this many bytes. Its default, 100 MiB with least-recently-used cleaning at
#: exit, is less than the kernels of one float32 reconstruction plus one float64 test session (about 110 MiB), so
#: each run evicted kernels the next one compiled again (10-30 s each time a neighbour table grew).
CACHE_BYTES = 1 << 30


@dataclass(frozen=True)
class RuntimeConfig:
    """How Taichi was started: arch ("cpu"|"cuda"), float precision ("f32"|"f64"), bounds checks."""

    arch: str = "cpu"
    precision: str = "f32"
    debug: bool = False


_current: RuntimeConfig | None = None


def cache_dir() -> Path:
    """Taichi's offline kernel cache (``$FLUIDNEXUS_CACHE`` or ``~/.cache/fluidnexus/taichi``)."""
    root = os.environ.get("FLUIDNEXUS_CACHE", str(Path.home() / ".cache" / "fluidnexus"))
    return Path(root) / "taichi"


#: Taichi's kernel cache is guarded by a lock file that a process creates while it writes the cache at exit (a
#: second or two) and removes after. A process killed in between leaves it behind, and from then on every process
#: warns that it cannot take the lock and writes nothing to the cache. A lock older than this is such a leftover.
STALE_LOCK_SECONDS = 120.0


def clear_stale_lock(folder: Path, now: float | None = None) -> bool:
    """Remove ``folder``'s cache lock (``ticache.lock``) when it is older than :data:`STALE_LOCK_SECONDS`; returns
    whether it did."""
    import time

    lock = Path(folder) / "ticache.lock"
    try:
        if (time.time() if now is None else now) - lock.stat().st_mtime <= STALE_LOCK_SECONDS:
            return False
        lock.unlink()
    except OSError:  # no lock (the usual case), or one another process removed first: nothing to clear
        return False
    return True


def init(arch: str = "cpu", precision: str = "f32", debug: bool = False) -> RuntimeConfig:
    """Start Taichi once per process; a second call with the same settings is a no-op.

    A call with different settings restarts Taichi, which invalidates every existing field.

    On the CPU the cores belong to Taichi's kernels: torch's intra-op pool is set to one thread, because the
    torch work between kernels (losses, optimiser steps on ~10^5-element tensors) gains little from a second
    thread and its parallel loops stall at their barrier whenever the other core is busy (a Taichi kernel or
    another process): on the 2-core CPU with other jobs running, the 0.8 L1 + 0.2 D-SSIM loss of one 270 x 480
    frame took 1-4 s with two torch threads and 60 ms with one (docs/renderer.md).

    Args:
        arch: "cpu" or "cuda" (resolve "auto" with :func:`resolve_arch` first).
        precision: "f32" or "f64"; the engine's real-valued fields and literals use it.
        debug: Taichi's bounds-checked debug mode (slow; for tests).
    """
    global _current
    if arch not in ARCHES:
        raise ValueError(f"arch must be one of {ARCHES}, got {arch!r}")
    if precision not in ("f32", "f64"):
        raise ValueError(f"precision must be 'f32' or 'f64', got {precision!r}")
    cfg = RuntimeConfig(arch, precision, debug)
    if _current == cfg:
        return cfg
    if _current is not None:
        ti.reset()
    clear_stale_lock(cache_dir())
    # ti.init prints "[Taichi] Starting on arch=..." to stdout, where it would land among a command's output (and
    # a command's one-line error); the arch goes to the log instead.
    with contextlib.redirect_stdout(io.StringIO()):
        ti.init(
            arch=ti.cuda if arch == "cuda" else ti.cpu,
            default_fp=ti.f64 if precision == "f64" else ti.f32,
            debug=debug,
            offline_cache=True,
            offline_cache_file_path=str(cache_dir()),
            offline_cache_max_size_of_files=CACHE_BYTES,
            log_level=ti.WARN,
            random_seed=0,
        )
    log.debug("Taichi started on %s (%s)", arch, precision)
    if arch == "cpu":
        import torch

        torch.set_num_threads(1)
    _current = cfg
    return cfg


def current() -> RuntimeConfig:
    """The running configuration; raises if :func:`init` has not been called."""
    if _current is None:
        raise RuntimeError("fluidnexus.engine.init() has not been called")
    return _current


def is_running(arch: str) -> bool:
    """True when :func:`init` has started the engine on ``arch`` in this process."""
    return _current is not None and _current.arch == arch


def real():
    """The Taichi float type of the running precision (use for every real-valued field)."""
    return ti.f64 if current().precision == "f64" else ti.f32


def resolve_arch(arch: str) -> str:
    """Turn "auto" into "cuda" when a CUDA device is usable, else "cpu"; pass "cpu"/"cuda" through."""
    if arch != "auto":
        if arch not in ARCHES:
            raise ValueError(f"arch must be auto, cpu or cuda, got {arch!r}")
        return arch
    try:
        import torch

        return "cuda" if torch.cuda.is_available() else "cpu"
    except Exception:  # pragma: no cover - torch is a dependency, but a broken CUDA setup must not crash
        return "cpu"
