"""Generative simulation (FluidNexus Sec. 3.3, Alg. S2, steps 2-4): render the physics rollout from every view
of the scene (with the constant initial appearance for a generative refiner, as the paper does; with the carried
appearance for a non-learned one), refine those rough videos with a video refiner, and re-fit
stages 1 and 2 of the reconstruction (``recon.fit``) frame by frame against the refined frames.

Only the rollout's own renders are used: the real future of the input camera is never read.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Iterator

import numpy as np
import torch

from ..camera import Camera
from ..frames import render_state
from ..progress import progress
from ..recon.fit import Views, fit_appearance, fit_dynamics
from ..recon.initial import emit, frame_generator
from ..recon.smoke import Smoke
from ..recon.workspace import Workspace
from ..scenery.backdrop import Behind
from ..scenery.obstacles import join
from .rollout import RunContext, constant_appearance, inflow_look


def rough_videos(states: list[Smoke], cameras: list[Camera], ctx: RunContext, constant: bool,
                 behind: list[Behind] | None = None) -> np.ndarray:
    """[V, T, H, W, C] float32: each rollout frame seen by each camera, with the constant initial appearance
    (``constant``, for a generative refiner) or with the appearance the rollout carries, composited with what
    each camera sees behind the smoke (``behind`` [V], ``scenery.backdrop``; black without it)."""
    def look(s: Smoke) -> Smoke:
        return constant_appearance(s, ctx.config) if constant else s

    behind = behind or [None] * len(cameras)
    return np.stack([np.stack([render_state(look(s).to_state(), cam, b) for s in states])
                     for cam, b in zip(cameras, behind)])


def refine_videos(rough: np.ndarray, refiner) -> np.ndarray:
    """The refiner applied to each view's video: [V, T, H, W, C] -> same shape."""
    return np.stack([np.asarray(refiner.refine(video), dtype=np.float32) for video in rough])


def refit(start: Smoke, videos: np.ndarray, cameras: list[Camera], ws: Workspace, ctx: RunContext,
          obstacle=None, behind: list[Behind] | None = None) -> Iterator[Smoke]:
    """Yield the re-fitted frames start.frame + 1 ... against ``videos`` [V, T, H, W, C] (one per camera, each
    composited with its entry of ``behind``, as ``rough_videos``).

    Stage 1 starts every frame from Sim(u_{t-1}, p_{t-1}) of the re-fitted previous frame (with the workspace's
    wind, and the scene's obstacles plus ``obstacle``); with an obstacle the look-ahead term is off (a step with an
    obstacle has no gradient) and the fitted particles are pushed out of the bodies (``fit_dynamics``).
    """
    obstacle = join(ctx.obstacle, obstacle)
    cfg = ctx.config if obstacle is None else replace(ctx.config, lambda_next=0.0)
    ws.set_obstacle(obstacle)
    prev, look = start, inflow_look(start, ctx)
    frames = videos.shape[1]
    args = tuple({} if b is None else b.render_args(ws.dtype) for b in (behind or [None] * len(cameras)))
    with progress("re-fit", frames) as bar:
        for k in range(frames):
            t = prev.frame + 1
            views = Views(tuple(cameras), torch.as_tensor(videos[:, k], dtype=ws.dtype), args)
            prev = replace(prev)  # emit appends to its argument; the caller's start stays as it is
            emit(prev, ctx.source, cfg, t, look, obstacle=ws.obstacle)
            dyn = fit_dynamics(prev, ws, views, cfg, frame_generator(cfg.seed, t), lambda p: ~ws.isolated(p), bar)
            smoke = Smoke(t, dyn.p, dyn.u, dyn.age, dyn.x, prev.color, prev.scale, prev.rotation, prev.opacity)
            fit_appearance(smoke, views, cfg, frame_generator(cfg.seed, t), bar)
            bar.advance()
            prev = smoke
            yield smoke
