"""``fluidnexus predict``: what the smoke does next (FluidNexus Sec. 3.3, Alg. S2; docs/prediction.md)."""
from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import click

from fluidnexus.errors import InputError

from .options import arch_option, load_model_file, max_memory_option, start_engine

log = logging.getLogger("fluidnexus")


def refine_options(func):
    """--refine, --no-refit and the CogVideoX options shared by ``predict`` and ``interact``."""
    options = [
        click.option("--refine", "method", type=click.Choice(["temporal", "cogvideox"]), default="temporal",
                     show_default=True, help="Refiner of the rough future videos."),
        click.option("--no-refit", is_flag=True, help="Stop after the physics rollout (no render/refine/re-fit)."),
        click.option("--anchor/--no-anchor", default=True, show_default=True,
                     help="Carry each view's look at the start frame along the rollout before refining."),
        click.option("--weights", type=click.Path(path_type=Path), help="cogvideox: local diffusers folder."),
        click.option("--lora", type=click.Path(path_type=Path), help="cogvideox: local LoRA folder."),
        click.option("--strength", type=float, default=0.75, show_default=True,
                     help="cogvideox: SDEdit strength (the paper uses 0.75 for the future)."),
        click.option("--steps", type=int, default=50, show_default=True, help="cogvideox: denoising steps."),
        click.option("--seed", type=int, default=0, show_default=True, help="cogvideox: noise seed."),
        click.option("--offload", is_flag=True, help="cogvideox: CPU offload of sub-models."),
        click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
                     help="cogvideox: torch device."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def make_refiner(method, no_refit, weights, lora, strength, steps, seed, offload, device):
    """The refiner chosen on the command line, or None with --no-refit."""
    if no_refit:
        return None
    from fluidnexus.gen.refiner import make_refiner as build

    if method == "cogvideox":
        from fluidnexus.gen.cogvideox import DEFAULT_PROMPT, CogVideoXConfig

        if not 0 < strength <= 1:
            raise InputError(None, "--strength", f"must be in (0, 1], got {strength}")
        config = CogVideoXConfig(strength=strength, steps=steps, prompt=DEFAULT_PROMPT, prompt_embeds=None, seed=seed,
                                 device=None if device == "auto" else device, offload=offload)
        return build(method, weights=weights, lora=lora, config=config)
    return build(method)


def model_options(func):
    """--model and --calibrate, shared by ``predict`` and ``interact``: the future's base model."""
    options = [
        click.option("--model", "model_file", type=click.Path(path_type=Path, dir_okay=False),
                     help="A model.json (e.g. from `fluidnexus diagnose`) instead of the run's model."),
        click.option("--calibrate/--no-calibrate", default=True, show_default=True,
                     help="Choose buoyancy and drag by backtesting on the last reconstructed frames."),
        click.option("--calibrate-window", type=click.IntRange(min=1), default=30, show_default=True,
                     help="Frames of the backtest."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def future_context(run, first, model_file, calibrate: bool, window: int):
    """(RunContext with the future's base model, run.json notes): --model, then the backtest calibration."""
    from fluidnexus.predict.calibrate import calibrate as backtest
    from fluidnexus.predict.rollout import RunContext
    from fluidnexus.predict.session import start_frame

    ctx = RunContext.of(run)
    loaded = load_model_file(model_file, ambient_air=True)
    notes = {"model_file": None if model_file is None else str(Path(model_file).resolve()), "calibration": None}
    if loaded is not None:
        ctx = dataclasses.replace(ctx, model=loaded.model)
        if loaded.window is not None and ctx.source.window is None:  # a window the scene declares wins
            ctx = dataclasses.replace(ctx, source=dataclasses.replace(ctx.source, window=loaded.window))
            log.info("the source emits in frames [%d, %s) only (the model file's window)", loaded.window[0],
                     "end" if loaded.window[1] is None else loaded.window[1])
    if calibrate:
        result = backtest(run, ctx, start_frame(run, first), window)
        if result is not None:
            ctx = dataclasses.replace(ctx, model=result.model)
            notes["calibration"] = result.to_dict()
    return ctx, notes


def check_frames(frames: int) -> None:
    if frames <= 0:
        raise InputError(None, "--frames", f"must be > 0, got {frames}")


@click.command()
@click.argument("run_dir", metavar="RUN", type=click.Path(path_type=Path))
@click.option("--frames", type=int, required=True, help="Number of future frames N.")
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False), help="New run folder.")
@click.option("--from", "from_frame", type=int, default=None,
              help="Start after this reconstructed frame (default: the run's last frame).")
@model_options
@refine_options
@max_memory_option
@arch_option
def predict(run_dir: Path, frames: int, out: Path, from_frame, model_file, calibrate, calibrate_window, method,
            no_refit, anchor, weights, lora, strength, steps, seed, offload, device, max_memory, arch) -> None:
    """Simulate N frames after the last frame of RUN, render them from every view, refine and re-fit.

    \b
    fluidnexus predict runs/sf --frames 30 --out runs/sf-future
    fluidnexus predict runs/sf --frames 30 --out runs/sf-physics --no-refit
    fluidnexus predict runs/sf --from 89 --frames 30 --out runs/sf-check --model diag/model.json
    """
    from fluidnexus.memory import parse_limit
    from fluidnexus.predict.session import Interaction, check_new_run, simulate_future
    from fluidnexus.runs import open_run

    limit = parse_limit(max_memory)
    check_frames(frames)
    check_new_run(out)
    run = open_run(run_dir)
    refiner = make_refiner(method, no_refit, weights, lora, strength, steps, seed, offload, device)
    start_engine(arch)
    ctx, notes = future_context(run, from_frame, model_file, calibrate, calibrate_window)
    simulate_future(run, out, "predict", frames, Interaction(), refiner, from_frame, ctx, notes, anchor, limit)
