"""``fluidnexus eval``: score a run against the scene's ground-truth videos (docs/evaluation.md).

- novel_view: every ground-truth camera renders every frame of the run (a moving camera from its pose at that
  frame); PSNR and SSIM per frame against the real frame at the run's resolution (LPIPS too with local AlexNet
  weights), averaged per view, then over views.
- resimulation: the visual particles of the first frame are advected through the run's reconstructed velocity
  fields only (x_t = x_{t-1} + dt V_t(x_{t-1}), new particles entering where the run's emitter put them), rendered
  with each frame's appearance and scored the same way (FluidNexus Sec. 4).
- divergence: mean |div V| over a dense grid in the scene volume and over time (definition in docs/evaluation.md),
  plus the same mean restricted to grid nodes inside the smoke (a visual particle within h).
- prediction (runs made by ``predict`` / ``interact``): the predicted frames against the real future of the
  scene's input cameras (``input_view``) and of the ground-truth cameras (``novel_views``), with the
  repeat-last-frame reference on the input cameras (the last observed real frame held still,
  ``repeat_last_input_view``); frames past the end of the videos are not scored.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from fluidnexus.scenery.backdrop import Backdrop, run_backdrop

from . import engine
from .engine.tensors import torch_dtype
from .errors import InputError
from .frames import render_state
from .metrics import psnr, ssim
from .progress import progress
from .runs import Run
from .scene import load_ground_truth
from .state import FrameState
from .video import read_video

DIVERGENCE_GRID = 32  # nodes along the longest side of the volume


@dataclass(frozen=True)
class Scores:
    psnr: float
    ssim: float
    lpips: float | None

    def to_dict(self) -> dict:
        return {"psnr": self.psnr, "ssim": self.ssim, "lpips": self.lpips}


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


# The footage is 8-bit: an error under its quantization (uniform noise of one step, variance step^2 / 12) is not
# measured, so a frame's PSNR stops there (58.9 dB) and a frame the render matches exactly (a plain backdrop
# before any smoke) does not make the mean infinite.
PSNR_CAP_DB = 10.0 * math.log10(12 * 255.0 ** 2)


def _score(rendered: list[np.ndarray], truth: np.ndarray, lpips_weights) -> Scores:
    p = [min(float(psnr(r, g)), PSNR_CAP_DB) for r, g in zip(rendered, truth)]
    s = [float(ssim(r, g)) for r, g in zip(rendered, truth)]
    lp = None
    if lpips_weights is not None:
        from .lpips import lpips

        lp = _mean(float(lpips(lpips_weights, torch.from_numpy(r), torch.from_numpy(g)))
                   for r, g in zip(rendered, truth))
    return Scores(float(np.mean(p)), float(np.mean(s)), lp)


def resimulate(run: Run, frames: list[int]) -> list[FrameState]:
    """States whose visual positions come only from advecting the first frame through the saved velocities (and,
    as in the reconstruction, moved out of the scene's obstacles)."""
    from fluidnexus.scenery.world import run_scenery

    from .engine.obstacle import PointProjector

    first = run.state(frames[0])
    out = [first]
    x = torch.as_tensor(first.visual_positions, dtype=torch_dtype())
    query = None
    obstacle = run_scenery(run).obstacle
    projector = PointProjector(max(1, first.num_visual)) if obstacle is not None else None
    for t in frames[1:]:
        state = run.state(t)
        p = torch.as_tensor(state.physical_positions, dtype=x.dtype)
        u = torch.as_tensor(state.physical_velocities, dtype=x.dtype)
        if query is None or query.source_capacity < len(p) or query.query_capacity < state.num_visual:
            query = engine.FieldQuery(2 * max(len(p), 1), 2 * state.num_visual, run.config["solver"]["h"])
        with torch.no_grad():
            x = engine.advect(x, p, u, run.dt, query)
            if obstacle is not None:  # as the reconstruction moved them: out of the scene's obstacles
                x = projector(obstacle, x)
        born = torch.as_tensor(state.visual_positions[len(x):], dtype=x.dtype)  # emitted at this frame
        x = torch.cat([x, born])[: state.num_visual]
        out.append(FrameState(t, state.physical_positions, state.physical_velocities, x.numpy().astype(np.float32),
                              state.visual_colors, state.visual_scales, state.visual_rotations,
                              state.visual_opacities, state.physical_ages))
    return out


def divergence(run: Run, frames: list[int], grid: int = DIVERGENCE_GRID) -> dict:
    """Mean |div V| over the volume grid and over time, and the same inside the smoke."""
    scene = run.scene(check_videos=False)
    if scene.volume is None:
        raise InputError(scene.root / "scene.json", "volume", "divergence needs the scene's volume bounds")
    lo, hi = np.asarray(scene.volume.min), np.asarray(scene.volume.max)
    res = np.maximum(3, np.round(grid * (hi - lo) / (hi - lo).max()).astype(int))
    h = run.config["solver"]["h"]
    all_nodes, in_smoke = [], []
    states = [run.state(t) for t in frames]
    nodes = int(np.prod(res))  # one pair of queries for all frames: Taichi field allocation is slow
    query = engine.FieldQuery(max(1, max(s.num_physical for s in states)), nodes, h)
    vis = engine.FieldQuery(max(1, max(s.num_visual for s in states)), nodes, h)
    for state in states:
        div, _ = engine.divergence_on_grid(query, state.physical_positions, state.physical_velocities, lo, hi, res)
        _, near_smoke = engine.divergence_on_grid(vis, state.visual_positions, np.zeros_like(state.visual_positions),
                                                  lo, hi, res)
        all_nodes.append(np.abs(div).mean())
        if (near_smoke > 0).any():
            in_smoke.append(np.abs(div[near_smoke > 0]).mean())
    return {"mean_abs": float(np.mean(all_nodes)), "mean_abs_in_smoke": _mean(in_smoke),
            "grid": [int(r) for r in res], "unit": "1/s"}


def _summary(scores: dict) -> dict:
    """Mean PSNR / SSIM / LPIPS over views, with each view's scores under ``per_view``."""
    return {**{k: _mean(getattr(s, k) for s in scores.values()) for k in ("psnr", "ssim", "lpips")},
            "per_view": {k: v.to_dict() for k, v in scores.items()}}


PREDICTION_KINDS = ("predict", "interact")


def prediction(run: Run, lpips_weights=None, backdrop: Backdrop | None = None) -> dict:
    """Scores of a prediction run's frames on the input cameras' real future and on the ground-truth cameras."""
    scene = run.scene(check_videos=False)
    start = int(run.info["start_frame"])
    frames = [t for t in run.frames if t < scene.frame_count]
    if not frames:
        raise InputError(run.root / "run.json", "frames", f"no predicted frame lies inside the videos "
                                                          f"({scene.frame_count} frames)")
    inputs = [v for v in scene.with_role("input") if v.video is not None]
    states = [run.state(t) for t in frames]
    backdrop = backdrop or run_backdrop(run)

    def real(video, cam, rows):
        clip = read_video(scene.root / video, frames=slice(min(rows), max(rows) + 1), size=(cam.width, cam.height),
                          channels=run.channels)
        return clip[[t - min(rows) for t in rows]]

    input_scores, repeat_scores = {}, {}
    for view in inputs:
        cam = view.camera.scaled(run.resolution)
        truth = real(view.video, cam, frames)
        behind = backdrop.behind(cam, view.name)
        input_scores[view.name] = _score([render_state(s, cam, behind) for s in states], truth, lpips_weights)
        last = real(view.video, cam, [start])[0]
        repeat_scores[view.name] = _score([last] * len(frames), truth, lpips_weights)
    novel = {}
    for gt in load_ground_truth(scene.root):
        cam = gt.camera.scaled(run.resolution)
        behind = backdrop.behind(cam)
        rendered = [render_state(s, gt.camera_at(t).scaled(run.resolution), behind) for s, t in zip(states, frames)]
        novel[gt.name] = _score(rendered, real(gt.video, cam, frames), lpips_weights)
    return {"frames": [frames[0], frames[-1] + 1], "start_frame": start, "input_view": _summary(input_scores),
            "repeat_last_input_view": _summary(repeat_scores), "novel_views": _summary(novel)}


def evaluate(run: Run, lpips_weights=None, backdrop: Backdrop | None = None) -> dict:
    """Score a run: the JSON document of ``fluidnexus eval`` (keys in docs/evaluation.md). The renders composite
    the smoke over ``backdrop`` (default the run's own: ``scenery.backdrop``)."""
    scene = run.scene(check_videos=False)
    truths = load_ground_truth(scene.root)
    if not truths:
        raise InputError(scene.root / "scene.json", "ground_truth", "the scene has no ground-truth view to score")
    frames = run.frames
    resim = resimulate(run, frames)
    backdrop = backdrop or run_backdrop(run)
    per_view, resim_scores = {}, {}
    with progress("evaluate", len(truths)) as bar:
        for gt in truths:
            cam = gt.camera.scaled(run.resolution)
            video = read_video(scene.root / gt.video, frames=slice(frames[0], frames[-1] + 1),
                               size=(cam.width, cam.height), channels=run.channels)
            truth = video[[t - frames[0] for t in frames]]
            cams = [gt.camera_at(t).scaled(run.resolution) for t in frames]  # a moving camera: one per frame
            behind = backdrop.behind(cams[0])  # a held-out camera: the static layer, the backdrop colour or black
            per_view[gt.name] = _score([render_state(run.state(t), c, behind) for t, c in zip(frames, cams)], truth,
                                       lpips_weights)
            resim_scores[gt.name] = _score([render_state(s, c, behind) for s, c in zip(resim, cams)], truth,
                                           lpips_weights)
            bar.advance()
    result = {"novel_view": _summary(per_view), "resimulation": _summary(resim_scores),
              "divergence": divergence(run, frames),
              "frames": [frames[0], frames[-1] + 1],
              "resolution": {"scale": run.resolution, "width": cam.width, "height": cam.height}}
    if run.info.get("kind") in PREDICTION_KINDS:
        result["prediction"] = prediction(run, lpips_weights, backdrop)
    return result
