"""The scene's length scale: one factor that sizes every length setting of every stage (docs/scale.md).

The project's length settings (particle spacings, the smoothing length H, emitter radii, the hull voxel, the
Gaussians' initial size, axisym's smoothing and depth spread, diagnose's spacing, ...) were tuned on the
ScalarFlow capture, whose reconstruction volume is 0.4909 x 0.73635 x 0.4909 m. A scene of another size gets
each of them multiplied by

    factor = round3(cbrt(volume of the scene's box) / cbrt(ScalarFlow's box volume))

(``round3``: three significant figures), so a scene twice as large gets particles twice as far apart and the
same particle counts. Without a volume the source disk decides: ``source.radius / 0.025 m`` (the ScalarFlow
import's disk), rounded the same way; with neither the factor is 1. The rounding makes the factor exactly 1
on ScalarFlow (its settings are bit-identical to the tuned values) and exactly 10 on a copy scaled by 10.

Physical constants are not lengths of the scene and are not scaled: gravity, buoyancy and drag act in
metres and seconds, so a scene must be in metres (``calibrate --metres-per-unit``) for its gas to rise at a
physical rate. A scene in unknown units still gets particles sized to it; its gas then rises as a plume of
that many metres would.
"""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the engine (Taichi) is not imported by the commands that only need the factor
    from .engine import SolverConfig
    from .scene import Scene

# The box the ScalarFlow settings were tuned on (its PINF voxel_scale, metres) and its import's source disk.
SCALARFLOW_BOX = (0.4909, 0.73635, 0.4909)
SCALARFLOW_SOURCE_RADIUS = 0.025

# Lengths the pipelines use at ScalarFlow's scale (metres); each is multiplied by the scene's factor where used.
SOURCE_SLAB = 0.01  # recon's source finder: thickness of the slab at the foot of the first frame's hull
DIAGNOSE_SPACING = 0.02  # diagnose's particle spacing (``diagnose --spacing``)
PLUME_BOX_BELOW = (0.3, 0.05, 0.3)  # diagnose without a volume: the box from the source down (x, y, z) ...
PLUME_BOX_ABOVE = (0.3, 0.8, 0.3)  # ... and up
WIND_HEIGHT = 0.5  # interact --wind without a volume: the height over which a profiled wind grows


def _round3(x: float) -> float:
    return float(f"{x:.3g}")


def box_size(extent) -> float:
    """The size of a box: the cube root of its volume (metres)."""
    e = np.asarray(extent, dtype=np.float64)
    return float(np.prod(e) ** (1.0 / 3.0))


def volume_factor(volume) -> float:
    """The length-scale factor of a scene whose reconstruction box is ``volume`` (``scene.Volume``)."""
    return _round3(box_size(np.subtract(volume.max, volume.min)) / box_size(SCALARFLOW_BOX))


def scene_factor(scene: "Scene") -> float:
    """The length-scale factor of ``scene`` against ScalarFlow (module docstring)."""
    if scene.volume is not None:
        return volume_factor(scene.volume)
    if scene.source is not None:
        return _round3(scene.source.radius / SCALARFLOW_SOURCE_RADIUS)
    return 1.0


def scaled(values: dict[str, float], factor: float) -> dict[str, float]:
    """Each length of ``values`` (metres at ScalarFlow's scale) multiplied by ``factor``."""
    return {k: v * factor for k, v in values.items()}


def scaled_solver(solver: "SolverConfig", factor: float) -> "SolverConfig":
    """The PBF constants for a scene ``factor`` times ScalarFlow's size: H scales as a length, the rest density
    (particles per m^3) as 1/length^3, the relaxation epsilon [1/m^2] as 1/length^2 and the tensile-correction
    strength [m^2] as length^2, so the dimensionless solver behaves identically on the scaled lattice."""
    if factor == 1.0:
        return solver
    return replace(solver, h=solver.h * factor, rest_density=solver.rest_density / factor**3,
                   eps=solver.eps / factor**2, scorr_k=solver.scorr_k * factor**2)
