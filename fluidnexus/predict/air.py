"""The physics rollout in ambient air: the model structure ``ambient_air`` (engine/ambient.py) continuing a run.

At the start frame the run's smoke keeps its reconstructed physical particles (positions, velocities, ages; smoke
weight 1) and is surrounded by air at rest (weight 0) on the rest density's lattice (``AirDomain.initial``); the
run's source is the inlet. Each future frame: the emitter seeds the frame's Gaussians (the smoke's physical
particles come from the inlet, not from the emitter), one step of the gas in air (``AirDomain.step``: inlet while the
source is on, the PBF step of smoke and air together, the wind shift, the open boundaries), then the Gaussians move
with the gas: ``x_t = x_{t-1} + dt (V_t(x_{t-1}) + wind)``, V (Eq. 2) interpolated over smoke and air particles alike.
The Gaussians are dye in the gas, and air is gas too: at the plume's edge they move with the mixture, not with the
smoke's core speed that an interpolation over smoke alone would carry into the air; in still air they stay still.
The air lives in the rollout only: the frames hold the smoke's physical particles (world velocities, the wind
added back), so render, eval and export read them unchanged.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Iterator

import numpy as np
import torch

from .. import engine
from ..engine import AirDomain, AmbientAir, ModelConfig
from ..errors import InputError
from ..recon.initial import emit
from ..recon.smoke import Smoke
from ..scene import UP

#: The smoke's speed the air estimate starts from: this quantile of its particles' speeds.
SPEED_QUANTILE = 0.99


def _numpy(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().numpy().astype(np.float64)


def air_domain(ctx, air: AmbientAir, obstacle=None) -> AirDomain:
    """The air around the source of ``ctx`` (``rollout.RunContext``), inside the scene's volume if it has one, with
    the run's solver (its rest density sets the air lattice); no air inside ``obstacle``."""
    if not np.allclose(ctx.source.direction, UP):
        raise InputError(None, "--model", "the gas in ambient air (ambient_air) needs an upward source (its inlet "
                         f"pipe is vertical); this run's source points along {list(ctx.source.direction)}")
    s = ctx.solver
    lo, hi = ctx.box if ctx.box is not None else (None, None)
    return AirDomain(air, s.h, s.rest_density, s.dt, ctx.source.center, ctx.source.radius, lo, hi, obstacle)


def air_capacity(smoke: Smoke, frames: int, ctx, model: ModelConfig) -> int:
    """Estimated most particles, smoke and air, over ``frames`` frames of ``model`` (the gas in ambient air) from
    ``smoke``: the region grown by the distance ``v T + a T^2 / 2`` (``AirDomain.reach``) that smoke covers in
    T = ``frames`` dt from the faster of the inflow and its ``SPEED_QUANTILE`` speed (plus the wind's) under the
    model's accelerations (buoyancy |alpha g| and the wind term; the air's drag is left out, so the region rarely
    gets there). The workspace grows beyond it if the plume needs more."""
    p = _numpy(smoke.p)
    speed = model.air.inflow
    if len(p):
        speed = max(speed, float(np.quantile(np.linalg.norm(_numpy(smoke.u), axis=1), SPEED_QUANTILE)))
    accel = sum(abs(t.alpha) * float(np.linalg.norm(t.gravity)) if t.kind == "buoyancy" else
                float(np.linalg.norm(t.accel)) for t in model.terms if t.kind in ("buoyancy", "wind"))
    T = frames * ctx.solver.dt
    distance = (speed + float(np.linalg.norm(model.air.wind))) * T + 0.5 * accel * T**2
    return air_domain(ctx, model.air).reach(p, distance)


def air_rollout(start: Smoke, frames: int, ws, ctx, look) -> Iterator[Smoke]:
    """Yield ``frames`` future frames after ``start`` in the air of ``ws.model`` (``ws``: a ``recon.Workspace``
    with its obstacle set; it grows with the air); new Gaussians get ``look``."""
    air = ws.model.air
    domain = air_domain(ctx, air, ws.obstacle)
    wind = np.asarray(air.wind, np.float64)
    shift = torch.as_tensor(wind * ws.dt, dtype=ws.dtype)
    state = domain.initial(_numpy(start.p), _numpy(start.u) - wind, _numpy(start.age))  # velocities relative to air
    smoke = start
    for _ in range(frames):
        t = smoke.frame + 1
        smoke = replace(smoke)  # emit appends to its argument
        emit(smoke, ctx.source, ctx.config, t, look, physical=False)
        ws.reserve(state.n)
        state = domain.step(ws.sim, state, inflow=ctx.source.emits_at(t))
        ws.reserve(state.n)  # the open boundaries may have added air
        p, u, age = (torch.as_tensor(a, dtype=ws.dtype) for a in (state.p, state.u, state.age))
        with torch.no_grad():
            x = engine.advect(smoke.x, p, u, ws.dt, ws.advect_query) + shift
        gas = torch.as_tensor(state.is_smoke)
        smoke = Smoke(t, p[gas], u[gas] + torch.as_tensor(wind, dtype=ws.dtype), age[gas], ws.push_out(x),
                      smoke.color, smoke.scale, smoke.rotation, smoke.opacity)
        yield smoke
