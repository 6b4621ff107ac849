"""``predict`` and ``interact`` end to end: from a run's state to a new run folder (docs/prediction.md).

The new folder is a run like any other (docs/run-format.md): ``run.json`` (kind ``predict`` or ``interact``, the
parent run, the start frame, the smoke source, the interaction), ``config.json`` (the model includes the wind
term; ``fit_model`` is the re-fit's), ``frames/`` (the future frames only), ``summary.json``, and ``videos/`` (the
rough and refined renders that the re-fit used; ``interact`` adds its side-by-side comparisons).
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import memory
from ..atomic import write_json
from ..camera import Camera
from ..engine.tensors import torch_dtype
from ..errors import InputError, RunError
from ..frames import side_by_side
from ..progress import track
from ..recon.smoke import Smoke
from ..runs import RUN_FORMAT, Run
from ..scenery.backdrop import run_backdrop
from ..state import frame_path, save_frame
from ..video import write_video
from .anchor import anchor_videos, known_frames
from .generative import refine_videos, refit, rough_videos
from .memory import future_estimate
from .rollout import RunContext, refit_model, rollout, workspace_for
from .shading import ObstacleLayer, render_with_obstacle

log = logging.getLogger("fluidnexus")


@dataclass(frozen=True)
class Interaction:
    """What changes in the future: a model with wind (or the run's), an engine obstacle, their description."""

    model: object = None
    obstacle: object = None
    info: dict = field(default_factory=dict)


def start_frame(run: Run, frame: int | None) -> int:
    """The frame the future starts after: ``frame`` (must be saved in the run) or the run's last frame."""
    if frame is None:
        return run.frames[-1]
    if frame not in run.frames:
        raise InputError(run.root, "--from",
                         f"frame {frame} is not in the run (frames {run.frames[0]}..{run.frames[-1]})")
    return frame


def check_new_run(out: Path) -> None:
    """The new run folder must not exist or be empty."""
    if out.exists() and any(out.iterdir()):
        raise InputError(out, None, "already exists and is not empty (choose another --out)")


def prepare(out: Path, run: Run, kind: str, first: int, frames: int, ctx: RunContext, model, info: dict) -> None:
    check_new_run(out)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    write_json(out / "run.json", {"format": RUN_FORMAT, "kind": kind, "scene": run.info["scene"],
                                  "frames": [first + 1, first + 1 + frames], "parent": str(run.root.resolve()),
                                  "start_frame": first, "source": ctx.source.to_dict(), **info})
    write_json(out / "config.json", {"recon": ctx.config.to_dict(), "solver": ctx.solver.to_dict(),
                                     "model": model.to_dict(), "fit_model": refit_model(model, ctx).to_dict()})


def _save(out: Path, smoke: Smoke) -> None:
    try:
        save_frame(frame_path(out, smoke.frame), smoke.to_state())
    except OSError as err:
        raise RunError(f"could not write {frame_path(out, smoke.frame)} ({err.strerror or err})") from None


def scene_cameras(run: Run) -> list[tuple[str, Camera]]:
    """(name, camera at the run's resolution) of every view of the run's scene."""
    scene = run.scene(check_videos=False)
    return [(v.name, v.camera.scaled(run.resolution)) for v in scene.views]


def simulate_future(run: Run, out: Path, kind: str, frames: int, interaction: Interaction, refiner=None,
                    first: int | None = None, ctx: RunContext | None = None,
                    notes: dict | None = None, anchor: bool = True,
                    max_memory: int | None = None) -> tuple[list[Smoke], list[Smoke]]:
    """Write the future of ``run`` into the run folder ``out``; return (physics rollout, saved frames).

    Args:
        run: the reconstruction (or an earlier prediction) to continue.
        out: the new run folder (must not exist or be empty).
        kind: "predict" or "interact" (recorded in run.json).
        frames: number of future frames N > 0.
        interaction: wind model / obstacle (empty for a plain prediction).
        refiner: a ``fluidnexus.gen`` video refiner, or None for the physics rollout only (--no-refit).
        first: the frame to start after (default the run's last).
        ctx: the run's settings with the future's base model (default ``RunContext.of(run)``).
        notes: more entries for run.json (e.g. the model calibration).
        anchor: carry each view's known look at the start frame along the rollout before refining
            (``anchor.anchor_videos``).
        max_memory: refuse (InputError) before writing anything when the estimated memory is above this many
            bytes (``fluidnexus.memory``; None: the default limit).
    """
    if frames <= 0:
        raise InputError(None, "--frames", f"must be > 0, got {frames}")
    first = start_frame(run, first)
    ctx = ctx or RunContext.of(run)
    model = interaction.model or ctx.model
    info = {"interaction": interaction.info, "refine": None if refiner is None else refiner.provenance(),
            "anchor": refiner is not None and anchor, **(notes or {})}
    start = Smoke.from_state(run.state(first), torch_dtype())
    limit = memory.parse_limit(None) if max_memory is None else max_memory
    cameras = [cam for _, cam in scene_cameras(run)]
    memory.check(future_estimate(kind, start, frames, ctx, model, cameras, refiner is not None), limit)
    prepare(out, run, kind, first, frames, ctx, model, info)
    tic = time.perf_counter()
    ws = workspace_for(start, frames, ctx, model)
    physics = list(track(rollout(start, frames, ws, ctx, interaction.obstacle), "simulate", frames))
    saved = physics
    if refiner is not None:
        names, cameras = zip(*scene_cameras(run))
        backdrop = run_backdrop(run)
        behind = [backdrop.behind(cam, name) for name, cam in zip(names, cameras)]
        rough = rough_videos([start] + physics, cameras, ctx, constant=refiner.generative, behind=behind)
        if anchor:
            known = known_frames(run.scene(check_videos=False), first, list(names), run.resolution, run.channels)
            guide = anchor_videos(rough, physics, start, cameras, known)
        else:
            guide = rough[:, 1:]
        refined = refine_videos(guide, refiner)
        fps = 1.0 / ctx.solver.dt
        for name, r, f in zip(names, rough[:, 1:], refined):
            write_video(out / "videos" / f"rough_{name}.mp4", r, fps=fps)
            write_video(out / "videos" / f"refined_{name}.mp4", f, fps=fps)
        ws.set_model(refit_model(model, ctx))  # the gas in ambient air re-fits with the paper's gas
        saved = list(refit(start, refined, cameras, ws, ctx, interaction.obstacle, behind))
    for smoke in saved:
        _save(out, smoke)
    elapsed = time.perf_counter() - tic
    write_json(out / "summary.json", {"format": RUN_FORMAT, "frames": [first + 1, first + 1 + frames],
                                      "refit": refiner is not None, "elapsed_s": round(elapsed, 3),
                                      "particles": {"physical": int(saved[-1].p.shape[0]),
                                                    "visual": int(saved[-1].x.shape[0])}})
    log.info("%s: frames %d:%d into %s (%.1f s)", kind, first + 1, first + 1 + frames, out, elapsed)
    return physics, saved


def comparison_videos(run: Run, out: Path, without: list[Smoke], with_: list[Smoke], obstacle=None) -> list[Path]:
    """Side-by-side videos (without | with the interaction) from the input camera and one novel camera."""
    scene = run.scene(check_videos=False)
    picks = list(scene.with_role("input")[:1]) + list(scene.with_role("novel")[:1])
    if len(picks) < 2:  # a multi-view scene: its second camera plays the novel one
        picks = list(scene.views[:2])
    written = []
    fps = scene.fps
    for view in picks:
        cam = view.camera.scaled(run.resolution)
        layer = ObstacleLayer(obstacle, cam) if obstacle is not None else None
        video = [side_by_side(render_with_obstacle(a.to_state(), cam, None),
                              render_with_obstacle(b.to_state(), cam, layer)) for a, b in zip(without, with_)]
        path = out / "videos" / f"compare_{view.name}.mp4"
        write_video(path, np.stack(video), fps=fps)
        written.append(path)
    return written


def physics_baseline(run: Run, frames: int, first: int | None = None,
                     ctx: RunContext | None = None) -> list[Smoke]:
    """The physics rollout of the base model without any interaction (the "without" side)."""
    first = start_frame(run, first)
    ctx = ctx or RunContext.of(run)
    start = Smoke.from_state(run.state(first), torch_dtype())
    return list(rollout(start, frames, workspace_for(start, frames, ctx, ctx.model), ctx))
