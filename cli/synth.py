"""``fluidnexus synth``: write a video for every ``novel`` view from the input view (paper Sec. 3.1, Eq. 1)."""
from __future__ import annotations

from pathlib import Path

import click

from fluidnexus.scene import load_scene

from .options import max_memory_option, parse_color

resolution_option = click.option(
    "--resolution", default="auto", show_default=True,
    help="Work and write at this scale of the scene's videos, or 'auto': recon's rule (long side 480 px), so "
         "recon reads the written videos as they are.")


@click.command()
@click.argument("scene_dir", metavar="SCENE", type=click.Path(path_type=Path, file_okay=False))
@click.option("--method", type=click.Choice(["axisym", "zero123"]), default="axisym", show_default=True,
              help="axisym: non-learned axisymmetric plume model; zero123: Zero-1-to-3 from local weights.")
@click.option("--weights", type=click.Path(path_type=Path), help="Local diffusers-format Zero123 folder.")
@click.option("--input", "input_name", help="The input view to synthesise from (default: the first one).")
@click.option("--steps", type=int, default=50, show_default=True, help="zero123: DDIM steps.")
@click.option("--guidance", type=float, default=3.0, show_default=True, help="zero123: guidance scale.")
@click.option("--seed", type=int, default=0, show_default=True, help="zero123: noise seed.")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
              help="zero123: torch device.")
@click.option("--smoke-color", metavar="R,G,B",
              help="With a plate: the smoke's colour where it is opaque, values in [0, 1] (white steam: 1,1,1), when "
                   "known; default: the colour of the densest smoke, taken as opaque.")
@resolution_option
@max_memory_option
def synth(scene_dir: Path, method: str, weights: Path | None, input_name: str | None, steps: int, guidance: float,
          seed: int, device: str, smoke_color: str | None, resolution: str, max_memory: str) -> None:
    """Synthesise a video for every novel view of SCENE from its input view.

    Where the input view has a clean plate (fluidnexus background), its smoke layer is synthesised instead of the
    raw frames: the novel videos show the smoke alone over black. The smoke's colour is that of its densest part,
    or --smoke-color when known.

    \b
    fluidnexus synth scene                       # axisym, runs anywhere
    fluidnexus synth scene --method zero123 --weights ~/models/zero123-xl-scalarflow
    """
    from fluidnexus.gen.novel_views import synthesis_source, synthesize_views
    from fluidnexus.memory import parse_limit
    from fluidnexus.scene_scale import scene_factor
    from fluidnexus.working_resolution import resolve_resolution

    limit = parse_limit(max_memory)
    known_color = parse_color(smoke_color, "--smoke-color")
    scene = load_scene(scene_dir)
    source = synthesis_source(scene, input_name)
    if method == "zero123":
        from fluidnexus.gen.zero123 import Zero123Config

        options = {"weights": weights, "config": Zero123Config(steps=steps, guidance=guidance, seed=seed,
                                                               device=None if device == "auto" else device)}
    else:
        from fluidnexus.gen.axisym import AxisymConfig

        options = {"config": AxisymConfig().scaled(scene_factor(scene))}
    synthesize_views(scene, method, options, resolve_resolution(resolution, scene), source, known_color, limit)
