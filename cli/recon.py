"""``fluidnexus recon``: reconstruct the smoke of a scene into a run folder."""
from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import click

from fluidnexus.atomic import read_json
from fluidnexus.scene import load_scene
from fluidnexus.video import parse_frame_range

from .options import arch_option, max_memory_option, start_engine

log = logging.getLogger("fluidnexus")
SPECIAL = {"frames", "channels", "resolution"}


def _settings_options(func):
    """One ``--name`` option per reconstruction setting (weights, iterations, learning rates, ...)."""
    from fluidnexus.recon.config import LENGTHS, ReconConfig

    for f in reversed(dataclasses.fields(ReconConfig)):
        if f.name in SPECIAL:
            continue
        scaled = " m x the scene's length scale (docs/scale.md)" if f.name in LENGTHS else ""
        func = click.option(f"--{f.name.replace('_', '-')}", f.name, type=type(f.default), default=None,
                            help=f"default {f.default}{scaled}")(func)
    return func


def load_overrides(path: Path | None) -> dict:
    if path is None:
        return {}
    data = read_json(path, "settings file")
    return data.get("recon", data)


@click.command()
@click.argument("scene_dir", type=click.Path(path_type=Path))
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False), help="Run folder.")
@click.option("--frames", "frames_text", default=None, help="Frame range A:B (half-open), default all.")
@click.option("--resolution", default="auto", show_default=True,
              help="Image scale of the scene's videos, or 'auto' (long side 480 px).")
@click.option("--channels", type=click.Choice(["gray", "rgb"]), default="gray", show_default=True)
@click.option("--config", "config_file", type=click.Path(path_type=Path, dir_okay=False),
              help="JSON settings (a run's config.json works); command-line values win.")
@click.option("--model", "model_file", type=click.Path(path_type=Path, dir_okay=False),
              help="A model.json (e.g. from `fluidnexus diagnose`) instead of the paper's ScalarFlow gas.")
@click.option("--resume", is_flag=True, help="Continue an interrupted run in --out.")
@max_memory_option
@arch_option
@_settings_options
def recon(scene_dir: Path, out: Path, frames_text, resolution, channels, config_file, model_file, resume, max_memory,
          arch, **settings) -> None:
    """Reconstruct physical and visual particles of SCENE_DIR frame by frame (FluidNexus Alg. S1)."""
    from fluidnexus.memory import parse_limit
    from fluidnexus.model_file import load_model_file
    from fluidnexus.recon.config import config_for_scene
    from fluidnexus.recon.run import reconstruct
    from fluidnexus.recon.setup import default_setup
    from fluidnexus.working_resolution import resolve_resolution

    limit = parse_limit(max_memory)
    scene = load_scene(scene_dir)
    values = load_overrides(config_file)
    values.update({k: v for k, v in settings.items() if v is not None})
    if frames_text is not None:
        rng = parse_frame_range(frames_text)
        values["frames"] = (rng.start or 0, rng.stop)
    values["resolution"] = resolve_resolution(resolution, scene)
    values["channels"] = 1 if channels == "gray" else 3
    cfg = config_for_scene(scene, values, config_file)  # lengths follow the scene's size unless given
    loaded = load_model_file(model_file, rollout=False)  # its physics only: recon emits as the scene says
    start_engine(arch)
    setup = default_setup(scene, cfg, None if loaded is None else loaded.model)
    summary = reconstruct(scene, out, setup, resume=resume, max_memory=limit)
    log.info("reconstructed frames %d:%d into %s (%.1f s per frame)", *summary["frames"], out,
             summary["seconds_per_frame"])
