"""What diagnose sees of a view: images of the smoke alone that grow with the amount of smoke along each ray.

- A view without a clean plate (glowing smoke on black, as ScalarFlow's capture): its gray frames, as before.
- A view with a plate (``fluidnexus background``: a backdrop, static objects): the smoke layer's opacity at the
  observation size (background/smoke_layer.py, with its one assumption: one smoke colour per video, that of the
  densest smoke). Smoke darker than its backdrop (PINF's absorbing smoke over white) and smoke brighter than it
  give the same positive image; the backdrop's texture and the static objects drop out.

Either is compared with the simulated plume's splats up to the fitted gain (observe.py). When some views of a scene
have plates, a view without one (a held-out camera: plates come from input views only) shows the backdrop as if
it were smoke, so it is left out.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from fluidnexus.backdrop import resize_image
from fluidnexus.background.smoke_layer import NoSmoke, smoke_color, smoke_layer
from fluidnexus.background.store import read_plate
from fluidnexus.scene import Scene
from fluidnexus.video import read_video

log = logging.getLogger("fluidnexus")


def usable(scene: Scene, name: str) -> bool:
    """Whether diagnose can see the smoke in view ``name``: every view when the scene has no plates, else the views
    that have one (the others are logged and left out)."""
    if not scene.backgrounds or name in scene.backgrounds:
        return True
    log.info("diagnose: view %s left out: it has no plate, and the scene's footage is over a backdrop", name)
    return False


def smoke_images(scene: Scene, views: list[tuple[str, Path, int, int]], frames: slice) -> list[np.ndarray]:
    """[T, height, width] float64 for each view (name, video path, width, height): its smoke in ``frames``
    (module docstring). The views with a plate share one smoke colour, the densest smoke's over all of them
    (background/smoke_layer.smoke_color): one smoke, seen from several sides."""
    images, plated = {}, {}
    for name, path, width, height in views:
        found = read_plate(scene, name)
        if found is None:
            images[name] = read_video(path, frames=frames, size=(width, height), gray=True)[..., 0].astype(np.float64)
            continue
        plate, confidence = found
        plated[name] = (read_video(path, frames=frames, size=(width, height), channels=3),
                        resize_image(plate, width, height), resize_image(confidence[..., None], width, height)[..., 0])
    if plated:
        try:
            color = smoke_color(*(list(x) for x in zip(*plated.values())))
        except NoSmoke:
            color = None
        log.info("diagnose: %d views seen as the smoke's opacity over their plates (smoke colour %s)", len(plated),
                 "none: no smoke" if color is None else np.round(color, 3).tolist())
        for name, (video, plate, confidence) in plated.items():
            try:
                images[name] = smoke_layer(video, plate, confidence, color).alpha.astype(np.float64)
            except NoSmoke:
                images[name] = np.zeros(video.shape[:3])
    return [images[name] for name, *_ in views]
