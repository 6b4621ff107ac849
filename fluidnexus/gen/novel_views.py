"""The novel views of a scene (paper Sec. 3.1): a video synthesised for every novel view from an input view
(Eq. 1), then refined to temporal coherence (Eq. 2). ``fluidnexus synth`` / ``refine`` and the batch steps of the
same names run these; the backends are picked by name (``synthesizer.make_synthesizer``,
``refiner.make_refiner``).

Videos are written into the scene folder (``videos/NAME_synth.mp4``, ``videos/NAME_refined.mp4``) and recorded in
scene.json with their provenance.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError
from ..memory import check, video_estimate
from ..scene import Scene, View, save_views
from ..scenery.backdrop import Backdrop
from ..scenery.smoke_layer import view_smoke_layer
from ..video import read_footage, resize_video, write_video
from .plume_foot import plume_foot
from .refiner import make_refiner
from .synthesizer import SynthesisInput, make_synthesizer

log = logging.getLogger("fluidnexus")


def stored_size(camera, working) -> tuple[int, int]:
    """The size a novel video is written at: the working camera's, unless a side is odd (the video writer pads
    odd sizes, which would no longer match the camera), then the full camera's."""
    if working.width % 2 or working.height % 2:
        return camera.width, camera.height
    return working.width, working.height


def synthesis_source(scene: Scene, input_name: str | None) -> View:
    """The input view to synthesise from (``input_name``, default the scene's first input view); InputError when
    there is none, it is not an input view with a video, or the scene has no novel view."""
    inputs = scene.with_role("input")
    if not inputs:
        raise InputError(scene.root / "scene.json", "views", "the scene has no input view")
    source = scene.view(input_name) if input_name else inputs[0]
    if source.role != "input" or source.video is None:
        raise InputError(None, "--input", f"{source.name!r} is not an input view with a video")
    if not scene.with_role("novel"):
        raise InputError(scene.root / "scene.json", "views", "the scene has no novel view to synthesise")
    return source


def synthesize_views(scene: Scene, method: str, options: dict, scale: float, input_view: View,
                     smoke_color: np.ndarray | None, limit: int) -> int:
    """Write a video for every novel view of ``scene`` from ``input_view``'s footage at ``scale`` of the scene's
    videos with the synthesiser ``method`` (built with ``options``: ``weights=``, ``config=``); returns how many.

    With a plate for ``input_view`` (``fluidnexus background``) its smoke layer is synthesised (over black) instead
    of the raw frames; ``smoke_color`` [3] is the smoke's colour where known (None: estimated). Without a declared
    source the plume stands where the input view shows its foot on the floor (``plume_foot``; recorded in each
    novel view's provenance). Refuses (InputError) before reading anything when the videos would not fit in
    ``limit`` bytes."""
    camera = input_view.camera.scaled(scale)
    check(video_estimate("synth", scene.frame_count, camera.width, camera.height, 3), limit)
    synthesizer = make_synthesizer(method, **options)
    footage = read_footage(scene.video_path(input_view), (camera.width, camera.height))
    smoke = None  # the smoke layer's provenance record, with a plate
    if input_view.name in scene.backgrounds:
        footage, smoke = view_smoke_layer(scene, input_view, footage, smoke_color)
    elif smoke_color is not None:
        raise InputError(None, "--smoke-color", f"input view {input_view.name!r} has no plate: there is no smoke "
                                                "layer to separate (fluidnexus background first)")
    inflow, found = scene.source, None
    if inflow is None:
        behind = None if smoke is not None else Backdrop(  # the smoke layer is over black; else the scene's colour
            footage.shape[-1], {}, color=scene.backdrop_color).behind(camera).background
        found = plume_foot(scene, input_view.name, camera, footage, behind, scene.video_path(input_view))
        inflow = found.source
        log.info("synth: no declared source; the plume's foot in %s (frame %d) meets the floor at %s, radius %.4g m",
                 input_view.name, found.record["frame"], np.round(inflow.center, 4).tolist(), inflow.radius)
    inp = SynthesisInput(footage, camera, inflow, scene.volume)
    done = {}
    for view in scene.with_role("novel"):
        log.info("synth %s: %s -> %s", method, input_view.name, view.name)
        rel = f"videos/{view.name}_synth.mp4"
        working = view.camera.scaled(scale)
        video = resize_video(synthesizer.synthesize(inp, working), stored_size(view.camera, working))
        write_video(scene.root / rel, video, scene.fps)
        provenance = {"synth": {**synthesizer.provenance(), "input": input_view.name, "resolution": scale}}
        if found is not None:
            provenance["synth"]["plume_foot"] = found.record
        if smoke is not None:
            provenance["smoke_layer"] = smoke
        done[view.name] = View(view.name, view.role, view.camera, rel, provenance)
    save_views(scene.root, tuple(done.get(v.name, v) for v in scene.views))
    log.info("wrote %d novel videos into %s", len(done), scene.root / "videos")
    return len(done)


def refinable_views(scene: Scene) -> list[View]:
    """The novel views that have a video; InputError when none has (synth first)."""
    novel = [v for v in scene.with_role("novel") if v.video is not None]
    if not novel:
        raise InputError(scene.root / "scene.json", "views", "no novel view has a video yet; run synth first")
    return novel


def refine_views(scene: Scene, method: str, options: dict, scale: float, limit: int) -> int:
    """Refine every novel video of ``scene`` at ``scale`` with the refiner ``method`` (built with ``options``);
    returns how many. The unrefined video is kept and named
    in the provenance, and a second refine starts from it again. Refuses (InputError) before reading anything
    when the videos would not fit in ``limit`` bytes."""
    novel = refinable_views(scene)
    working = novel[0].camera.scaled(scale)
    size = (working.width, working.height)
    check(video_estimate("refine", scene.frame_count, *size, 4), limit)
    refiner = make_refiner(method, **options)
    done = {}
    for view in novel:
        provenance = dict(view.provenance or {})
        unrefined = provenance.get("unrefined", view.video)  # re-running refine starts from the rough video
        log.info("refine %s: %s", method, view.name)
        rel = f"videos/{view.name}_refined.mp4"
        refined = resize_video(refiner.refine(read_footage(scene.root / unrefined, size)),
                               stored_size(view.camera, working))
        write_video(scene.root / rel, refined, scene.fps)
        provenance.update({"unrefined": unrefined, "refine": {**refiner.provenance(), "resolution": scale}})
        done[view.name] = View(view.name, view.role, view.camera, rel, provenance)
    save_views(scene.root, tuple(done.get(v.name, v) for v in scene.views))
    log.info("refined %d novel videos", len(done))
    return len(done)
