"""Choose the future's buoyancy and drag by backtesting the model on the run's own past (docs/prediction.md).

A reconstructed frame's velocities are the optimiser's, fitted to images frame by frame; the constant model then
has to carry them on alone. With the paper's ScalarFlow constants the plume rises 2-3x faster than the real one
within a second (BENCHMARKS.md). Calibration asks which model would have forecast the recent past best: it rolls
each candidate out from frame ``first - window`` over the ``window`` frames up to ``first``, renders them through
the scene's input cameras (real footage only) and scores them against the real frames (PSNR). The search is by
coordinates: the drag k over ``DRAG_GRID`` at the model's alpha, then alpha scaled by ``ALPHA_SCALES`` at the best
k. The best candidate, the model itself included, is the future's model. No frame after ``first`` is read.

The gas in ambient air (model structure ``ambient_air``) is searched over alpha alone: its smoke passes momentum to
the air through the solver and XSPH viscosity, and the Eq. S4 drag is inert among air at rest density, so the
model has no drag to calibrate (diagnose fits none); each backtest surrounds the reconstructed smoke at
``first - window`` with air at rest, as the future does at ``first``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from ..engine import ModelConfig
from ..engine.tensors import torch_dtype
from ..frames import render_state
from ..metrics import psnr
from ..progress import progress
from ..recon.smoke import Smoke
from ..runs import Run
from ..scenery.backdrop import run_backdrop
from ..video import read_video
from .rollout import RunContext, rollout, workspace_for

log = logging.getLogger("fluidnexus")

DEFAULT_WINDOW = 30  # frames; one second of ScalarFlow
MIN_WINDOW = 5
DRAG_GRID = (3.0, 10.0, 20.0, 40.0, 60.0)  # 1/s; explicit drag is stable for k dt <= 2, i.e. k <= 60 at 30 fps
ALPHA_SCALES = (0.0, 0.5, 1.0, 2.0)


@dataclass(frozen=True)
class Calibration:
    """The chosen model and every candidate's backtest score."""

    model: ModelConfig
    window: tuple[int, int]  # the frames forecast in the backtest (start excluded, end included)
    views: tuple[str, ...]
    candidates: tuple[dict, ...]  # {"alpha", "k", "psnr"}; k None without a drag term (ambient air)

    def to_dict(self) -> dict:
        chosen = max(self.candidates, key=lambda c: c["psnr"])
        return {"window": list(self.window), "views": list(self.views), "metric": "psnr",
                "chosen": chosen, "candidates": list(self.candidates)}


def with_buoyancy_drag(model: ModelConfig, alpha: float, k: float | None) -> ModelConfig:
    """``model`` with the buoyancy alpha and the drag k replaced (every other term and parameter kept; k None:
    the drag as it is)."""
    terms = []
    for t in model.terms:
        if t.kind == "buoyancy":
            t = replace(t, alpha=float(alpha))
        elif t.kind == "drag" and k is not None:
            t = replace(t, k=float(k))
        terms.append(t)
    return replace(model, terms=tuple(terms))


def calibrate(run: Run, ctx: RunContext, first: int, window: int = DEFAULT_WINDOW) -> Calibration | None:
    """Backtest calibration of ``ctx.model`` (which must have a buoyancy term, and a drag term in the paper's gas)
    before frame ``first``.

    Returns None (and logs why) when the run has fewer than ``MIN_WINDOW`` frames before ``first``, the scene
    has no input view with footage, or the model lacks a buoyancy term (or, in the paper's gas, a drag term).
    """
    kinds = {t.kind for t in ctx.model.terms}
    if "buoyancy" not in kinds or (ctx.model.air is None and "drag" not in kinds):
        log.info("calibration skipped: the model has no buoyancy or (in the paper's gas) no drag term")
        return None
    window = min(window, first - run.frames[0])
    if window < MIN_WINDOW:
        log.info("calibration skipped: %d reconstructed frames before frame %d (needs %d)", window, first, MIN_WINDOW)
        return None
    scene = run.scene(check_videos=False)
    views = [v for v in scene.with_role("input") if v.video is not None]
    if not views:
        log.info("calibration skipped: the scene has no input view with footage")
        return None
    begin = first - window
    cameras = [v.camera.scaled(run.resolution) for v in views]
    truth = [read_video(scene.root / v.video, frames=slice(begin + 1, first + 1), size=(c.width, c.height),
                        channels=run.channels) for v, c in zip(views, cameras)]
    start = Smoke.from_state(run.state(begin), torch_dtype())
    backdrop = run_backdrop(run)
    model, candidates = search(start, cameras, truth, ctx, [backdrop.behind(c, v.name) for v, c in zip(views, cameras)])
    return Calibration(model, (begin + 1, first), tuple(v.name for v in views), candidates)


def search(start: Smoke, cameras: list, truth: list[np.ndarray], ctx: RunContext,
           behind: list | None = None) -> tuple[ModelConfig, tuple]:
    """The coordinate search: (best model, candidates {"alpha", "k", "psnr"}); in ambient air over alpha alone
    (k None).

    Args:
        start: the state the backtest starts from.
        cameras: [V] cameras; truth: [V] arrays [T, H, W, C] of the T frames after ``start`` seen by them.
        behind: [V] what each camera sees behind the smoke (``scenery.backdrop``; black without it).
    """
    behind = behind or [None] * len(cameras)
    window = truth[0].shape[0]
    ws = workspace_for(start, window, ctx, ctx.model)

    def score(alpha: float, k: float | None) -> float:
        model = with_buoyancy_drag(ctx.model, alpha, k)
        ws.set_model(model)
        values = [psnr(render_state(s.to_state(), cam, b), video[i])
                  for i, s in enumerate(rollout(start, window, ws, replace(ctx, model=model)))
                  for cam, video, b in zip(cameras, truth, behind)]
        return float(np.mean(values))

    alpha0 = ctx.model.term("buoyancy").alpha
    if ctx.model.air is None:
        k0 = ctx.model.term("drag").k
        drags = sorted(set(DRAG_GRID) | {k0})
    else:
        k0, drags = None, [None]
    alphas = [alpha0 * s for s in ALPHA_SCALES if s != 1.0]
    results: dict[tuple[float, float], float] = {}
    with progress("calibrate", len(drags) + len(alphas)) as bar:
        for k in drags:
            results[(alpha0, k)] = score(alpha0, k)
            bar.advance()
        best_k = max(drags, key=lambda k: results[(alpha0, k)])
        for alpha in alphas:
            results[(alpha, best_k)] = score(alpha, best_k)
            bar.advance()
    (alpha, k), best = max(results.items(), key=lambda item: item[1])
    log.info("calibration: alpha %.4g, k %s (%.2f dB; the model as given %.2f dB)", alpha,
             "none" if k is None else f"{k:.3g}", best, results[(alpha0, k0)])
    candidates = tuple({"alpha": a, "k": kk, "psnr": v} for (a, kk), v in results.items())
    return with_buoyancy_drag(ctx.model, alpha, k), candidates
