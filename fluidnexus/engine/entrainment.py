"""Entrainment: the paper's gas taking in the ambient air a turbulent plume draws in, without air particles.

Morton, Taylor and Turner (1956): ambient air flows into a plume across its edge at a speed proportional to the
plume's own, ``alpha`` times it, so a slice of plume of radius b moving at speed w relative to the air grows in
volume at the rate ``d ln V / dt = 2 alpha w / b``. Its smoke and its buoyancy are kept while its mass grows: the
smoke is diluted, the buoyant acceleration falls as 1/V, and the entrained air (at the ambient velocity) takes its
share of the momentum. In a steady plume this makes the radius grow linearly with height.

Here each particle is such a slice. After every PBF step (between steps, in numpy, never on the tape):

- b: the plume's radius at the particle's height along ``up`` (-gravity of the buoyancy term): particles binned
  in slabs one kernel radius thick; in each slab the top-hat radius ``sqrt(2 <r^2>)`` of the particles'
  distances r from the slab's centroid axis, at least the kernel radius;
- the particle's rest volume v grows by ``g = exp(2 alpha |u - v_env| dt / b)`` (v_env: the drag term's ambient
  velocity, else still air) and its velocity relative to the air falls by 1/g (momentum shared with the air);
- the PBF constraint holds a particle of volume v at rest density rho0 / v (engine/pbf.py ``_lambda``), so the
  plume widens, and buoyancy acts on the smoke concentration smoke / v (``PBFSimulator.load``).

Smoke is conserved: no particle is created or removed, and each keeps its smoke weight. ``alpha = 0`` changes
nothing (bit for bit). The coefficient is not differentiated (the growth happens between steps): diagnose fits it
derivative-free, and recon's gradient steps treat the volumes as constants.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Entrainment coefficients measured for turbulent plumes (top-hat profiles) lie around 0.1; reported values span
#: about this range (the report states a fitted value against it).
PLUME_RANGE = (0.08, 0.16)


@dataclass(frozen=True)
class Entrainment:
    """The entrainment term of the paper's gas. Attributes: alpha, the entrainment coefficient (0: none)."""

    alpha: float = 0.0

    def __post_init__(self):
        if not (np.isfinite(self.alpha) and self.alpha >= 0):
            raise ValueError(f"entrainment alpha must be a finite number >= 0, got {self.alpha}")

    def to_dict(self) -> dict:
        return {"alpha": float(self.alpha)}


def plume_radius(p: np.ndarray, up: np.ndarray, slab: float) -> np.ndarray:
    """The plume's top-hat radius [N] m at each particle's height: particles [N, 3] binned in slabs ``slab`` thick
    along ``up``; per slab ``sqrt(2 <|r|^2>)`` with r the offsets from the slab's centroid across ``up``; at least
    ``slab``."""
    s = p @ up
    k = np.floor((s - s.min()) / slab).astype(np.int64)
    across = p - s[:, None] * up
    count = np.bincount(k).astype(np.float64)
    centre = np.stack([np.bincount(k, across[:, a]) for a in range(3)], -1) / np.maximum(count, 1.0)[:, None]
    r2 = ((across - centre[k]) ** 2).sum(-1)
    mean_r2 = np.bincount(k, r2) / np.maximum(count, 1.0)
    return np.maximum(np.sqrt(2.0 * mean_r2[k]), slab)


def entrain(model, p: np.ndarray, u: np.ndarray, volume: np.ndarray, solver) -> tuple[np.ndarray, np.ndarray]:
    """(velocities [N, 3], rest volumes [N]) after one step's entrainment of ``model`` (a ModelConfig with an
    ``entrainment``) at positions p [N, 3] m, velocities u [N, 3] m/s, volumes [N]; ``solver`` gives dt and the
    kernel radius (the slab thickness)."""
    alpha = float(model.entrainment.alpha)
    if alpha == 0.0 or not len(p):
        return u, volume
    kinds = [t.kind for t in model.terms]
    gravity = np.asarray(model.term("buoyancy").gravity if "buoyancy" in kinds else (0.0, -9.8, 0.0), np.float64)
    up = -gravity / np.linalg.norm(gravity)
    v_env = np.asarray(model.term("drag").v_env if "drag" in kinds else (0.0, 0.0, 0.0), np.float64)
    p64, rel = np.asarray(p, np.float64), np.asarray(u, np.float64) - v_env
    b = plume_radius(p64, up, solver.h)
    growth = np.exp(2.0 * alpha * np.linalg.norm(rel, axis=1) * solver.dt / b)
    return (v_env + rel / growth[:, None]).astype(u.dtype), (volume * growth).astype(volume.dtype)
