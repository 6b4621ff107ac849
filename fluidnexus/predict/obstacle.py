"""Obstacles for ``interact``: a ball from ``--ball CX,CY,CZ,R`` or a closed triangle mesh from ``--mesh FILE``.

A mesh becomes a signed-distance grid (negative inside) over its bounding box plus a margin, computed once by
the engine (``signed_distance_grid``: exact point-triangle distance to the nearest face, sign from the generalised
winding number), so any closed OBJ/STL/PLY that trimesh loads works without a spatial index. The engine's
``GridObstacle`` projects
particles with it (fluidnexus/engine/obstacle.py).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import InputError

GRID_NODES = 40  # nodes along the longest side of the mesh's box


def parse_ball(text: str) -> tuple[tuple[float, float, float], float]:
    """``CX,CY,CZ,R`` (metres) -> (centre, radius); raises InputError for anything else or R <= 0."""
    parts = text.split(",")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise InputError(None, "--ball", f"expected four finite numbers CX,CY,CZ,R in metres, got {text!r}")
    if values[3] <= 0:
        raise InputError(None, "--ball", f"the radius R must be > 0, got {values[3]}")
    return (values[0], values[1], values[2]), values[3]


def load_mesh(path: str | Path):
    """A closed triangle mesh (trimesh.Trimesh) from any file trimesh reads; InputError otherwise."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "--mesh", "file not found")
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as err:  # trimesh raises many types for unreadable files
        raise InputError(path, "--mesh", f"cannot load a triangle mesh ({err})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(path, "--mesh", "no triangles in the file")
    if not mesh.is_watertight:
        raise InputError(path, "--mesh", "the mesh is not closed (watertight); an obstacle needs an inside")
    return mesh


def mesh_sdf_grid(mesh, nodes: int = GRID_NODES, margin_cells: int = 2) -> tuple[np.ndarray, np.ndarray, float]:
    """Signed distance phi [nx, ny, nz] m of ``mesh`` on a grid over its box; returns (phi, origin, spacing)."""
    from ..engine.obstacle import signed_distance_grid

    lo, hi = np.asarray(mesh.bounds[0], float), np.asarray(mesh.bounds[1], float)
    spacing = float((hi - lo).max()) / (nodes - 1 - 2 * margin_cells)
    origin = lo - margin_cells * spacing
    res = np.ceil((hi - origin) / spacing).astype(int) + margin_cells + 1
    phi = signed_distance_grid(np.asarray(mesh.triangles, dtype=np.float64), origin, spacing, res)
    return phi, origin, spacing


def make_obstacle(ball: str | None, mesh_file: str | Path | None, nodes: int = GRID_NODES):
    """The engine obstacle for ``--ball`` or ``--mesh`` (exactly one), plus a JSON description of it."""
    from ..engine.obstacle import GridObstacle, SphereObstacle

    if (ball is None) == (mesh_file is None):
        raise InputError(None, "--ball/--mesh", "give exactly one of --ball and --mesh")
    if ball is not None:
        center, radius = parse_ball(ball)
        return SphereObstacle(center, radius), {"kind": "ball", "center": list(center), "radius": radius}
    mesh = load_mesh(mesh_file)
    phi, origin, spacing = mesh_sdf_grid(mesh, nodes)
    return GridObstacle(phi, origin, spacing), {"kind": "mesh", "file": str(Path(mesh_file).resolve()),
                                                "faces": int(len(mesh.faces)), "grid": list(phi.shape),
                                                "spacing": spacing}
