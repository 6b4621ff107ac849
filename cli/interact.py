"""``fluidnexus interact``: the future under wind or around an obstacle (FluidNexus Sec. 4.2; docs/prediction.md)."""
from __future__ import annotations

import logging
from pathlib import Path

import click

from fluidnexus.errors import InputError

from .options import arch_option, max_memory_option, start_engine
from .predict import check_frames, future_context, make_refiner, model_options, refine_options

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
    from fluidnexus.predict.rollout import parse_wind, with_wind
    from fluidnexus.predict.session import (Interaction, check_new_run, comparison_videos, physics_baseline,
                                            simulate_future)
    from fluidnexus.runs import open_run
    from fluidnexus.scene_scale import WIND_HEIGHT
    from fluidnexus.scenery.obstacles import make_obstacle, parse_sphere

    limit = parse_limit(max_memory)
    check_frames(frames)
    check_new_run(out)
    if wind is None and ball is None and mesh_file is None:
        raise InputError(None, "--wind/--ball/--mesh", "give at least one interaction")
    if ball is not None and mesh_file is not None:
        raise InputError(None, "--ball/--mesh", "give one obstacle, not both")
    accel = parse_wind(wind) if wind is not None else None
    if ball is not None:
        parse_sphere(ball, "--ball", "CX,CY,CZ,R in metres")
    if wind_height is not None and not wind_height > 0:
        raise InputError(None, "--wind-height", f"must be > 0, got {wind_height}")
    run = open_run(run_dir)
    refiner = make_refiner(method, no_refit, weights, lora, strength, steps, seed, offload, device)
    start_engine(arch)
    ctx, notes = future_context(run, from_frame, model_file, calibrate, calibrate_window)
    info, model = {}, None
    if accel is not None:
        scene = run.scene(check_videos=False)
        height = wind_height or (float(scene.volume.max[1] - scene.volume.min[1]) if scene.volume is not None
                                else WIND_HEIGHT * run.length_scale)
        model = with_wind(ctx.model, accel, profile, ctx.source.center[1], height)
        info["wind"] = {"accel": list(accel), "profile": profile, "height": height}
    obstacle = None
    if ball is not None or mesh_file is not None:
        obstacle, info["obstacle"] = make_obstacle(ball, mesh_file)
    _, with_ = simulate_future(run, out, "interact", frames, Interaction(model, obstacle, info), refiner, from_frame,
                               ctx, notes, anchor, limit)
    without = physics_baseline(run, frames, from_frame, ctx)
    for path in comparison_videos(run, out, without, with_, obstacle):
        log.info("wrote %s", path)
