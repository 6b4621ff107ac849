"""``fluidnexus render``'s work: MP4 (and PNG) videos of a run from the scene's cameras or an orbit around its
volume, over what each camera saw behind the smoke, optionally beside the real video."""
from __future__ import annotations

import logging
from pathlib import Path

from .errors import InputError
from .frames import orbit_cameras, render_state, side_by_side
from .images import resize_image, to_channels
from .progress import track
from .runs import Run
from .scene import load_ground_truth
from .scenery.backdrop import Behind, black_backdrop, run_backdrop
from .scenery.plate_store import read_image
from .video import read_video, write_frames, write_video

log = logging.getLogger("fluidnexus")


def view_cameras(run, scene, which: str):
    """(name, frame -> camera at the run's resolution, ground-truth video or None) for ``--views``; a moving
    ground-truth camera gives its pose at each frame."""
    truths = {g.name: g for g in load_ground_truth(scene.root)}
    views = {v.name: v for v in scene.views}
    if which == "all":
        names = list(views)
    elif which == "ground-truth":
        names = list(truths)
    else:
        names = [n.strip() for n in which.split(",") if n.strip()]
    out = []
    for name in names:
        if name in truths:
            g = truths[name]
            out.append((name, lambda t, g=g: g.camera_at(t).scaled(run.resolution), scene.root / g.video))
        elif name in views:
            cam = views[name].camera.scaled(run.resolution)
            out.append((name, lambda t, cam=cam: cam, None))
        else:
            raise InputError(scene.root / "scene.json", "--views",
                             f"unknown view {name!r}; known: {sorted(views) + sorted(truths)}")
    return out


def backdrop_choice(choice: str, run):
    """(camera, view name or None) -> ``Behind`` for ``--background``; a FILE is read (and refused) at once."""
    if choice == "plates":
        backdrop = run_backdrop(run)
        return lambda camera, view: backdrop.behind(camera, view)
    if choice == "black":
        black = black_backdrop(run.channels)
        return lambda camera, view: black.behind(camera, view)
    try:
        image = to_channels(read_image(choice), run.channels)
    except InputError as err:
        raise InputError(err.path, "--background", f"{err.message} (expected black, plates or an image file)") \
            from None
    return lambda camera, view: Behind(resize_image(image, camera.width, camera.height))


def render_run(run: Run, out: Path, which: str = "all", orbit: int = 0, compare: bool = False, png: bool = False,
               background: str = "plates", with_alpha: bool = False) -> None:
    """Write ``out/NAME.mp4`` for the views ``which`` names (``view_cameras``) over ``background``
    (``backdrop_choice``); with ``compare`` beside the real video (``NAME_compare.mp4``), with ``with_alpha`` the
    smoke's matte too, with ``orbit`` N frames of one turn around the volume (``orbit.mp4``). Needs the engine
    started."""
    scene = run.scene(check_videos=False)
    if orbit < 0:
        raise InputError(None, "--orbit", f"must be >= 0, got {orbit}")
    behind_of = backdrop_choice(background, run)
    frames = run.frames
    states = [run.state(t) for t in frames]
    views = view_cameras(run, scene, "ground-truth" if compare and which == "all" else which)
    for name, camera_at, truth in track(views, "render"):
        cam = camera_at(frames[0])
        behind = behind_of(cam, name)
        video = [render_state(s, camera_at(t), behind) for s, t in zip(states, frames)]
        if with_alpha:
            write_video(out / f"{name}_alpha.mp4", [render_state(s, camera_at(t), matte=True)
                                                    for s, t in zip(states, frames)], fps=scene.fps)
        if compare:
            if truth is None:
                raise InputError(scene.root / "scene.json", "--compare", f"view {name!r} has no ground-truth video")
            real = read_video(truth, frames=slice(frames[0], frames[-1] + 1), size=(cam.width, cam.height),
                              channels=run.channels)
            video = [side_by_side(r, real[t - frames[0]]) for r, t in zip(video, frames)]
            name = f"{name}_compare"
        write_video(out / f"{name}.mp4", video, fps=scene.fps)
        if png:
            write_frames(out / name, video)
        log.info("wrote %s", out / f"{name}.mp4")
    if orbit:
        if scene.volume is None:
            raise InputError(scene.root / "scene.json", "volume", "--orbit needs the scene's volume")
        cams = orbit_cameras(scene.volume, scene.views[0].camera.scaled(run.resolution), orbit)
        picks = [states[round(k * (len(states) - 1) / max(1, orbit - 1))] for k in range(orbit)]
        write_video(out / "orbit.mp4", [render_state(s, c, behind_of(c, None)) for s, c in zip(picks, cams)],
                    fps=scene.fps)
        log.info("wrote %s", out / "orbit.mp4")
