"""``fluidnexus interact``: the future under wind or around an obstacle (FluidNexus Sec. 4.2; docs/prediction.md)."""
from __future__ import annotations

import logging
from pathlib import Path

import click

from .options import arch_option, max_memory_option, start_engine
from .predict import model_options, refine_options

log = logging.getLogger("fluidnexus")


@click.command()
@click.argument("run_dir", metavar="RUN", type=click.Path(path_type=Path))
@click.option("--wind", help="Wind acceleration VX,VY,VZ in m/s^2.")
@click.option("--profile", type=click.Choice(["uniform", "height"]), default="uniform", show_default=True,
              help="Wind everywhere, or growing linearly with height above the source (the release).")
@click.option("--wind-height", type=float, default=None,
              help="height profile: metres above the source where the wind reaches full strength "
                   "(default: the scene volume's height).")
@click.option("--ball", help="A rigid ball CX,CY,CZ,R in metres.")
@click.option("--mesh", "mesh_file", type=click.Path(path_type=Path, dir_okay=False),
              help="A closed triangle mesh (OBJ/STL/PLY, metres, world frame) as the obstacle.")
@click.option("--from", "from_frame", type=int, default=None,
              help="Start after this reconstructed frame (default: the run's last frame).")
@click.option("--frames", type=int, required=True, help="Number of future frames N.")
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False), help="New run folder.")
@model_options
@refine_options
@max_memory_option
@arch_option
def interact(run_dir: Path, wind, profile, wind_height, ball, mesh_file, from_frame, frames, out, model_file, calibrate,
             calibrate_window, method, no_refit, anchor, weights, lora, strength, steps, seed, offload, device,
             max_memory, arch) -> None:
    """Simulate N frames of RUN with a wind force and/or a rigid obstacle, then render, refine and re-fit.

    Writes OUT/videos/compare_<view>.mp4: without | with the interaction, from the input camera and a novel one.

    \b
    fluidnexus interact runs/sf --wind 0.5,0,0 --profile height --frames 30 --out runs/sf-wind
    fluidnexus interact runs/sf --ball 0.33,0.25,-0.25,0.05 --frames 30 --out runs/sf-ball
    fluidnexus interact runs/sf --mesh bunny.obj --frames 30 --out runs/sf-bunny --no-refit
    """
    from fluidnexus.memory import parse_limit
    from fluidnexus.predict.future import Future, InteractionRequest, future_refiner, interact_run
    from fluidnexus.runs import open_run

    limit = parse_limit(max_memory)
    future = Future(frames, from_frame, model_file, calibrate, calibrate_window, anchor)
    future.check(out)
    request = InteractionRequest.parse(wind, profile, wind_height, ball, mesh_file)
    run = open_run(run_dir)
    refiner = future_refiner(method, no_refit, weights, lora, strength, steps, seed, offload, device)
    start_engine(arch)
    for path in interact_run(run, out, future, request, refiner, limit):
        log.info("wrote %s", path)
