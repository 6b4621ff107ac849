"""Taichi engine: particle simulation and splat rendering kernels. No file IO, no printing.

Call :func:`init` once before creating any engine object.
"""
from .runtime import current, init, is_running, real, resolve_arch
from .forces import TERMS, Buoyancy, Drag, Viscosity, Vorticity, Wind, register_term
from .model import ModelConfig, SolverConfig, rest_density_for_lattice
from .ambient import STRUCTURES, AirDomain, AirState, AmbientAir
from .entrainment import Entrainment
from .neighbors import NeighborOverflow, NeighborTable
from .pbf import PBFSimulator, step_particles
from .query import FieldQuery, divergence_on_grid, mean_abs_divergence
from .bridge import density_at, simulate_step, velocity_at
from .advect import advect
from .particles import PhysicalParticles, VisualParticles, prune
from .emitter import SourceDisk, cylinder_lattice, scalarflow_initial_lattice, stabilize

__all__ = ["init", "current", "is_running", "real", "resolve_arch", "TERMS", "Buoyancy", "Drag", "Viscosity",
           "Vorticity", "Wind", "register_term", "ModelConfig", "STRUCTURES", "AirDomain", "AirState", "AmbientAir",
           "Entrainment", "SolverConfig",
           "rest_density_for_lattice",
           "NeighborOverflow", "NeighborTable", "PBFSimulator", "step_particles", "FieldQuery",
           "divergence_on_grid", "mean_abs_divergence", "simulate_step", "velocity_at", "density_at", "advect",
           "PhysicalParticles", "VisualParticles", "prune", "SourceDisk", "cylinder_lattice",
           "scalarflow_initial_lattice", "stabilize"]

from .splat import render, reserve_gaussians  # noqa: E402  (differentiable 3D Gaussian splatting, docs/renderer.md)
from .splat_gaussians import Gaussians  # noqa: E402

__all__ += ["render", "reserve_gaussians", "Gaussians"]
