"""Particle sets in Taichi fields with a fixed capacity and an active count.

Rows [0, n) are active. Adding appends; removing compacts the survivors in their original order, so
indices stay stable up to the removed rows (checkpoints store rows in this order).
Housekeeping happens between steps, never inside a differentiated step.
"""
import numpy as np
import taichi as ti

from . import tensors
from .neighbors import NeighborTable
from .runtime import real


@ti.kernel
def _compact(field: ti.template(), rows: ti.types.ndarray(), kept: ti.i32, n: ti.i32):
    """field[k] = field[rows[k]] for k < kept (rows ascending, so rows[k] >= k: in order, no row is overwritten
    before it is read), then rows [kept, n) cleared."""
    ti.loop_config(serialize=True)
    for k in range(kept):
        field[k] = field[rows[k]]
    for k in range(kept, n):
        if ti.static(isinstance(field, ti.MatrixField)):
            for d in ti.static(range(field.n)):
                field[k][d] = 0
        else:
            field[k] = 0


class ParticleSet:
    """Named per-particle attributes ``{name: width}`` held in Taichi fields of ``capacity`` rows. Rows at and
    beyond the active count hold zeros. Every call moves the active rows only, one kernel per attribute.

    Args:
        capacity: most particles.
        attributes: attribute name -> number of components.
        defaults: attribute name -> value used for rows added without that attribute.
    """

    def __init__(self, capacity: int, attributes: dict, defaults: dict | None = None):
        self.capacity = int(capacity)
        self.n = 0
        self.widths = dict(attributes)
        self.defaults = dict(defaults or {})
        self.fields = {name: ti.Vector.field(w, real(), shape=self.capacity) if w > 1
                       else ti.field(real(), shape=self.capacity) for name, w in self.widths.items()}

    def __len__(self) -> int:
        return self.n

    def _shape(self, name: str, rows: int) -> tuple:
        return (rows, self.widths[name]) if self.widths[name] > 1 else (rows,)

    def get(self, name: str) -> np.ndarray:
        """Active rows of an attribute, [n, width] (or [n] for width 1)."""
        return tensors.store(self.fields[name], self.n).numpy()

    def set(self, name: str, values) -> None:
        """Overwrite the active rows of an attribute."""
        tensors.load(self.fields[name], np.asarray(values).reshape(self._shape(name, self.n)))

    def add(self, **values) -> slice:
        """Append rows; every attribute not given gets its default (or 0). Returns the new rows' slice."""
        unknown = set(values) - set(self.widths)
        if unknown:
            raise ValueError(f"unknown attributes {sorted(unknown)}")
        rows = {len(np.asarray(v)) for v in values.values()}
        if len(rows) != 1:
            raise ValueError("give at least one attribute, all with the same number of rows")
        count = rows.pop()
        if self.n + count > self.capacity:
            raise ValueError(f"adding {count} particles to {self.n} exceeds the capacity {self.capacity}")
        for name in self.widths:
            shape = self._shape(name, count)
            if name in values:
                v = np.asarray(values[name]).reshape(shape)
            else:
                v = np.broadcast_to(np.asarray(self.defaults.get(name, 0.0)), shape)
            tensors.load(self.fields[name], np.ascontiguousarray(v), start=self.n)
        rows = slice(self.n, self.n + count)
        self.n += count
        return rows

    def keep(self, mask) -> int:
        """Keep the active rows where ``mask`` [n] is true, in order; returns how many were removed."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.n,):
            raise ValueError(f"mask must have shape ({self.n},), got {mask.shape}")
        rows = np.flatnonzero(mask).astype(np.int32)
        kept = len(rows)
        if kept < self.n:
            for fld in self.fields.values():
                _compact(fld, rows, kept, self.n)
        removed, self.n = self.n - kept, kept
        return removed


class PhysicalParticles(ParticleSet):
    """Physical particles: position [m], velocity [m/s], force (last step's external acceleration) [m/s^2],
    age [s], smoke weight (1 = smoke, the default; 0 = ambient air, engine/ambient.py), rest volume (1 = the
    particle's own, the default; the entrainment term grows it, engine/entrainment.py)."""

    def __init__(self, capacity: int):
        super().__init__(capacity, {"position": 3, "velocity": 3, "force": 3, "age": 1, "smoke": 1, "volume": 1},
                         {"smoke": 1.0, "volume": 1.0})


class VisualParticles(ParticleSet):
    """Visual particles (3D Gaussians): position [m], colour [channels], scale [m, 3 axes], rotation (w, x, y, z),
    opacity. Defaults follow the release: grey 0.7, scale 0.0027 m, identity rotation, opacity 0.1."""

    def __init__(self, capacity: int, channels: int = 1):
        super().__init__(capacity, {"position": 3, "color": channels, "scale": 3, "rotation": 4, "opacity": 1},
                         {"color": 0.7, "scale": 0.0027, "rotation": (1.0, 0.0, 0.0, 0.0), "opacity": 0.1})


def removal_mask(positions: np.ndarray, table: NeighborTable | None, h: float, lo=None, hi=None,
                 field=None) -> np.ndarray:
    """Which rows to keep: finite, inside the box [lo, hi] (if given), and, with a table, not isolated.

    Args:
        positions: [n, 3] m.
        table: a neighbour table with capacity >= n; ``None`` skips the isolation test.
        h: neighbour radius [m].
        lo, hi: box corners [m]; ``None`` skips the box test.
        field: the Taichi field holding ``positions`` (rows [0, n)), used to build the table.
    """
    keep = np.isfinite(positions).all(axis=1)
    if lo is not None:
        keep &= (positions >= np.asarray(lo)).all(axis=1) & (positions <= np.asarray(hi)).all(axis=1)
    if table is not None and len(positions):
        table.build(field, len(positions), h)
        keep &= table.counts() > 0
    return keep


def prune(particles: ParticleSet, table: NeighborTable | None, h: float, lo=None, hi=None) -> int:
    """Remove non-finite particles, particles outside [lo, hi] and (with a table) isolated ones; returns
    how many were removed. The release deletes physical particles with no neighbour within h."""
    mask = removal_mask(particles.get("position"), table, h, lo, hi, particles.fields["position"])
    return particles.keep(mask)
