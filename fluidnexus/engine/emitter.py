"""Sources and initial states of the gas: the emitter disk, the initial cylinder lattice, stabilisation.

Defaults follow the FluidNexus release's ScalarFlow constants: source centre (x, z) = (0.34, -0.225) at y = 0,
physical spacing 0.015 m in a disk of radius 0.09 m, visual spacing 0.00625 m in a disk of radius 0.025 m; initial
lattice 0.009 m in a cylinder of radius 0.10 m, y in [-0.02, 0.08].

A source points along a unit ``direction`` (default up, +y): its disk is perpendicular to it and the lattices
built for the default up direction are turned onto it by :func:`orient` (the minimal rotation taking +y to the
direction; the identity, and therefore bit-exact, for +y).
"""
from dataclasses import dataclass

import numpy as np


def disk_lattice(center, radius: float, spacing: float) -> np.ndarray:
    """Points of a square lattice of ``spacing`` [m] in the horizontal disk (centre (x, y, z), radius) [M, 3]."""
    m = int(np.floor(radius / spacing))
    a = np.arange(-m, m + 1) * spacing
    gx, gz = np.meshgrid(a, a, indexing="ij")
    inside = gx**2 + gz**2 <= radius**2 + 1e-12
    pts = np.stack([gx[inside], np.zeros(inside.sum()), gz[inside]], -1)
    return pts + np.asarray(center, dtype=np.float64)


def cylinder_lattice(center_xz, radius: float, y0: float, y1: float, spacing: float) -> np.ndarray:
    """Points of a cubic lattice of ``spacing`` [m] inside the vertical cylinder over (x, z), y in [y0, y1]."""
    ys = np.arange(y0, y1 + 1e-12, spacing)
    disk = disk_lattice((center_xz[0], 0.0, center_xz[1]), radius, spacing)
    return np.concatenate([disk + np.array([0.0, y, 0.0]) for y in ys]) if len(ys) else np.zeros((0, 3))


UP = (0.0, 1.0, 0.0)


def rotation_from_up(direction) -> np.ndarray:
    """[3, 3] the minimal rotation taking +y onto the unit vector ``direction`` (180 degrees about x for -y)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    up = np.array(UP)
    c = float(d @ up)
    if c < -1.0 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(up, d)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + kx + kx @ kx / (1.0 + c)


def orient(points: np.ndarray, origin, direction) -> np.ndarray:
    """``points`` [M, 3] laid out for a source pointing up at ``origin``, turned about ``origin`` so that up
    becomes ``direction``. Returned unchanged (bit for bit) for the up direction."""
    if tuple(float(v) for v in direction) == UP:
        return points
    o = np.asarray(origin, dtype=np.float64)
    return (np.asarray(points, dtype=np.float64) - o) @ rotation_from_up(direction).T + o


@dataclass(frozen=True)
class SourceDisk:
    """An emitter: each emission seeds a jittered disk lattice of particles.

    Attributes:
        center: disk centre (x, y, z) [m].
        radius: disk radius [m].
        direction: unit normal of the disk, the way the smoke leaves the source (default up).
        spacing: lattice spacing [m].
        jitter: uniform random offset per axis, as a fraction of the spacing.
        velocity: initial velocity of the seeded particles [m/s].
        every: emit once every ``every`` steps (seeding rate = count / (every * dt) particles per second).
    """

    center: tuple = (0.34, 0.0, -0.225)
    radius: float = 0.09
    spacing: float = 0.015
    jitter: float = 0.1
    velocity: tuple = (0.0, 0.0, 0.0)
    every: int = 1
    direction: tuple = UP

    @property
    def count(self) -> int:
        """Particles seeded per emission."""
        return len(disk_lattice(self.center, self.radius, self.spacing))

    def lattice(self) -> np.ndarray:
        """The disk's lattice points [count, 3] m, perpendicular to ``direction``."""
        return orient(disk_lattice(self.center, self.radius, self.spacing), self.center, self.direction)

    def emits_at(self, step: int) -> bool:
        return step % self.every == 0

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """Seeded positions [count, 3] m for one emission."""
        pts = self.lattice()
        return pts + rng.uniform(-0.5, 0.5, pts.shape) * self.jitter * self.spacing

    def emit(self, particles, step: int, rng: np.random.Generator) -> int:
        """Append one emission to a particle set at ``step`` (if it emits then); returns the number added."""
        if not self.emits_at(step):
            return 0
        pts = self.sample(rng)
        values = {"position": pts}
        if "velocity" in particles.widths:
            values["velocity"] = np.broadcast_to(np.asarray(self.velocity, dtype=np.float64), pts.shape)
        particles.add(**values)
        return len(pts)


SCALARFLOW_PHYSICAL_SOURCE = SourceDisk()
SCALARFLOW_VISUAL_SOURCE = SourceDisk(radius=0.025, spacing=0.00625)


def scalarflow_initial_lattice(spacing: float = 0.009, radius: float = 0.10, y0: float = -0.02,
                               y1: float = 0.08, center_xz=(0.34, -0.225)) -> np.ndarray:
    """The release's ScalarFlow initial physical particles (about 4.6 k with the defaults) [N, 3] m."""
    return cylinder_lattice(center_xz, radius, y0, y1, spacing)


def stabilize(step_fn, particles, steps: int = 20, sources=(), rng: np.random.Generator | None = None,
              prune_fn=None) -> None:
    """N_stable stabilisation steps before reconstruction (FluidNexus supp. "Initialization").

    Args:
        step_fn: advances ``particles`` by one simulation step in place (e.g. ``Simulation.step``).
        particles: the physical particle set.
        steps: N_stable (20 in the paper).
        sources: emitters seeding new particles before each step.
        rng: random generator for the emitter jitter.
        prune_fn: optional housekeeping called after each step (e.g. removal of isolated particles).
    """
    rng = rng or np.random.default_rng(0)
    for s in range(steps):
        for src in sources:
            src.emit(particles, s, rng)
        step_fn(particles)
        if prune_fn is not None:
            prune_fn(particles)
