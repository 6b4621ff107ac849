"""Memory before allocation: what a run will need, the limit it must stay under, and the refusal (docs/scale.md).

Every command that allocates a lot (recon, predict, interact, diagnose, synth, refine) adds up its large
buffers from the scene and its settings before it reads a video or writes a file (each stage owns its estimate:
``recon/memory.py``, ``predict/memory.py``, ``diagnose/parallel.py``, ``gen/novel_views.py``; this module holds the
arithmetic they share), and compares the sum with
``--max-memory`` (default ``DEFAULT_FRACTION`` of the memory the machine has available now, from
``/proc/meminfo``). Over the limit it raises :class:`~fluidnexus.errors.InputError` naming the setting that
shrinks the largest part, so the CLI prints one line and exits with code 2 before anything is written.

The byte counts per particle follow the engine's fields (float32, and a gradient twin for every field that
has one): the PBF simulator keeps ``iterations + 1`` copies of the positions and per-iteration solver state;
neighbour tables hold ``width`` int32 per query. ``RUNTIME_BYTES`` is what Python, torch, Taichi and the
compiled kernels take before any scene is read (measured, BENCHMARKS.md). The estimate is checked against
the measured peak resident memory of real runs (tests/recon/test_memory.py states the factor).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

from .errors import InputError

DEFAULT_FRACTION = 0.8  # of MemAvailable
RUNTIME_BYTES = 450 * 2**20  # interpreter, torch, Taichi runtime and compiled kernels (measured: 430-470 MiB)
F32 = 4
NEIGHBOURS = 64  # neighbour-table width a dense PBF gas grows to (it starts at 48)
HULL_VOXEL_BYTES = 160  # per voxel tested at once: centre (float64 x 3), projection, depth, pixel indices, masks
# per Gaussian: the torch graph of one differentiable render (projected means, covariances, conics, colours with
# their gradients) and its tile-list entries; measured: Sphere, 98.7k Gaussians at 400x400 (BENCHMARKS.md)
RENDER_GRAPH_BYTES = 3072


@dataclass
class Estimate:
    """Bytes a run will hold at its peak, by part; each part names the setting that shrinks it."""

    command: str
    parts: dict[str, int] = field(default_factory=dict)
    settings: dict[str, str] = field(default_factory=dict)

    def add(self, part: str, nbytes: float, setting: str) -> None:
        self.parts[part] = self.parts.get(part, 0) + int(nbytes)
        self.settings[part] = setting

    @property
    def total(self) -> int:
        return RUNTIME_BYTES + sum(self.parts.values())

    def largest(self) -> tuple[str, int]:
        return max(self.parts.items(), key=lambda kv: kv[1]) if self.parts else ("runtime", RUNTIME_BYTES)

    def describe(self) -> str:
        parts = ", ".join(f"{k} {_fmt(v)}" for k, v in sorted(self.parts.items(), key=lambda kv: -kv[1]))
        return f"{self.command} needs about {_fmt(self.total)} (runtime {_fmt(RUNTIME_BYTES)}, {parts})"


def _fmt(nbytes: float) -> str:
    for unit, size in (("GiB", 2**30), ("MiB", 2**20)):
        if nbytes >= size or unit == "MiB":
            return f"{nbytes / size:.1f} {unit}"
    return f"{nbytes} B"


def available_bytes() -> int:
    """The memory the machine can give now without swapping (MemAvailable of /proc/meminfo)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")


def parse_limit(text: str | None) -> int:
    """``--max-memory``: ``auto`` (``DEFAULT_FRACTION`` of the available memory) or a size such as ``8G``,
    ``1500M``, ``2.5GiB`` or a byte count. A limit below what the smallest run needs is refused."""
    if text is None or text == "auto":
        return int(DEFAULT_FRACTION * available_bytes())
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kKmMgGtT]?)(i?[bB])?\s*", str(text))
    if not m:
        raise InputError(None, "--max-memory", f"expected a size such as 8G or 1500M, or 'auto', got {text!r}")
    limit = int(float(m.group(1)) * 1024 ** " KMGT".index(m.group(2).upper() or " "))
    if limit < RUNTIME_BYTES:
        raise InputError(None, "--max-memory", f"{_fmt(limit)} is below the {_fmt(RUNTIME_BYTES)} the smallest "
                                               "run needs (interpreter, torch and the engine)")
    return limit


def check(estimate: Estimate, limit: int) -> Estimate:
    """Refuse ``estimate`` over ``limit`` (one line naming the setting that shrinks its largest part)."""
    if estimate.total > limit:
        part, _ = estimate.largest()
        setting = estimate.settings.get(part, "--max-memory")
        raise InputError(None, setting.split()[0], f"{estimate.describe()}; over --max-memory {_fmt(limit)}: "
                                                   f"the largest part is the {part}, change {setting}")
    return estimate


# ---- the parts ------------------------------------------------------------------------------------------
def video_bytes(views: int, frames: int, width: int, height: int, channels: int) -> int:
    """A [V, T, H, W, C] float32 frame cache, held twice while the views are stacked."""
    return 2 * views * frames * width * height * channels * F32


def hull_bytes(grid_voxels: int, chunk: int) -> int:
    """The visual hull's working memory: one slab of voxels at a time, plus at most every voxel kept."""
    return min(grid_voxels, chunk) * HULL_VOXEL_BYTES + grid_voxels * 3 * 8 // 4


def physical_bytes(capacity: int, iterations: int) -> int:
    """PBF simulator (positions per iteration, solver state, two neighbour tables) and three field queries."""
    its = max(iterations, 1)
    per = 2 * F32 * (4 * 3 + 1 + 3 * (its + 1) + 3 * its + 2 * 3 * its) + 2 * F32
    table = F32 * (3 + 3 + 4 + NEIGHBOURS)  # keys, order, bucket heads, sorted positions, count, neighbours
    query = 2 * F32 * (3 * 3 + 1 + 2 * 3) + table
    return capacity * (per + 2 * table + 3 * query)


def visual_bytes(capacity: int, channels: int) -> int:
    """Splat buffers, the advection query, the visual pair table and the per-particle torch state with Adam."""
    splat = 2 * F32 * (3 + 3 + 4 + 1 + channels + 2 + 3 + 1) + 16 * F32  # + tile-list entries
    query = 2 * F32 * (3 * 3 + 1) + F32 * (1 + NEIGHBOURS)
    pairs = F32 * (3 + 3 + 4 + 32 + 3)
    state = 4 * F32 * (3 + channels + 3 + 4 + 1)  # value, gradient, two Adam moments
    return capacity * (splat + query + pairs + state + RENDER_GRAPH_BYTES)


def image_bytes(width: int, height: int, channels: int, views: int) -> int:
    """Render buffers of one image per view (colour, alpha, depth with gradients; torch copies; SSIM)."""
    return views * width * height * (2 * F32 * (channels + 2) + 24 * F32 * channels)


# ---- shared by several commands ----------------------------------------------------------------------
def video_estimate(command: str, frames: int, width: int, height: int, videos: int) -> Estimate:
    """A command that holds ``videos`` RGB float32 videos of ``frames`` x ``width`` x ``height`` at once
    (synth: the input, the output and the warp; refine: the rough video, its smoothed copy and the output)."""
    est = Estimate(command)
    est.add("videos", videos * frames * width * height * 3 * F32, "--resolution")
    return est
