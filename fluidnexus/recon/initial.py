"""The state before the first reconstructed frame (FluidNexus supp. "Initialization").

Physical particles start on a cubic lattice in a cylinder over the source, along its direction, and are
stabilised for N_stable steps while the emitter seeds more (if the source is on at the first frame); visual
particles start in the first frame's visual hull (or, without one, on a finer lattice in a thin cylinder over the
source) with the constant initial appearance; their positions are then fitted to the first frame
(``fit.fit_positions``). Lattices are laid out for an upward source and turned onto the source's direction
(``engine.emitter.orient``); buoyancy alone stays vertical (it acts against gravity).

No particle is placed inside an obstacle (declared or found): seeds, the initial lattice and every emitted
particle that falls inside a body are dropped (``outside``), and the run's log says how many.
"""
from __future__ import annotations

import logging

import numpy as np
import torch

from ..engine import SourceDisk, cylinder_lattice
from ..engine.emitter import orient
from ..scene import Source
from .config import ReconConfig
from .smoke import Smoke
from .workspace import Workspace

SOURCE_DEPTH = 0.02  # the initial physical cylinder starts this far below the source (metres at ScalarFlow's scale)

log = logging.getLogger("fluidnexus")


def outside(points: np.ndarray, obstacle, what: str) -> np.ndarray:
    """The points [K, 3] that lie outside ``obstacle`` (an engine body, or None: all of them); logs how many of
    ``what`` were dropped."""
    if obstacle is None or not len(points):
        return points
    keep = obstacle.distance(np.asarray(points)) > 0
    if not keep.all():
        log.info("%d of %d %s inside an obstacle dropped", int((~keep).sum()), len(points), what)
    return points[keep]


def physical_source(source: Source, cfg: ReconConfig) -> SourceDisk:
    """The physical emitter: ``physical_emit_spacing`` on a disk of ``physical_emit_radius`` at the source."""
    return SourceDisk(center=tuple(source.center), radius=cfg.physical_emit_radius,
                      spacing=cfg.physical_emit_spacing, jitter=0.1, velocity=source.velocity,
                      direction=source.direction)


def visual_source(source: Source, cfg: ReconConfig) -> SourceDisk:
    """The visual emitter: ``visual_spacing`` on a disk of ``visual_radius`` at the source."""
    return SourceDisk(center=tuple(source.center), radius=cfg.visual_radius, spacing=cfg.visual_spacing, jitter=0.1,
                      direction=source.direction)


def frame_rng(seed: int, frame: int) -> np.random.Generator:
    """The generator of one frame's random choices (emitter jitter); independent of any earlier frame."""
    return np.random.default_rng([seed, frame + 1_000_000])


def frame_generator(seed: int, frame: int) -> torch.Generator:
    """The torch generator of one frame's view choices."""
    return torch.Generator().manual_seed(seed * 1_000_003 + frame)


def initial_smoke(source: Source, visual: np.ndarray, cfg: ReconConfig, ws: Workspace, frame: int) -> Smoke:
    """Physical particles after N_stable stabilisation steps around ``source``, and visual particles at
    ``visual`` [M, 3] (outside the obstacles: ``run.locate_smoke``) with the constant initial appearance, at
    ``frame``; no physical particle inside ``ws``'s obstacle."""
    dtype, dt = ws.dtype, ws.dt
    cx, cy, cz = source.center
    below = SOURCE_DEPTH * cfg.length_scale
    lattice = cylinder_lattice((cx, cz), cfg.physical_radius, cy - below, cy - below + cfg.physical_height,
                               cfg.physical_spacing)
    empty = torch.zeros((0, 3), dtype=dtype)
    smoke = Smoke(frame, empty, empty, torch.zeros(0, dtype=dtype), empty, torch.zeros((0, cfg.channels), dtype=dtype),
                  empty, torch.zeros((0, 4), dtype=dtype), torch.zeros(0, dtype=dtype))
    lattice = outside(orient(lattice, source.center, source.direction), ws.obstacle, "initial physical particles")
    smoke.add_physical(torch.as_tensor(lattice))
    emitter = physical_source(source, cfg)
    for step in range(cfg.stabilization_steps):
        if source.emits_at(frame):
            points = outside(emitter.sample(frame_rng(cfg.seed, -1 - step)), ws.obstacle,
                             "physical particles emitted while stabilising")
            smoke.add_physical(torch.as_tensor(points), emitter.velocity)
        smoke.p, smoke.u = ws.simulate(smoke.p, smoke.u, smoke.age)
        smoke.age = smoke.age + dt
        smoke.keep_physical(~ws.isolated(smoke.p))
    smoke.add_visual(torch.as_tensor(visual), cfg.color0, cfg.scale0, cfg.opacity0)
    return smoke


def initial_visual(source: Source, hull_points: np.ndarray, cfg: ReconConfig, min_points: int = 8) -> np.ndarray:
    """Seeds of the visual particles: the first frame's hull, or a thin cylinder over the source without one."""
    if len(hull_points) >= min_points:
        return hull_points
    cx, cy, cz = source.center
    return orient(cylinder_lattice((cx, cz), cfg.init_visual_radius, cy, cy + cfg.init_visual_height,
                                   cfg.visual_spacing), source.center, source.direction)


def emit(smoke: Smoke, source: Source, cfg: ReconConfig, frame: int, look=None, physical: bool = True,
         obstacle=None) -> None:
    """Seed one frame's new physical and visual particles at the source (nothing outside its emission window,
    nothing inside ``obstacle``, an engine body or None); the physical ones leave it at the inflow velocity.

    ``look`` (colour [C] or a float, scale, opacity) is the new Gaussians' appearance; default the constant initial
    appearance of ``cfg``. Without ``physical`` only the Gaussians are seeded, at the same places (the gas in
    ambient air gets its smoke from the inlet).
    """
    if not source.emits_at(frame):
        return
    rng = frame_rng(cfg.seed, frame)
    emitter = physical_source(source, cfg)
    points = emitter.sample(rng)
    visual = visual_source(source, cfg).sample(rng)
    if physical:
        smoke.add_physical(torch.as_tensor(outside(points, obstacle, f"physical particles emitted at frame {frame}")),
                           emitter.velocity)
    color, scale, opacity = look if look is not None else (cfg.color0, cfg.scale0, cfg.opacity0)
    smoke.add_visual(torch.as_tensor(outside(visual, obstacle, f"visual particles emitted at frame {frame}")), color,
                     scale, opacity)
