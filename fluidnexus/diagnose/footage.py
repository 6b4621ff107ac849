"""What diagnose sees of a view: images of the smoke alone that grow with the amount of smoke along each ray.

- A view without a clean plate (glowing smoke on black, as ScalarFlow's capture): its gray frames, as before.
- A view with a plate (``fluidnexus background``: a backdrop, static objects): the smoke layer's opacity at the
  observation size (scenery/smoke_layer.py, with its one assumption: one smoke colour per video, that of the
  densest smoke). Smoke darker than its backdrop (PINF's absorbing smoke over white) and smoke brighter than it
  give the same positive image; the backdrop's texture and the static objects drop out.

- A view without a plate in a scene with plates (a held-out camera: plates come from input views only): given a
  reconstruction of the scene with a static layer (``recon`` fits one to the plates), the layer rendered from that
  camera is its plate, as eval composites held-out cameras over it; the smoke colour stays the one the real plates
  give. Without a layer such a view would show the backdrop as if it were smoke, so it is left out.

Either is compared with the simulated plume's splats up to the fitted gain (observe.py).
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from fluidnexus.images import resize_image, to_channels
from fluidnexus.scene import Scene
from fluidnexus.scenery.plate_store import read_plate
from fluidnexus.scenery.smoke_layer import NoSmoke, smoke_color, smoke_layer
from fluidnexus.video import read_video

log = logging.getLogger("fluidnexus")


def run_layer(run_dir: Path | None):
    """The static layer (``scenery.static_layer.StaticLayer``) recon fitted in ``run_dir``, or None (no run, or a run
    of footage without plates)."""
    from fluidnexus.scenery.static_layer import STATIC_FILE, load_static

    if run_dir is None or not (Path(run_dir) / STATIC_FILE).is_file():
        return None
    return load_static(Path(run_dir) / STATIC_FILE)


def usable(scene: Scene, name: str, layer=None) -> bool:
    """Whether diagnose can see the smoke in view ``name``: every view when the scene has no plates, else the views
    that have one, and with a static ``layer`` every view (the others are logged and left out)."""
    if not scene.backgrounds or name in scene.backgrounds:
        return True
    if layer is not None:
        log.info("diagnose: view %s has no plate: the run's static layer seen from it is its background", name)
        return True
    log.info("diagnose: view %s left out: it has no plate, and the scene's footage is over a backdrop", name)
    return False


def layer_plate(layer, camera) -> np.ndarray:
    """[H, W, C] the static ``layer`` rendered from ``camera``, in the layer's channels (needs the engine)."""
    from fluidnexus.scenery.static_layer import render_static

    return np.clip(render_static(layer, camera)[0].detach().cpu().numpy(), 0.0, 1.0).astype(np.float32)


def smoke_images(scene: Scene, views: list[tuple], frames: slice, layer=None) -> list[np.ndarray]:
    """[T, height, width] float64 for each view (name, video path, width, height, its camera at full size): its
    smoke in ``frames`` (module docstring). The views with a plate share one smoke colour, the densest smoke's over
    all of them (scenery/smoke_layer.smoke_color): one smoke, seen from several sides. With a static ``layer``,
    a view without a plate in a scene with plates is seen over the layer's render from its camera, in the layer's
    channels (a gray layer: its frames and that colour as gray)."""
    images, plated, held = {}, {}, {}
    for name, path, width, height, camera in views:
        found = read_plate(scene, name)
        if found is None and scene.backgrounds and layer is not None:
            plate = resize_image(layer_plate(layer, camera), width, height)
            held[name] = (to_channels(read_video(path, frames=frames, size=(width, height), channels=3),
                                      plate.shape[-1]), plate)
        elif found is None:
            images[name] = read_video(path, frames=frames, size=(width, height), gray=True)[..., 0].astype(np.float64)
        else:
            plate, confidence = found
            plated[name] = (read_video(path, frames=frames, size=(width, height), channels=3),
                            resize_image(plate, width, height),
                            resize_image(confidence[..., None], width, height)[..., 0])
    if plated:
        try:
            color = smoke_color(*(list(x) for x in zip(*plated.values())))
        except NoSmoke:
            color = None
        log.info("diagnose: %d views seen as the smoke's opacity over their plates (smoke colour %s)", len(plated),
                 "none: no smoke" if color is None else np.round(color, 3).tolist())
        for name, (video, plate, confidence) in plated.items():
            images[name] = _opacity(video, plate, confidence, color)
        for name, (video, plate) in held.items():
            images[name] = _opacity(video, plate, np.ones(plate.shape[:2], np.float32),
                                    None if color is None else to_channels(color, plate.shape[-1]))
    return [images[name] for name, *_ in views]


def _opacity(video: np.ndarray, plate: np.ndarray, confidence: np.ndarray, color) -> np.ndarray:
    """[T, H, W] float64 the smoke's opacity over ``plate`` (zeros where there is no smoke: no colour, or none in
    this view)."""
    if color is None:
        return np.zeros(video.shape[:3])
    try:
        return smoke_layer(video, plate, confidence, color).alpha.astype(np.float64)
    except NoSmoke:
        return np.zeros(video.shape[:3])
