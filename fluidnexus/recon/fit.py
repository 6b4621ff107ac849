"""The per-frame optimisations of FluidNexus Alg. S1.

- :func:`fit_look`: the earliest frame with smoke, before the positions: one colour and one opacity shared by every
  visual particle (the initial look; on footage over a backdrop the release's constants, tuned to faint smoke on
  black, can be far off, e.g. dense grey smoke on white).
- :func:`fit_positions`: frame 0, visual positions only.
- :func:`fit_dynamics`: stage 1, the physical positions p_t (Eq. 6): image loss through advection of the visual
  particles by V_t(.|u_t, p_t), plus lambda_sim L_sim and L_incomp (density at p_t, at the differentiable look-ahead
  Sim(u_t, p_t), and the visual spacing term).
- :func:`fit_appearance`: stage 2, colour, opacity, scale and rotation with positions fixed (Eq. 7).

Each takes the observed frame of every view and a seeded generator that picks the view of each iteration, so a
frame's result depends only on its inputs and the seed (this is what makes --resume bit-identical).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from .. import engine
from ..camera import Camera
from ..metrics import image_loss
from .config import ReconConfig
from .losses import anisotropy_loss, density_loss, simulation_loss, spacing_loss, temporal_loss
from .smoke import Smoke
from .timing import Stopwatch
from .workspace import Workspace

_IDLE = Stopwatch()


@dataclass(frozen=True)
class Views:
    """The cameras and the observed images of one frame: images [V, H, W, C] (engine dtype), and what each view
    sees behind the smoke as ``engine.render`` keyword arguments (``background``, ``static``; empty: black)."""

    cameras: tuple[Camera, ...]
    images: torch.Tensor
    behind: tuple[dict, ...] = ()

    def render_args(self, v: int) -> dict:
        return self.behind[v] if self.behind else {}

    def pick(self, generator: torch.Generator, count: int) -> list[int]:
        if count >= len(self.cameras):
            return list(range(len(self.cameras)))
        return torch.randperm(len(self.cameras), generator=generator)[:count].tolist()


def _render_loss(views: Views, picked: list[int], cfg: ReconConfig, watch: Stopwatch, x, color, scale, rotation,
                 opacity):
    total = 0.0
    for v in picked:
        with watch.measure("render"):
            image, _, _ = engine.render(views.cameras[v], x, scale, rotation, opacity, color, **views.render_args(v))
        total = total + image_loss(image, views.images[v], cfg.w_l1, cfg.w_dssim)
    return total / len(picked)


def _step(loss: torch.Tensor, opt, cfg: ReconConfig, what: str, watch: Stopwatch) -> float:
    """Check the loss for divergence, back-propagate, and take one optimiser step."""
    value = float(loss.detach())
    if not (value == value) or value > cfg.max_loss:
        raise FloatingPointError(f"{what} loss diverged ({value}); try a smaller learning rate")
    opt.zero_grad()
    with watch.measure("backward"):
        loss.backward()
    opt.step()
    return value


LOOK_ITERS = 100
LOOK_LR = 0.1


def fit_look(x: torch.Tensor, views: Views, cfg: ReconConfig, generator: torch.Generator, progress=None,
             watch: Stopwatch = _IDLE) -> tuple[float, float]:
    """The initial look: (colour, opacity) shared by Gaussians of size ``cfg.scale0`` at ``x`` [M, 3] (the first
    frame's visual hull) that best reproduces the frame, from ``cfg.color0`` / ``cfg.opacity0`` (Adam on the two
    logits, ``LOOK_ITERS`` steps of ``LOOK_LR``)."""
    m, dtype = x.shape[0], x.dtype
    raw = torch.tensor([cfg.color0, cfg.opacity0], dtype=dtype)
    raw = (torch.log(raw) - torch.log1p(-raw)).requires_grad_(True)
    opt = torch.optim.Adam([raw], lr=LOOK_LR)
    scale = torch.full((m, 3), cfg.scale0, dtype=dtype)
    rotation = torch.zeros((m, 4), dtype=dtype)
    rotation[:, 0] = 1.0
    channels = views.images.shape[-1]
    for _ in range(LOOK_ITERS if m else 0):
        look = torch.sigmoid(raw)
        loss = _render_loss(views, views.pick(generator, cfg.views_per_iter), cfg, watch, x,
                            look[0].expand(m, channels), scale, rotation, look[1].expand(m))
        value = _step(loss, opt, cfg, "initial look", watch)
        if progress is not None:
            progress.status(look=value)
    color, opacity = (float(v) for v in torch.sigmoid(raw.detach()))
    return color, opacity


def fit_positions(smoke: Smoke, views: Views, cfg: ReconConfig, generator: torch.Generator, progress=None,
                  watch: Stopwatch = _IDLE) -> float:
    """Frame-0 fit of the visual positions to the images (appearance held at its initial constants)."""
    x = smoke.x.clone().requires_grad_(True)
    opt = torch.optim.Adam([x], lr=cfg.lr_position)
    value = 0.0
    for _ in range(cfg.init_iters):
        loss = _render_loss(views, views.pick(generator, cfg.views_per_iter), cfg, watch, x, smoke.color,
                            smoke.scale, smoke.rotation, smoke.opacity)
        value = _step(loss, opt, cfg, "initial position", watch)
        if progress is not None:
            progress.status(loss=value)
    smoke.x = x.detach()
    return value


@dataclass(frozen=True)
class DynamicsResult:
    p: torch.Tensor
    u: torch.Tensor
    age: torch.Tensor
    x: torch.Tensor
    losses: dict


def fit_dynamics(prev: Smoke, ws: Workspace, views: Views, cfg: ReconConfig, generator: torch.Generator,
                 keep=None, progress=None, watch: Stopwatch = _IDLE) -> DynamicsResult:
    """Stage 1 at one frame: optimise p_t from p_sim = Sim(u_{t-1}, p_{t-1}); return p_t, u_t, their ages and
    x_t. ``keep`` (p [N, 3] -> [N] bool) selects the physical particles the frame keeps; x_t is advected by those
    alone, so that the saved velocity field is exactly the one that moved the visual particles (the
    re-simulation of ``eval`` replays it)."""
    dt, rho0 = ws.dt, ws.solver.rest_density
    p_prev, x_prev = prev.p.detach(), prev.x.detach()
    with watch.measure("simulation"):
        p_sim, _ = ws.simulate(p_prev, prev.u, prev.age)
    pairs = ws.visual_pairs(x_prev, cfg.visual_sigma) if cfg.lambda_visual_incomp else None
    p = p_sim.clone().requires_grad_(True)
    opt = torch.optim.Adam([p], lr=cfg.lr_position)
    age = prev.age + dt
    terms = {}
    for _ in range(cfg.dynamics_iters):
        u = (p - p_prev) / dt
        with watch.measure("advection"):
            x = engine.advect(x_prev, p, u, dt, ws.advect_query)
        terms = {"image": _render_loss(views, views.pick(generator, cfg.views_per_iter), cfg, watch, x, prev.color,
                                       prev.scale, prev.rotation, prev.opacity)}
        if cfg.lambda_sim:
            terms["sim"] = cfg.lambda_sim * simulation_loss(p, p_sim, cfg.loss_unit)
        if cfg.lambda_density:
            terms["density"] = cfg.lambda_density * density_loss(engine.density_at(p, p, ws.density_query), rho0)
        if cfg.lambda_next:
            with watch.measure("simulation"):
                p_next, _ = ws.simulate(p, u, age, differentiable=True)
            terms["next"] = cfg.lambda_next * density_loss(engine.density_at(p_next, p_next, ws.next_query), rho0)
        if pairs is not None:
            terms["spacing"] = cfg.lambda_visual_incomp * spacing_loss(x, pairs, cfg.visual_sigma, cfg.loss_unit)
        _step(sum(terms.values()), opt, cfg, "dynamics", watch)
        if progress is not None:
            progress.status(**{k: float(v.detach()) for k, v in terms.items()})
    with torch.no_grad():
        p = ws.push_out(p.detach())  # with an obstacle, nothing ends the frame inside it
        u = (p - p_prev) / dt
        if keep is not None:
            kept = keep(p)
            p, u, age = p[kept], u[kept], age[kept]
        x = ws.push_out(engine.advect(x_prev, p, u, dt, ws.advect_query))
    return DynamicsResult(p, u, age, x, {k: float(v.detach()) for k, v in terms.items()})


def _logit(v: torch.Tensor) -> torch.Tensor:
    v = v.clamp(1e-4, 1 - 1e-4)
    return torch.log(v) - torch.log1p(-v)


def fit_appearance(smoke: Smoke, views: Views, cfg: ReconConfig, generator: torch.Generator,
                   progress=None, watch: Stopwatch = _IDLE) -> dict:
    """Stage 2 at one frame: colour, opacity, scale, rotation with positions fixed, regularised towards the
    values the frame started from (those of t-1; the paper's Eq. 7 temporal terms) and the anisotropy cap."""
    c0, o0, s0, r0 = (t.detach() for t in (smoke.color, smoke.opacity, smoke.scale, smoke.rotation))
    raw = {"color": _logit(c0).requires_grad_(True), "opacity": _logit(o0).requires_grad_(True),
           "scale": torch.log(s0).requires_grad_(True), "rotation": r0.clone().requires_grad_(True)}
    lrs = {"color": cfg.lr_color, "opacity": cfg.lr_opacity, "scale": cfg.lr_scale, "rotation": cfg.lr_rotation}
    opt = torch.optim.Adam([{"params": [raw[k]], "lr": lrs[k]} for k in raw])
    terms = {}
    for _ in range(cfg.appearance_iters):
        color, opacity = torch.sigmoid(raw["color"]), torch.sigmoid(raw["opacity"])
        scale, rotation = torch.exp(raw["scale"]), raw["rotation"]
        quat = rotation / rotation.norm(dim=1, keepdim=True).clamp_min(1e-12)
        terms = {"image": _render_loss(views, views.pick(generator, cfg.views_per_iter), cfg, watch, smoke.x, color,
                                       scale, quat, opacity),
                 "regularisation": cfg.lambda_color * temporal_loss(color, c0)
                 + cfg.lambda_scale * temporal_loss(scale, s0) + cfg.lambda_opacity * temporal_loss(opacity, o0)
                 + cfg.lambda_rotation * temporal_loss(quat, r0),
                 "anisotropy": anisotropy_loss(scale, cfg.anisotropy_cap)}
        _step(sum(terms.values()), opt, cfg, "appearance", watch)
        if progress is not None:
            progress.status(**{k: float(v.detach()) for k, v in terms.items()})
    with torch.no_grad():
        smoke.color = torch.sigmoid(raw["color"]).detach()
        smoke.opacity = torch.sigmoid(raw["opacity"]).detach()
        smoke.scale = torch.exp(raw["scale"]).detach()
        r = raw["rotation"].detach()
        smoke.rotation = r / r.norm(dim=1, keepdim=True).clamp_min(1e-12)
    return {k: float(v.detach()) for k, v in terms.items()}
