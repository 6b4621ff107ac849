"""Engine objects a reconstruction reuses every iteration, sized once for the whole run (a rollout in ambient air
grows the physical side when its plume needs more, :meth:`Workspace.reserve`)."""
from __future__ import annotations

import logging

import numpy as np
import taichi as ti
import torch

from .. import engine
from ..engine import FieldQuery, ModelConfig, NeighborTable, PBFSimulator, SolverConfig, simulate_step
from ..engine.tensors import torch_dtype

log = logging.getLogger("fluidnexus")


class Workspace:
    """The simulator, the field queries and the visual pair table of one run.

    Each differentiable query has its own :class:`FieldQuery`, so the forward state a backward needs is never
    overwritten within an iteration (the bridges recompute it if it is).

    Args:
        physical_capacity: most physical particles at any frame.
        visual_capacity: most visual particles at any frame.
        solver, model: the PBF gas (constants, external terms).
    """

    def __init__(self, physical_capacity: int, visual_capacity: int, solver: SolverConfig, model: ModelConfig,
                 extra_gaussians: int = 0):
        self.solver, self.model = solver, model
        self.dtype = torch_dtype()
        self.theta = torch.tensor(model.to_vector(), dtype=self.dtype)
        self._allocate(physical_capacity, visual_capacity)
        self._pair_points = ti.Vector.field(3, engine.real(), shape=visual_capacity)
        self._pair_dtype = np.float64 if self.dtype == torch.float64 else np.float32
        self._pair_table = NeighborTable(visual_capacity, width=32)
        # the render kernels compile once, not at every doubling; static Gaussians are drawn with the smoke
        engine.reserve_gaussians(visual_capacity + extra_gaussians)
        self.obstacle, self._projector = None, None

    def _allocate(self, physical_capacity: int, visual_capacity: int) -> None:
        """The simulator and the field queries for these capacities."""
        h = self.solver.h
        self.sim = PBFSimulator(physical_capacity, self.solver, self.model)
        self.advect_query = FieldQuery(physical_capacity, visual_capacity, h)
        self.density_query = FieldQuery(physical_capacity, physical_capacity, h)
        self.next_query = FieldQuery(physical_capacity, physical_capacity, h)

    def set_model(self, model: ModelConfig) -> None:
        """Use ``model`` (terms, parameters, structure) from the next step on."""
        self.model = model
        self.theta = torch.tensor(model.to_vector(), dtype=self.dtype)
        self.sim.set_model(model)

    def reserve(self, physical: int) -> None:
        """Room for ``physical`` particles (the gas in ambient air grows with its plume): when the simulator is
        smaller, a new one and new field queries 1.5 x larger (model and obstacle kept; Taichi keeps the old
        fields allocated)."""
        if physical <= self.sim.capacity:
            return
        capacity = int(1.5 * physical)
        log.info("workspace: %d physical particles exceed the capacity %d; grown to %d", physical, self.sim.capacity,
                 capacity)
        self._allocate(capacity, self.advect_query.query_capacity)
        self.set_obstacle(self.obstacle)

    def set_obstacle(self, obstacle) -> None:
        """A rigid body (``engine.obstacle``; None for none) that no particle ends a step inside: the simulator
        moves physical particles out at every step, :meth:`push_out` moves fitted or advected points out."""
        from ..engine.obstacle import PointProjector

        self.obstacle = obstacle
        self.sim.set_obstacle(obstacle)
        self._projector = None if obstacle is None else PointProjector(
            max(self.sim.capacity, self.advect_query.query_capacity))

    def push_out(self, points: torch.Tensor) -> torch.Tensor:
        """``points`` [K, 3] moved out of the obstacle (the tensor itself without one)."""
        return points if self.obstacle is None else self._projector(self.obstacle, points)

    @property
    def dt(self) -> float:
        return self.solver.dt

    def simulate(self, p: torch.Tensor, u: torch.Tensor, age: torch.Tensor, differentiable: bool = False,
                 volume: torch.Tensor | None = None):
        """One PBF step (p, u) -> (p', u'); with ``differentiable`` the result carries the ``ti.ad`` graph.
        ``volume``: the particles' rest volumes (default 1; entrainment, engine/entrainment.py)."""
        if differentiable:
            return simulate_step(p, u, self.theta, self.sim, age, volume=volume)
        with torch.no_grad():
            return simulate_step(p.detach(), u.detach(), self.theta, self.sim, age, volume=volume)

    def isolated(self, p: torch.Tensor) -> torch.Tensor:
        """[N] bool: physical particles with no other particle within h (the release deletes them)."""
        if p.shape[0] == 0:
            return torch.zeros(0, dtype=torch.bool)
        with torch.no_grad():
            rho = engine.density_at(p.detach(), p.detach(), self.density_query)
        h = self.solver.h
        self_term = 315.0 / (64.0 * np.pi * h**9) * h**6  # Poly6 W(0)
        return rho <= self_term * (1.0 + 1e-6)

    def visual_pairs(self, x: torch.Tensor, radius: float) -> torch.Tensor:
        """[P, 2] int64 index pairs (i < j) of visual particles closer than ``radius``."""
        m = x.shape[0]
        if m < 2:
            return torch.zeros((0, 2), dtype=torch.long)
        full = np.zeros((self._pair_points.shape[0], 3), dtype=self._pair_dtype)
        full[:m] = x.detach().cpu().numpy()
        self._pair_points.from_numpy(full)
        self._pair_table.build(self._pair_points, m, radius)
        count = self._pair_table.count.to_numpy()[:m]
        nbr = self._pair_table.nbr.to_numpy()[:m]
        i = np.repeat(np.arange(m), count)
        j = np.concatenate([nbr[k, :c] for k, c in enumerate(count)]) if count.sum() else np.zeros(0, int)
        keep = i < j
        return torch.from_numpy(np.stack([i[keep], j[keep]], axis=1).astype(np.int64))
