"""What a reconstruction needs besides the scene (settings, the PBF gas), the smoke inflow it starts from, and
the particle capacities its workspace is allocated for."""
from __future__ import annotations

from dataclasses import dataclass

from ..engine import ModelConfig, SolverConfig, cylinder_lattice
from ..errors import InputError
from ..scene import SCENE_FILE, Scene, Source
from ..scene_scale import SCALARFLOW_SOURCE_RADIUS, scaled_solver
from .config import ReconConfig
from .initial import physical_source, visual_source


@dataclass(frozen=True)
class RunSetup:
    """What a reconstruction needs besides the scene: settings, the PBF gas, and the resolved frame range."""

    config: ReconConfig
    solver: SolverConfig
    model: ModelConfig

    def to_dict(self) -> dict:
        return {"recon": self.config.to_dict(), "solver": self.solver.to_dict(), "model": self.model.to_dict()}


def default_setup(scene: Scene, config: ReconConfig, model: ModelConfig | None = None) -> RunSetup:
    """Settings for ``scene``: the solver's time step is one frame (1 / fps), its lengths follow the config's
    length scale (``scene_scale.scaled_solver``)."""
    solver = scaled_solver(SolverConfig(dt=1.0 / scene.fps), config.length_scale)
    return RunSetup(config, solver, model or ModelConfig.scalarflow())


def scene_source(scene: Scene, length_scale: float) -> Source:
    """The smoke inflow: the scene's ``source``, else a disk of ScalarFlow's radius times ``length_scale`` at the
    bottom centre of its volume."""
    if scene.source is not None:
        return scene.source
    if scene.volume is not None:
        return Source(tuple(float(v) for v in scene.volume.bottom_center),
                      SCALARFLOW_SOURCE_RADIUS * length_scale)
    raise InputError(scene.root / SCENE_FILE, "source", "the scene has neither a source nor a volume")


def capacities(n_frames: int, setup: RunSetup, source: Source, n_visual: int) -> tuple[int, int]:
    """Upper bounds of the physical and visual particle counts over a run (initial + every emission)."""
    cfg = setup.config
    cx, cy, cz = source.center
    n0 = len(cylinder_lattice((cx, cz), cfg.physical_radius, 0.0, cfg.physical_height, cfg.physical_spacing))
    steps = n_frames + cfg.stabilization_steps + 1
    visual = n_visual + (n_frames + 1) * visual_source(source, cfg).count + 64
    physical = n0 + steps * physical_source(source, cfg).count + 64
    if cfg.physical_support == "on":  # a frame seeds at most one particle per visual particle (support.py);
        # survivors of earlier frames can exceed this, and then the workspace grows (Workspace.reserve)
        physical += visual
    return physical, visual
