"""The gas in ambient air: a model structure in which the PBF smoke rises through air particles.

The paper's gas (structure ``paper_gas``) is smoke particles alone in empty space: it has no air to entrain,
to pass momentum to or to hold a swirl in (docs/diagnose.md). The structure ``ambient_air`` fills the space
around and above the smoke with air particles of the same PBF gas at its rest density:

- **Air region**: the lattice of the rest density (spacing ``rest_spacing(solver)``, anchored at the source
  centre) in a box that follows the smoke: the smoke's horizontal extent (percentiles ``STRAY``, ``100 - STRAY``)
  and the source disk, plus ``margin`` source radii on every side and above the highest smoke, from ``below``
  source radii under the source. It
  grows upward as the smoke rises; its top is an outlet.
- **Open boundaries**: particles leaving a shell of ``SHELL`` lattice spacings around the region are removed;
  vacant lattice sites of the shell (no particle within ``VACANT`` spacings) are refilled with air at rest.
- **Inlet**: the source is a pipe (the source disk's cylinder below the source up to the source plane) whose
  particles move up at the inflow speed; particles in its top slab become smoke (smoke weight 1, age 0).
  No mass is injected: the pipe draws air in through the open bottom.
- **Buoyancy on smoke only**: each particle's smoke weight (1 smoke, 0 air) multiplies the buoyancy term
  (``forces.Buoyancy``); every other term acts on all particles (XSPH viscosity among smoke and air alike).
- **Wind**: the air's own motion, as a Galilean shift: every particle moves by ``wind dt`` after each step
  (velocities are relative to the air), the source stays fixed, so the fitted value is the air's speed.

Housekeeping (inlet, shift, boundaries) runs between steps in numpy, never on the tape. Air particles are
never rendered and never counted as smoke.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from .sph import lattice_density, point_density

#: The model structures: the paper's gas in empty space, or the gas in ambient air.
STRUCTURES = ("paper_gas", "ambient_air")
#: Thickness of the open-boundary shell around the air region, in lattice spacings.
SHELL = 2
#: The region follows the smoke's horizontal extent between these percentiles (a few stray smoke particles may
#: leave the air; those leaving the shell are removed).
STRAY = 1.0
#: A shell site is vacant when no particle lies within this many lattice spacings of it.
VACANT = 0.6
#: At the start, a vacant site gets air only where the smoke's own density is below this fraction of the rest
#: density: smoke at any positions (a reconstructed state) leaves sites between its particles further than
#: ``VACANT`` spacings from any, and air there would compress it (to 1.45 rest density on a ScalarFlow state,
#: 1.13 with this test).
FILL = 0.5


@dataclass(frozen=True)
class AmbientAir:
    """Parameters of the ambient-air structure (lengths in source radii, so they follow the scene's source).

    Attributes:
        inflow: speed [m/s] at which the inlet pipe pushes air up through the source disk.
        wind: the air's velocity (vx, vy, vz) [m/s].
        margin: air kept beside and above the smoke, in source radii.
        below: depth of the inlet pipe (and of the air region) below the source plane, in source radii.
    """

    inflow: float = 0.25
    wind: tuple = (0.0, 0.0, 0.0)
    margin: float = 1.5
    below: float = 1.2
    name: ClassVar[str] = "ambient_air"

    def __post_init__(self):
        if len(self.wind) != 3 or not np.all(np.isfinite(self.wind)):
            raise ValueError(f"ambient_air wind must be three finite numbers, got {self.wind}")
        if not (np.isfinite(self.inflow) and self.inflow >= 0):
            raise ValueError(f"ambient_air inflow must be >= 0 m/s, got {self.inflow}")
        if not (self.margin > 0 and self.below > 0):
            raise ValueError(f"ambient_air margin and below must be > 0 source radii, got {self.margin}, {self.below}")

    def to_dict(self) -> dict:
        return {"name": self.name, "inflow": float(self.inflow), "wind": [float(w) for w in self.wind],
                "margin": float(self.margin), "below": float(self.below)}


def structure_to_dict(air: AmbientAir | None) -> dict:
    """model.json's ``structure``: ``{"name": "paper_gas"}`` or the ambient air's parameters."""
    return {"name": "paper_gas"} if air is None else air.to_dict()


def structure_from_dict(d: dict) -> AmbientAir | None:
    """The inverse of :func:`structure_to_dict` (None is the paper's gas); ValueError on unknown names or keys."""
    d = dict(d)
    name = d.pop("name", None)
    if name not in STRUCTURES:
        raise ValueError(f"unknown model structure {name!r}; known: {list(STRUCTURES)}")
    if name == "paper_gas":
        if d:
            raise ValueError(f"the paper_gas structure has no parameters, got {sorted(d)}")
        return None
    unknown = set(d) - {"inflow", "wind", "margin", "below"}
    if unknown:
        raise ValueError(f"unknown keys for structure 'ambient_air': {sorted(unknown)}")
    if "wind" in d:
        d["wind"] = tuple(float(w) for w in d["wind"])
    return AmbientAir(**d)


def rest_spacing(h: float, rest_density: float) -> float:
    """Spacing [m] of the cubic lattice whose Poly6 density equals ``rest_density`` (air at rest)."""
    lo, hi = 0.05 * h, 2.0 * h  # lattice_density falls as the spacing grows
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if lattice_density(mid, h) > rest_density else (lo, mid)
    return 0.5 * (lo + hi)


@dataclass
class AirState:
    """Particles of the gas in air (numpy, float64): positions p [N, 3] m, velocities u [N, 3] m/s (relative to
    the air), ages [N] s, smoke weights [N] (1 smoke, 0 air)."""

    p: np.ndarray
    u: np.ndarray
    age: np.ndarray
    smoke: np.ndarray

    @property
    def n(self) -> int:
        return len(self.p)

    @property
    def is_smoke(self) -> np.ndarray:
        return self.smoke > 0.5

    def take(self, mask) -> "AirState":
        return AirState(self.p[mask], self.u[mask], self.age[mask], self.smoke[mask])

    def append(self, p, u, age, smoke) -> "AirState":
        return AirState(np.concatenate([self.p, p]), np.concatenate([self.u, u]), np.concatenate([self.age, age]),
                        np.concatenate([self.smoke, smoke]))


class AirDomain:
    """The air around one source: region, inlet, open boundaries and wind of the ambient-air structure.

    Args:
        air: the structure's parameters.
        h, rest_density, dt: the solver's kernel radius [m], rest density [1/m^3] and step [s].
        source_center: (x, y, z) of the source disk [m]; source_radius: its radius [m].
        lo, hi: optional scene box [m]; the air region never leaves it (its top is then the outlet), except the
            inlet pipe and its shell, which may reach under the box's floor.
        obstacle: optional rigid body (``engine.obstacle``, with ``distance(points)``); no air is placed inside it.
    """

    def __init__(self, air: AmbientAir, h: float, rest_density: float, dt: float, source_center, source_radius: float,
                 lo=None, hi=None, obstacle=None):
        self.air, self.dt, self.h, self.rest_density = air, float(dt), float(h), float(rest_density)
        self.center, self.radius = np.asarray(source_center, np.float64), float(source_radius)
        self.spacing = rest_spacing(h, rest_density)
        self.obstacle = obstacle
        self.lo = None if lo is None else np.asarray(lo, np.float64).copy()
        if self.lo is not None:  # the inlet pipe and its shell stay, also under the scene box's floor
            self.lo[1] = min(self.lo[1], self.center[1] - air.below * self.radius - SHELL * self.spacing)
        self.hi = None if hi is None else np.asarray(hi, np.float64)
        self.slab = max(self.spacing, air.inflow * self.dt)  # every particle crossing the source spends a step in it

    # ---------------------------------------------------------------- geometry
    def region(self, smoke_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inner air region (lo, hi) [m] for the smoke positions [M, 3]: the smoke and the source disk, plus the
        margin beside and above, from ``below`` under the source."""
        r, c = self.radius, self.center
        m = self.air.margin * r
        lo = np.array([c[0] - r, c[1] - self.air.below * r, c[2] - r])
        hi = np.array([c[0] + r, c[1], c[2] + r])
        if len(smoke_p):  # the smoke's extent without its few farthest stray particles
            lo[[0, 2]] = np.minimum(lo[[0, 2]], np.percentile(smoke_p[:, [0, 2]], STRAY, axis=0))
            hi[[0, 2]] = np.maximum(hi[[0, 2]], np.percentile(smoke_p[:, [0, 2]], 100 - STRAY, axis=0))
            hi[1] = max(hi[1], smoke_p[:, 1].max())
        lo[[0, 2]] -= m
        hi += m
        return self._clip(lo), self._clip(hi)

    def _clip(self, x: np.ndarray) -> np.ndarray:
        return x if self.lo is None else np.clip(x, self.lo, self.hi)

    def outer(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The region with its open-boundary shell."""
        d = SHELL * self.spacing
        return self._clip(lo - d), self._clip(hi + d)

    def _axes(self, lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
        s, c = self.spacing, self.center
        return [c[a] + s * np.arange(np.ceil((lo[a] - c[a]) / s - 1e-9), np.floor((hi[a] - c[a]) / s + 1e-9) + 1)
                for a in range(3)]

    def sites(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Lattice sites [K, 3] (spacing ``self.spacing``, anchored at the source centre) inside [lo, hi]."""
        return np.stack(np.meshgrid(*self._axes(lo, hi), indexing="ij"), -1).reshape(-1, 3)

    def _bound(self, lo: np.ndarray, hi: np.ndarray, smoke: int) -> int:
        """The lattice sites of [lo, hi] with 25 % slack for compression, plus ``smoke`` particles."""
        return int(1.25 * np.prod([len(axis) for axis in self._axes(lo, hi)])) + int(smoke) + 64

    def capacity(self, smoke: int = 0) -> int:
        """Most particles the domain can hold inside the scene box (needs ``lo``, ``hi``), 25 % slack for
        compression, plus ``smoke`` particles."""
        if self.lo is None:
            raise ValueError("capacity needs the scene box (lo, hi)")
        return self._bound(self.lo, self.hi, smoke)

    def reach(self, smoke_p: np.ndarray, distance: float) -> int:
        """Particles the domain holds once the smoke at ``smoke_p`` [M, 3] m has moved up to ``distance`` m
        further: the lattice sites of the region grown by ``distance`` upward and sideways (within the scene box)
        and of its shell, 25 % slack for compression, plus the smoke."""
        lo, hi = self.region(smoke_p)
        d = max(float(distance), 0.0)
        lo[[0, 2]] -= d
        hi += d
        return self._bound(*self.outer(self._clip(lo), self._clip(hi)), len(smoke_p))

    def in_pipe(self, p: np.ndarray) -> np.ndarray:
        """[N] bool: inside the inlet pipe (the source disk's cylinder below the source plane)."""
        d = p - self.center
        return (d[:, 0] ** 2 + d[:, 2] ** 2 <= self.radius**2) & (d[:, 1] < 0.0)

    # ---------------------------------------------------------------- state
    def initial(self, smoke_p=None, smoke_u=None, smoke_age=None) -> AirState:
        """Smoke particles (default none; any positions) surrounded by air at rest on every lattice site of the
        region and its shell that the smoke does not occupy (no smoke particle within ``VACANT`` spacings, smoke
        density below ``FILL`` x the rest density)."""
        sp = np.zeros((0, 3)) if smoke_p is None else np.asarray(smoke_p, np.float64).reshape(-1, 3)
        su = np.zeros_like(sp) if smoke_u is None else np.asarray(smoke_u, np.float64).reshape(-1, 3)
        sa = np.zeros(len(sp)) if smoke_age is None else np.asarray(smoke_age, np.float64).ravel()
        state = AirState(sp, su, sa, np.ones(len(sp)))
        sites = self.sites(*self.outer(*self.region(sp)))
        sites = sites[point_density(sites, sp, self.h) < FILL * self.rest_density]
        return self._fill(state, sites)

    def _fill(self, state: AirState, sites: np.ndarray) -> AirState:
        """``state`` plus air at rest on the vacant ``sites`` outside the obstacle."""
        if self.obstacle is not None and len(sites):
            sites = sites[self.obstacle.distance(sites) > 0]
        if len(state.p) and len(sites):
            dist, _ = cKDTree(state.p).query(sites, distance_upper_bound=VACANT * self.spacing)
            sites = sites[~np.isfinite(dist)]
        k = len(sites)
        return state.append(sites, np.zeros((k, 3)), np.zeros(k), np.zeros(k))

    def inlet(self, state: AirState, omega: float = 0.0) -> None:
        """In place: particles in the pipe move up at the inflow speed (world frame; plus the swirl
        ``(0, omega, 0) x r``); those in its top slab become smoke of age 0."""
        pipe = self.in_pipe(state.p)
        r = state.p[pipe] - self.center
        v = np.stack([omega * r[:, 2], np.full(len(r), self.air.inflow), -omega * r[:, 0]], -1)
        state.u[pipe] = v - np.asarray(self.air.wind)  # velocities are relative to the moving air
        top = pipe & (state.p[:, 1] >= self.center[1] - self.slab)
        state.smoke[top] = 1.0
        state.age[top] = 0.0

    def housekeep(self, state: AirState) -> AirState:
        """After a step: the wind shift, removal outside the shell (and non-finite rows), refill of the shell."""
        state.p += np.asarray(self.air.wind) * self.dt
        state.age += self.dt
        lo, hi = self.region(state.p[state.is_smoke & np.isfinite(state.p).all(1)])
        olo, ohi = self.outer(lo, hi)
        keep = np.isfinite(state.p).all(1) & np.isfinite(state.u).all(1)
        keep &= (state.p >= olo).all(1) & (state.p <= ohi).all(1)
        state = state.take(keep)
        sites = self.sites(olo, ohi)
        shell = ~((sites > lo).all(1) & (sites < hi).all(1))
        return self._fill(state, sites[shell])

    def step(self, sim, state: AirState, omega: float = 0.0, inflow: bool = True) -> AirState:
        """One step of the gas in air: inlet (unless ``inflow`` is off: a source switched off), the PBF step of
        ``sim`` (engine.PBFSimulator, any model terms, with its loaded parameters and obstacle) on smoke and air
        together, housekeeping. Returns the new state (``state`` is changed)."""
        if inflow:
            self.inlet(state, omega)
        if state.n > sim.capacity:
            raise ValueError(f"{state.n} particles exceed the simulator capacity {sim.capacity}")
        sim.load(state.p, state.u, state.age, state.smoke)
        sim.forward()
        p, u = sim.result()
        state = AirState(p.double().numpy(), u.double().numpy(), state.age, state.smoke)
        return self.housekeep(state)
