"""Gridded fields of a frame state: the physical particles' density and velocity sampled on a regular grid over the
scene volume (what the ``vti``, ``vdb`` and ``npz`` exports write). Needs the engine started (``FieldQuery``)."""
from __future__ import annotations

import numpy as np

from .vti import grid_points


def sample_fields(state, volume, voxel: float, h: float, frame=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Density and velocity of a state's physical particles on a grid of ``voxel`` metres over ``volume``.

    With ``frame`` (a :class:`~fluidnexus.world_frame.SourceFrame`) the grid is laid out in that frame instead:
    over the volume's box there, ``voxel`` metres converted to its unit, and the fields are in its units.

    Returns (origin, spacing, {"density": [nz, ny, nx], "velocity": [nz, ny, nx, 3]}).
    """
    import torch

    from fluidnexus import engine

    lo, hi = np.asarray(volume.min), np.asarray(volume.max)
    if frame is not None:
        corners = frame.from_scene([np.where(np.array(p, bool), hi, lo) for p in np.ndindex(2, 2, 2)])
        lo, hi, voxel = corners.min(0), corners.max(0), float(frame.length_from_scene(voxel))
    counts = np.maximum(2, np.round((hi - lo) / voxel).astype(int) + 1)
    spacing = (hi - lo) / (counts - 1)
    shape = (int(counts[2]), int(counts[1]), int(counts[0]))
    pts = grid_points(lo, spacing, shape).reshape(-1, 3)
    if frame is not None:
        pts = frame.to_scene(pts)
    query = engine.FieldQuery(max(1, state.num_physical), len(pts), h)
    query.forward(torch.as_tensor(pts), torch.as_tensor(state.physical_positions, dtype=torch.float64),
                  torch.as_tensor(state.physical_velocities, dtype=torch.float64))
    density = query.density().numpy().reshape(shape)
    velocity = query.velocity().numpy().reshape(*shape, 3)
    if frame is not None:
        density, velocity = frame.density_from_scene(density), frame.from_scene(velocity)
    return lo, spacing, {"density": density, "velocity": velocity}
