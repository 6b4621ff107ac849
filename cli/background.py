"""``fluidnexus background``: estimate a clean plate (the backdrop without smoke) for every input view of a scene."""
from __future__ import annotations

from pathlib import Path

import click

from fluidnexus.scene import load_scene

from .options import parse_color


@click.command()
@click.argument("scene_dir", metavar="SCENE", type=click.Path(path_type=Path, file_okay=False))
@click.option("--plate", "plates", multiple=True, metavar="NAME=FILE",
              help="An image of view NAME's empty backdrop, used as is (repeatable).")
@click.option("--color", metavar="R,G,B", help="The backdrop's colour, values in [0, 1] (default: the scene's "
                                                "backdrop_color, e.g. PINF's frame_bkg_color).")
@click.option("--resolution", default="auto", show_default=True,
              help="Working scale of the estimate, a factor in (0, 1] of the video size (auto: at most 0.25 "
                   "megapixels); plates are always written at the videos' size.")
@click.option("--overwrite", is_flag=True, help="Replace plates the scene already has.")
def background(scene_dir: Path, plates: tuple[str, ...], color: str | None, resolution: str, overwrite: bool) -> None:
    """Estimate one clean plate per input view of SCENE into SCENE/backgrounds/ and record them in scene.json.

    Sources, per view, in order: a --plate; frames before any smoke appears (found automatically); a known
    backdrop colour (--color or the scene's); otherwise a per-pixel estimate from the moments each pixel is
    still. Ground-truth videos are never read. SCENE/backgrounds/sheet.png shows the result.

    \b
    fluidnexus background scene
    fluidnexus background scene --plate cam0=empty_wall.png --color 1,1,1
    """
    from fluidnexus.scenery.plate_estimate import estimate_plates

    estimate_plates(load_scene(scene_dir), plates, parse_color(color, "--color"), resolution, overwrite)
