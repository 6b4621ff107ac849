"""The family's smoke: an Eulerian grid solver in numpy, independent of the project's PBF engine.

Collocated grid over the scene's box (cell size ``dx``), one frame = ``substeps`` steps of ``dt``. Each step
(Stam 1999, "Stable Fluids", with Fedkiw et al. 2001's vorticity confinement):

1. emit: during the source's window the source cells (a disk of the source's radius, two cells thick along its
   direction) are filled to density 1 and take the inflow velocity ``speed * direction`` (plus a small seeded
   wobble); what the filling adds is booked as emitted.
2. ``add_buoyancy``: u_y += dt * buoyancy * density (buoyancy acts along +y whatever the source's direction).
3. ``confine_vorticity``: u += dt * eps * dx * (N x w), N the normalised gradient of |w| (Fedkiw 2001, Eq. 9-11).
4. ``project``: Jacobi iterations on the pressure Poisson equation, Neumann at solid cells (a solid neighbour
   takes the cell's own pressure), p = 0 outside the box (open walls: smoke leaves through them); then
   u -= grad p and u = 0 in solids.
5. ``advect``: semi-Lagrangian, trilinear: the density, then the velocity itself, through the projected velocity
   (so the smoke moves in a divergence-free field).

Mass: semi-Lagrangian advection is not conservative. After each step the smoke leaving through the box's walls
(``outflow``: density times the outward normal velocity at the boundary cells) is booked, density inside solids is
removed, and the rest is rescaled to (mass before the step - outflow); the factor of each step is recorded
(``Flow.mass_factors``) so tests can bound what the advection itself loses or gains.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class Grid:
    """Cells of size ``dx`` from ``lo``; ``shape`` (nx, ny, nz)."""

    lo: tuple
    dx: float
    shape: tuple

    @classmethod
    def over(cls, lo, hi, cells: int) -> "Grid":
        """A grid over the box (lo, hi) with ``cells`` cells along its longest side."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        dx = float((hi - lo).max() / cells)
        shape = tuple(int(max(4, round(e / dx))) for e in hi - lo)
        return cls(tuple(map(float, lo)), dx, shape)

    def centres(self) -> np.ndarray:
        """[nx, ny, nz, 3] cell centres, metres."""
        idx = np.stack(np.meshgrid(*[np.arange(n) for n in self.shape], indexing="ij"), -1)
        return np.asarray(self.lo) + (idx + 0.5) * self.dx

    @property
    def hi(self) -> np.ndarray:
        return np.asarray(self.lo) + np.asarray(self.shape) * self.dx


@dataclass(frozen=True)
class Inflow:
    """The source as the solver sees it (metres, m/s, frames)."""

    center: tuple
    radius: float
    direction: tuple
    speed: float
    window: tuple
    buoyancy: float

    def emits_at(self, t: int) -> bool:
        """Whether the step into frame t emits (window [A, B), B None: to the end)."""
        a, b = self.window
        return t >= a and (b is None or t < b)


@dataclass
class Flow:
    """The simulation's result: density [T, nx, ny, nz] (frame 0: before any inflow), the solid mask, and the
    mass bookkeeping (in density x cells: emitted, left through the walls, per-step rescale factors)."""

    grid: Grid
    density: np.ndarray
    solid: np.ndarray
    emitted: float = 0.0
    outflow: float = 0.0
    mass_factors: list = field(default_factory=list)


def solid_mask(grid: Grid, bodies) -> np.ndarray:
    """[nx, ny, nz] True where a cell centre lies inside a body (``spec.Body``: sphere or box)."""
    c = grid.centres()
    mask = np.zeros(grid.shape, bool)
    for b in bodies:
        rel = c - np.asarray(b.center)
        if b.kind == "sphere":
            mask |= np.linalg.norm(rel, axis=-1) <= b.radius
        else:
            mask |= np.all(np.abs(rel) <= np.asarray(b.half), axis=-1)
    return mask


def source_cells(grid: Grid, inflow: Inflow) -> np.ndarray:
    """[nx, ny, nz] True in the source disk: within the radius of the axis, 0 to 2 cells along the direction
    (at least the one cell nearest the centre)."""
    rel = grid.centres() - np.asarray(inflow.center)
    d = np.asarray(inflow.direction, float)
    along = rel @ d
    across = np.linalg.norm(rel - along[..., None] * d, axis=-1)
    cells = (along >= -0.5 * grid.dx) & (along < 2.0 * grid.dx) & (across <= max(inflow.radius, 0.5 * grid.dx))
    if not cells.any():
        cells[np.unravel_index(np.argmin(np.linalg.norm(rel, axis=-1)), grid.shape)] = True
    return cells


def advect(q: np.ndarray, vel: np.ndarray, dt: float, dx: float) -> np.ndarray:
    """Semi-Lagrangian advection of a scalar [nx, ny, nz] or vector [nx, ny, nz, 3] field (trilinear; zero from
    outside the box)."""
    idx = np.indices(q.shape[:3], dtype=float)
    back = idx - np.moveaxis(vel, -1, 0) * (dt / dx)
    if q.ndim == 3:
        return ndimage.map_coordinates(q, back, order=1, mode="constant")
    return np.stack([ndimage.map_coordinates(q[..., a], back, order=1, mode="constant") for a in range(3)], -1)


def divergence(u: np.ndarray, dx: float) -> np.ndarray:
    return sum(np.gradient(u[..., a], dx, axis=a) for a in range(3))


def project(u: np.ndarray, solid: np.ndarray, dx: float, p: np.ndarray, iters: int = 40) -> tuple:
    """(u - grad p, p): Jacobi on lap p = div u, Neumann at solids, p = 0 outside the box; ``p`` warm-starts."""
    u = np.where(solid[..., None], 0.0, u)
    div = divergence(u, dx)
    fluid = np.pad(~solid, 1, constant_values=True).astype(float)
    count = np.zeros(solid.shape)
    slices = []
    for a in range(3):
        for s in (-1, 1):
            sl = [slice(1, -1)] * 3
            sl[a] = slice(1 + s, solid.shape[a] + 1 + s)
            slices.append(tuple(sl))
            count += fluid[tuple(sl)]
    count = np.maximum(count, 1.0)
    for _ in range(iters):
        pp = np.pad(p, 1)
        total = sum(pp[sl] * fluid[sl] for sl in slices)
        p = np.where(solid, 0.0, (total - dx * dx * div) / count)
    # solid cells take their fluid neighbours' mean pressure, so the gradient next to them has no normal jump
    pp = np.pad(p, 1)
    nb = sum(pp[sl] * fluid[sl] for sl in slices) / count
    p_full = np.where(solid, nb, p)
    u = u - np.stack(np.gradient(p_full, dx), -1)
    return np.where(solid[..., None], 0.0, u), p


def confine_vorticity(u: np.ndarray, dx: float, eps: float) -> np.ndarray:
    """The confinement force (Fedkiw et al. 2001, Eq. 9-11) per unit mass."""
    g = [np.gradient(u[..., a], dx) for a in range(3)]  # g[a][b] = d u_a / d x_b
    w = np.stack([g[2][1] - g[1][2], g[0][2] - g[2][0], g[1][0] - g[0][1]], -1)
    gn = np.stack(np.gradient(np.linalg.norm(w, axis=-1), dx), -1)
    n = gn / (np.linalg.norm(gn, axis=-1, keepdims=True) + 1e-12)
    return eps * dx * np.cross(n, w)


def outflow(d: np.ndarray, u: np.ndarray, dt: float, dx: float) -> float:
    """Smoke (density x cells) leaving through the six walls in one step: boundary density times the outward
    velocity's share of a cell per step."""
    out = 0.0
    for a in range(3):
        lo_face = np.take(d, 0, axis=a) * np.clip(-np.take(u[..., a], 0, axis=a), 0, None)
        hi_face = np.take(d, -1, axis=a) * np.clip(np.take(u[..., a], -1, axis=a), 0, None)
        out += float((lo_face.sum() + hi_face.sum()) * dt / dx)
    return out


def simulate(grid: Grid, inflow: Inflow, frames: int, fps: float, bodies=(), vorticity: float = 0.0,
             seed: int = 0) -> Flow:
    """Density at every frame of a smoke released by ``inflow`` into the box of ``grid`` around ``bodies``.

    The inflow velocity gets a small random wobble per step (seeded) so plumes are not perfectly symmetric."""
    rng = np.random.default_rng(seed)
    solid = solid_mask(grid, bodies)
    src = source_cells(grid, inflow) & ~solid
    dx = grid.dx
    fastest = inflow.speed + inflow.buoyancy / fps
    substeps = int(np.clip(np.ceil(fastest / fps / dx / 2.0), 1, 4))
    dt = 1.0 / (fps * substeps)
    d = np.zeros(grid.shape)
    u = np.zeros(grid.shape + (3,))
    p = np.zeros(grid.shape)
    flow = Flow(grid, np.zeros((frames,) + grid.shape, np.float32), solid)
    direction = np.asarray(inflow.direction, float)
    for t in range(1, frames):
        for _ in range(substeps):
            if inflow.emits_at(t):
                flow.emitted += float(np.clip(1.0 - d[src], 0, None).sum())
                d[src] = np.maximum(d[src], 1.0)
                wobble = rng.normal(0.0, 0.1, 3) * inflow.speed
                u[src] = inflow.speed * direction + wobble
            u[..., 1] += dt * inflow.buoyancy * d
            if vorticity > 0:
                u += dt * confine_vorticity(u, dx, vorticity)
            u, p = project(u, solid, dx, p)
            before = float(d.sum())
            gone = min(outflow(d, u, dt, dx), before)
            moved = advect(d, u, dt, dx)
            moved[solid] = 0.0
            total = float(moved.sum())
            factor = (before - gone) / total if total > 1e-12 else 1.0
            if before > 1e-12:
                flow.mass_factors.append(factor)
            d = moved * factor
            flow.outflow += gone
            u = advect(u, u, dt, dx)
        flow.density[t] = d
    return flow
