"""``fluidnexus background``: estimate a clean plate (the backdrop without smoke) for every input view of a scene."""
from __future__ import annotations

import logging
from pathlib import Path

import click
import numpy as np

from fluidnexus.errors import InputError
from fluidnexus.scene import SCENE_FILE, load_scene

from .options import parse_color

log = logging.getLogger("fluidnexus")


def parse_plates(items: tuple[str, ...], scene, views) -> dict[str, tuple[Path, np.ndarray]]:
    """``--plate NAME=FILE``: each names an input view with footage once, and its image has that camera's size."""
    from fluidnexus.scenery.plate_store import read_plate_file

    by_name = {v.name: v for v in views}
    out = {}
    for item in items:
        name, sep, file = item.partition("=")
        if not sep or not name or not file:
            raise InputError(None, "--plate", f"expected NAME=FILE, got {item!r}")
        if name not in by_name:
            kind = "not an input view with a video" if name in scene.view_names() else "an unknown view"
            raise InputError(None, "--plate", f"{name!r} is {kind}; plates are for the input views "
                                              f"{sorted(by_name)}")
        if name in out:
            raise InputError(None, "--plate", f"view {name!r} is given two plates")
        cam = by_name[name].camera
        out[name] = (Path(file), read_plate_file(file, cam.width, cam.height, "--plate",
                                                 f"view {name!r}'s camera (and video)"))
    return out


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
    from fluidnexus.progress import progress
    from fluidnexus.scenery.plate_estimate import estimate_view, given_plate, working_scale
    from fluidnexus.scenery.plate_sheet import contact_sheet
    from fluidnexus.scenery.plate_store import FOLDER, write_backgrounds

    scene = load_scene(scene_dir)
    views = [v for v in scene.with_role("input") if v.video is not None]
    if not views:
        raise InputError(scene.root / SCENE_FILE, "views", "the scene has no input view with a video")
    given = parse_plates(plates, scene, views)
    known = parse_color(color, "--color")
    if known is None and scene.backdrop_color is not None:
        known = np.asarray(scene.backdrop_color, np.float32)
    if (scene.backgrounds or (scene.root / FOLDER).exists()) and not overwrite:
        raise InputError(scene.root / FOLDER, None, "the scene already has plates; pass --overwrite to replace them")
    cam = views[0].camera
    scale = working_scale(resolution, cam.width, cam.height)
    estimates, rows = {}, []
    with progress("background", len(views)) as bar:
        for view in views:
            path = scene.video_path(view)
            if view.name in given:
                est, middle = given_plate(*given[view.name], path, scene.frame_count)
            else:
                est, middle = estimate_view(view.name, path, view.camera.width, view.camera.height, scale, known)
            estimates[view.name] = est
            rows.append((view.name, middle, est))
            bar.advance()
    write_backgrounds(scene, estimates, contact_sheet(rows))
    for name, est in estimates.items():
        log.info("background %s: %s, mean confidence %.2f", name, est.source, est.confidence.mean())
    log.info("wrote %d plates and %s into %s", len(estimates), "sheet.png", scene.root / FOLDER)
