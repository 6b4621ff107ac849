"""``fluidnexus predict``: what the smoke does next (FluidNexus Sec. 3.3, Alg. S2; docs/prediction.md)."""
from __future__ import annotations

from pathlib import Path

import click

from .options import arch_option, max_memory_option, start_engine


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
    from fluidnexus.predict.future import Future, future_refiner, predict_run
    from fluidnexus.runs import open_run

    limit = parse_limit(max_memory)
    future = Future(frames, from_frame, model_file, calibrate, calibrate_window, anchor)
    future.check(out)
    run = open_run(run_dir)
    refiner = future_refiner(method, no_refit, weights, lora, strength, steps, seed, offload, device)
    start_engine(arch)
    predict_run(run, out, future, refiner, limit)
