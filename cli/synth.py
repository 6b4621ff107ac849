"""``fluidnexus synth``: write a video for every ``novel`` view from the input view (paper Sec. 3.1, Eq. 1)."""
from __future__ import annotations

import logging
from pathlib import Path

import click
import numpy as np

from fluidnexus.errors import InputError
from fluidnexus.scene import View, load_scene, save_views
from fluidnexus.video import read_video, write_video

from .options import max_memory_option, parse_color

log = logging.getLogger("fluidnexus")

resolution_option = click.option(
    "--resolution", default="auto", show_default=True,
    help="Work and write at this scale of the scene's videos, or 'auto': recon's rule (long side 480 px), so "
         "recon reads the written videos as they are.")


def stored_size(camera, working) -> tuple[int, int]:
    """The size a novel video is written at: the working camera's, unless a side is odd (the video writer pads
    odd sizes, which would no longer match the camera), then the full camera's."""
    if working.width % 2 or working.height % 2:
        return camera.width, camera.height
    return working.width, working.height


def resized(video: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """[T, H, W, C] resampled to ``size`` (width, height); unchanged when it already has that size."""
    import cv2

    if video.shape[1:3] == (size[1], size[0]):
        return video
    return np.stack([cv2.resize(f, size, interpolation=cv2.INTER_LINEAR).reshape(size[1], size[0], -1)
                     for f in video])


def read_footage(path: Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """[T, H, W, C] float32 at ``size`` (width, height; None: the file's); a gray video stored as RGB
    (R = G = B) comes back with C = 1."""
    video = read_video(path, size=size)
    if video.shape[-1] == 3 and np.array_equal(video[..., :1], video[..., 1:2]) and np.array_equal(
            video[..., :1], video[..., 2:]):
        return np.ascontiguousarray(video[..., :1])
    return video


def smoke_only(scene, source, footage: np.ndarray, color: np.ndarray | None) -> tuple[np.ndarray, dict]:
    """The smoke layer of ``source``'s footage [T, h, w, C] over its plate (docs/background.md, "Smoke layer for a
    single video"), premultiplied over black, and its provenance record; ``color`` [3]: the smoke's colour as the
    user gives it (None: estimated)."""
    from fluidnexus.backdrop import resize_image, to_channels
    from fluidnexus.background.smoke_layer import NoSmoke, smoke_layer
    from fluidnexus.background.store import read_plate

    plate, confidence = read_plate(scene, source.name)
    height, width = footage.shape[1:3]
    plate = to_channels(resize_image(plate, width, height), footage.shape[-1])
    confidence = resize_image(confidence[..., None], width, height)[..., 0]
    record = scene.backgrounds[source.name].plate
    known = None if color is None else to_channels(color, footage.shape[-1])
    try:
        smoke = smoke_layer(footage, plate, confidence, known)
    except NoSmoke as err:
        raise InputError(scene.video_path(source), None, f"shows no smoke over its plate {record} ({err})") from None
    log.info("synth: smoke layer of %s over %s: colour %s, ill-conditioned pixels %.1f%%", source.name, record,
             smoke.summary()["smoke_color"], 100 * smoke.ill_conditioned)
    return smoke.layer, {"over": "black", "input_plate": record, **smoke.summary(),
                         "smoke_color_from": "estimated" if color is None else "--smoke-color"}


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
    from fluidnexus.gen.synthesizer import SynthesisInput, make_synthesizer
    from fluidnexus.memory import check, parse_limit, video_estimate
    from fluidnexus.scene_scale import scene_factor

    from .recon import resolve_resolution

    limit = parse_limit(max_memory)
    known_color = parse_color(smoke_color, "--smoke-color")
    scene = load_scene(scene_dir)
    inputs = scene.with_role("input")
    if not inputs:
        raise InputError(scene.root / "scene.json", "views", "the scene has no input view")
    source = scene.view(input_name) if input_name else inputs[0]
    if source.role != "input" or source.video is None:
        raise InputError(None, "--input", f"{source.name!r} is not an input view with a video")
    novel = scene.with_role("novel")
    if not novel:
        raise InputError(scene.root / "scene.json", "views", "the scene has no novel view to synthesise")
    scale = resolve_resolution(resolution, scene)
    camera = source.camera.scaled(scale)
    check(video_estimate("synth", scene.frame_count, camera.width, camera.height, 3), limit)
    if method == "zero123":
        from fluidnexus.gen.zero123 import Zero123Config

        synthesizer = make_synthesizer(method, weights=weights, config=Zero123Config(
            steps=steps, guidance=guidance, seed=seed, device=None if device == "auto" else device))
    else:
        from fluidnexus.gen.axisym import AxisymConfig

        synthesizer = make_synthesizer(method, config=AxisymConfig().scaled(scene_factor(scene)))
    footage = read_footage(scene.video_path(source), (camera.width, camera.height))
    smoke = None  # the smoke layer's provenance record, with a plate
    if source.name in scene.backgrounds:
        footage, smoke = smoke_only(scene, source, footage, known_color)
    elif known_color is not None:
        raise InputError(None, "--smoke-color", f"input view {source.name!r} has no plate: there is no smoke layer "
                                                "to separate (fluidnexus background first)")
    inp = SynthesisInput(footage, camera, scene.source, scene.volume)
    done = {}
    for view in novel:
        log.info("synth %s: %s -> %s", method, source.name, view.name)
        rel = f"videos/{view.name}_synth.mp4"
        working = view.camera.scaled(scale)
        video = resized(synthesizer.synthesize(inp, working), stored_size(view.camera, working))
        write_video(scene.root / rel, video, scene.fps)
        provenance = {"synth": {**synthesizer.provenance(), "input": source.name, "resolution": scale}}
        if smoke is not None:
            provenance["smoke_layer"] = smoke
        done[view.name] = View(view.name, view.role, view.camera, rel, provenance)
    save_views(scene.root, tuple(done.get(v.name, v) for v in scene.views))
    log.info("wrote %d novel videos into %s", len(done), scene.root / "videos")
