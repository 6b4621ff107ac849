"""``fluidnexus predict`` and ``interact``'s work: the future of a run with its base model (a model file, then the
backtest calibration), and under a wind or around a rigid body (FluidNexus Sec. 3.3, 4.2, Alg. S2;
docs/prediction.md)."""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..model_file import load_model_file
from ..runs import Run
from ..scene_scale import WIND_HEIGHT
from ..scenery.obstacles import make_obstacle, parse_sphere
from .calibrate import calibrate as backtest
from .rollout import RunContext, parse_wind, with_wind
from .session import Interaction, check_new_run, comparison_videos, physics_baseline, simulate_future, start_frame

log = logging.getLogger("fluidnexus")


@dataclass(frozen=True)
class Future:
    """What predict and interact share: ``frames`` future frames after ``from_frame`` (None: the run's last), the
    base model (``model_file``, then a backtest over ``calibrate_window`` frames when ``calibrate``), and whether
    each view's last look is carried along the rollout before refining (``anchor``)."""

    frames: int
    from_frame: int | None = None
    model_file: Path | None = None
    calibrate: bool = True
    calibrate_window: int = 30
    anchor: bool = True

    def check(self, out: Path) -> None:
        """InputError before anything is read or written: no frames, or ``out`` not a new run folder."""
        if self.frames <= 0:
            raise InputError(None, "--frames", f"must be > 0, got {self.frames}")
        check_new_run(out)


@dataclass(frozen=True)
class InteractionRequest:
    """``interact``'s interactions: a wind acceleration (m/s^2) with its profile and height, and/or one body."""

    wind: tuple[float, float, float] | None
    profile: str
    wind_height: float | None
    ball: str | None
    mesh_file: Path | None

    @classmethod
    def parse(cls, wind: str | None, profile: str, wind_height: float | None, ball: str | None,
              mesh_file: Path | None) -> "InteractionRequest":
        """Checked ``--wind``, ``--profile``, ``--wind-height``, ``--ball``, ``--mesh``; InputError naming the
        option otherwise."""
        if wind is None and ball is None and mesh_file is None:
            raise InputError(None, "--wind/--ball/--mesh", "give at least one interaction")
        if ball is not None and mesh_file is not None:
            raise InputError(None, "--ball/--mesh", "give one obstacle, not both")
        accel = parse_wind(wind) if wind is not None else None
        if ball is not None:
            parse_sphere(ball, "--ball", "CX,CY,CZ,R in metres")
        if wind_height is not None and not wind_height > 0:
            raise InputError(None, "--wind-height", f"must be > 0, got {wind_height}")
        return cls(accel, profile, wind_height, ball, mesh_file)


def future_refiner(method: str, no_refit: bool, weights, lora, strength: float, steps: int, seed: int,
                   offload: bool, device: str):
    """The refiner of the rough future videos (``--refine`` and the CogVideoX options), or None with
    ``no_refit``."""
    if no_refit:
        return None
    from ..gen.refiner import make_refiner

    if method == "cogvideox":
        from ..gen.cogvideox import DEFAULT_PROMPT, CogVideoXConfig

        if not 0 < strength <= 1:
            raise InputError(None, "--strength", f"must be in (0, 1], got {strength}")
        config = CogVideoXConfig(strength=strength, steps=steps, prompt=DEFAULT_PROMPT, prompt_embeds=None, seed=seed,
                                 device=None if device == "auto" else device, offload=offload)
        return make_refiner(method, weights=weights, lora=lora, config=config)
    return make_refiner(method)


def future_context(run: Run, future: Future) -> tuple[RunContext, dict]:
    """(RunContext with the future's base model, run.json notes): the model file, then the backtest calibration.
    Needs the engine started."""
    ctx = RunContext.of(run)
    loaded = load_model_file(future.model_file, rollout=True)
    notes = {"model_file": None if future.model_file is None else str(Path(future.model_file).resolve()),
             "calibration": None}
    if loaded is not None:
        ctx = dataclasses.replace(ctx, model=loaded.model)
        if loaded.window is not None and ctx.source.window is None:  # a window the scene declares wins
            ctx = dataclasses.replace(ctx, source=dataclasses.replace(ctx.source, window=loaded.window))
            log.info("the source emits in frames [%d, %s) only (the model file's window)", loaded.window[0],
                     "end" if loaded.window[1] is None else loaded.window[1])
    if future.calibrate:
        result = backtest(run, ctx, start_frame(run, future.from_frame), future.calibrate_window)
        if result is not None:
            ctx = dataclasses.replace(ctx, model=result.model)
            notes["calibration"] = result.to_dict()
    return ctx, notes


def predict_run(run: Run, out: Path, future: Future, refiner, limit: int) -> None:
    """Write the future of ``run`` into the new run folder ``out`` (simulate, render, anchor, refine, re-fit).
    Needs the engine started."""
    ctx, notes = future_context(run, future)
    simulate_future(run, out, "predict", future.frames, Interaction(), refiner, future.from_frame, ctx, notes,
                    future.anchor, limit)


def interact_run(run: Run, out: Path, future: Future, request: InteractionRequest, refiner, limit: int) -> list[Path]:
    """Write the future of ``run`` under ``request`` into ``out``, and the comparison videos without | with the
    interaction; returns their paths. Needs the engine started."""
    ctx, notes = future_context(run, future)
    info, model = {}, None
    if request.wind is not None:
        scene = run.scene(check_videos=False)
        height = request.wind_height or (float(scene.volume.max[1] - scene.volume.min[1])
                                         if scene.volume is not None else WIND_HEIGHT * run.length_scale)
        model = with_wind(ctx.model, request.wind, request.profile, ctx.source.center[1], height)
        info["wind"] = {"accel": list(request.wind), "profile": request.profile, "height": height}
    obstacle = None
    if request.ball is not None or request.mesh_file is not None:
        obstacle, info["obstacle"] = make_obstacle(request.ball, request.mesh_file)
    _, with_ = simulate_future(run, out, "interact", future.frames, Interaction(model, obstacle, info), refiner,
                               future.from_frame, ctx, notes, future.anchor, limit)
    without = physics_baseline(run, future.frames, future.from_frame, ctx)
    return comparison_videos(run, out, without, with_, obstacle)
