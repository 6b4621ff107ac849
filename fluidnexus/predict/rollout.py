"""Physics-only rollout from a reconstructed state (FluidNexus Alg. S2, step 1).

Each future frame t repeats what the reconstruction does before its fit, without the fit: the emitter seeds frame
t's particles (the new Gaussians look like the recently emitted ones of the reconstruction, ``inflow_look``), the
PBF gas steps (p_t, u_t) = Sim(u_{t-1}, p_{t-1}) (with the interaction's wind term and obstacle if any, and the
model's entrainment), the visual particles are advected x_t = x_{t-1} + dt V_t(x_{t-1}) (Eq. 2) and pushed out of an
obstacle, and physical particles left without a neighbour are deleted (as in the release). A model whose structure
is the gas in ambient air rolls out in air instead (``air.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterator

import numpy as np
import torch

from .. import engine
from ..engine import ModelConfig, SolverConfig, Wind
from ..engine.entrainment import entrain
from ..errors import InputError
from ..recon.config import ReconConfig
from ..recon.initial import emit, physical_source, visual_source
from ..recon.smoke import Smoke
from ..recon.workspace import Workspace
from ..runs import Run
from ..scene import Source
from ..scenery.obstacles import join
from .air import air_capacity, air_rollout

WIND_PROFILES = {"uniform": "constant", "height": "ramp"}


@dataclass(frozen=True)
class RunContext:
    """What a rollout needs from a run folder: its settings, its smoke inflow, the scene's obstacles (an engine
    body, or None), the scene's volume ((lo, hi) [m], or None; the air of the gas in ambient air stays in it) and
    the paper's gas of the per-frame fits (``fit_model``: the reconstruction's model; the re-fit after refining
    runs it when the future is the gas in ambient air)."""

    config: ReconConfig
    solver: SolverConfig
    model: ModelConfig
    source: Source
    obstacle: object = None
    box: tuple | None = None
    fit_model: ModelConfig | None = None

    @classmethod
    def of(cls, run: Run) -> "RunContext":
        """The run's context; the scene's obstacles (declared, and found in its static layer) become engine
        bodies (the engine must be started)."""
        from fluidnexus.scenery.world import run_scenery

        cfg = run.config
        src = run.info.get("source") or _summary_source(run)
        volume = run.scene(check_videos=False).volume
        model = ModelConfig.from_dict(cfg["model"])
        return cls(ReconConfig.from_dict(cfg["recon"], run.root / "config.json"), SolverConfig.from_dict(cfg["solver"]),
                   model, Source.from_dict(src, run.root / "run.json"), run_scenery(run).obstacle,
                   None if volume is None else (tuple(volume.min), tuple(volume.max)),
                   ModelConfig.from_dict(cfg["fit_model"]) if "fit_model" in cfg else model)


def _summary_source(run: Run) -> dict:
    import json

    path = run.root / "summary.json"
    try:
        return json.loads(path.read_text())["source"]
    except (OSError, ValueError, KeyError):
        raise InputError(path, "source", "the run records no smoke source (is the reconstruction finished?)") from None


def parse_wind(text: str) -> tuple[float, float, float]:
    """``VX,VY,VZ`` (m/s^2) -> a finite 3-vector; InputError otherwise (NaN included)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(np.isfinite(values)):
        raise InputError(None, "--wind", f"expected three finite numbers VX,VY,VZ in m/s^2, got {text!r}")
    return values


def with_wind(model: ModelConfig, accel, profile: str, y0: float, height: float) -> ModelConfig:
    """``model`` plus a wind term (replacing one it has): ``uniform`` everywhere, ``height`` growing linearly from
    zero at ``y0`` to full strength ``height`` metres above (the release's clamped ramp)."""
    if profile not in WIND_PROFILES:
        raise InputError(None, "--profile", f"must be one of {sorted(WIND_PROFILES)}, got {profile!r}")
    wind = Wind(accel=tuple(float(a) for a in accel), profile=WIND_PROFILES[profile], y0=float(y0),
                height=float(height))
    return _with_wind_term(model, (wind,))


def _with_wind_term(model: ModelConfig, wind: tuple) -> ModelConfig:
    """``model`` with its wind term replaced by the terms ``wind`` (none or one)."""
    return replace(model, terms=tuple(t for t in model.terms if t.kind != "wind") + tuple(wind))


def refit_model(model: ModelConfig, ctx: RunContext) -> ModelConfig:
    """The model of the re-fit's per-frame fits for a future of ``model``: ``model`` itself for the paper's gas;
    for the gas in ambient air, the run's paper gas (``ctx.fit_model``) with ``model``'s wind term if it has one
    (the fit is the reconstruction's, whose smoke moves without air)."""
    if model.air is None:
        return model
    return _with_wind_term(ctx.fit_model, tuple(t for t in model.terms if t.kind == "wind"))


def capacities(smoke: Smoke, frames: int, ctx: RunContext, model: ModelConfig) -> tuple[int, int, int]:
    """(physical, smoke, visual) particle capacities of a future of ``frames`` frames from ``smoke``: the smoke plus
    every emission; the workspace's physical side holds the air too with the gas in ambient air (an estimate,
    ``air.air_capacity``)."""
    phys = smoke.p.shape[0] + (frames + 1) * physical_source(ctx.source, ctx.config).count + 64
    vis = smoke.x.shape[0] + (frames + 1) * visual_source(ctx.source, ctx.config).count + 64
    return (phys if model.air is None else air_capacity(smoke, frames, ctx, model)), phys, vis


def workspace_for(smoke: Smoke, frames: int, ctx: RunContext, model: ModelConfig) -> Workspace:
    """A workspace large enough for ``smoke`` plus ``frames`` frames of emission (and the air, ``capacities``)."""
    phys, _, vis = capacities(smoke, frames, ctx, model)
    return Workspace(phys, vis, ctx.solver, model)


INFLOW_FRAMES = 30


def inflow_look(smoke: Smoke, ctx: RunContext, frames: int = INFLOW_FRAMES) -> tuple:
    """(colour [C], scale, opacity) of the future's new Gaussians: the median appearance the reconstruction gave the
    Gaussians its emitter seeded in the last ``frames`` frames (rows are appended in order, a fixed number per
    frame). The fit turns most of them nearly transparent (ScalarFlow: median opacity 0.004 against the initial
    0.1), so new smoke in the future looks like the inflow the footage showed, not like the constant initial look."""
    rows = min(smoke.x.shape[0], frames * visual_source(ctx.source, ctx.config).count)
    if rows == 0:
        return ctx.config.color0, ctx.config.scale0, ctx.config.opacity0
    recent = slice(smoke.x.shape[0] - rows, None)
    return (smoke.color[recent].median(dim=0).values, float(smoke.scale[recent].mean(dim=1).median()),
            float(smoke.opacity[recent].median()))


def physics_step(smoke: Smoke, volume: torch.Tensor, ws: Workspace, ctx: RunContext,
                 look=None) -> tuple[Smoke, torch.Tensor]:
    """Frame ``smoke.frame + 1`` by physics alone (``smoke`` itself is left as it is), around the workspace's
    obstacle; new Gaussians get ``look`` (default: the constant initial appearance). ``volume`` [N]: the physical
    particles' rest volumes, which the model's entrainment grows (engine/entrainment.py; new particles start at
    1); returned with the frame."""
    t = smoke.frame + 1
    smoke = replace(smoke)  # emit appends to its argument
    emit(smoke, ctx.source, ctx.config, t, look, obstacle=ws.obstacle)
    volume = torch.cat([volume, torch.ones(smoke.p.shape[0] - volume.shape[0], dtype=volume.dtype)])
    p, u = ws.simulate(smoke.p, smoke.u, smoke.age, volume=volume)
    if ws.model.entrainment is not None:
        u_np, v_np = entrain(ws.model, p.numpy(), u.numpy(), volume.numpy(), ws.solver)
        u, volume = torch.as_tensor(u_np), torch.as_tensor(v_np)
    kept = ~ws.isolated(p)  # the visual particles move with the particles the frame keeps (as in recon)
    p, u, age, volume = p[kept], u[kept], (smoke.age + ws.dt)[kept], volume[kept]
    with torch.no_grad():
        x = engine.advect(smoke.x, p, u, ws.dt, ws.advect_query)
    x = ws.push_out(x)
    return Smoke(t, p, u, age, x, smoke.color, smoke.scale, smoke.rotation, smoke.opacity), volume


def rollout(start: Smoke, frames: int, ws: Workspace, ctx: RunContext, obstacle=None) -> Iterator[Smoke]:
    """Yield ``frames`` future frames after ``start`` around the scene's obstacles and ``obstacle`` (``ws`` keeps
    them set), in the structure of ``ws.model`` (the paper's gas, or the gas in ambient air: ``air.air_rollout``)."""
    if frames <= 0:
        raise InputError(None, "--frames", f"must be > 0, got {frames}")
    ws.set_obstacle(join(ctx.obstacle, obstacle))
    smoke, look = start, inflow_look(start, ctx)
    if ws.model.air is not None:
        yield from air_rollout(start, frames, ws, ctx, look)
        return
    volume = torch.ones(start.p.shape[0], dtype=start.p.dtype)  # the reconstruction's particles: their own volume
    for _ in range(frames):
        smoke, volume = physics_step(smoke, volume, ws, ctx, look)
        yield smoke


def constant_appearance(smoke: Smoke, cfg: ReconConfig) -> Smoke:
    """``smoke`` with every Gaussian at the constant initial appearance (colour, scale, opacity, no rotation)."""
    m, dtype = smoke.x.shape[0], smoke.x.dtype
    rot = torch.zeros((m, 4), dtype=dtype)
    rot[:, 0] = 1.0
    return replace(smoke, color=torch.full((m, smoke.color.shape[1]), cfg.color0, dtype=dtype),
                   scale=torch.full((m, 3), cfg.scale0, dtype=dtype), rotation=rot,
                   opacity=torch.full((m,), cfg.opacity0, dtype=dtype))
