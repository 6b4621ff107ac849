"""The static scene at the start of a reconstruction (issue 16, parts 3-4): the static layer fitted to the input
views' clean plates, and the obstacles it shows, joined with the scene's declared ones.

A scene without plates has no static layer; its obstacles are the declared ones (scene.json ``obstacles``). With
plates, recon fits the layer at the run's resolution and colour channels (``fluidnexus.static.fit_static``, seeded
by the run's seed) and saves it as ``RUN/static.npz`` (a resumed run reads it back instead of fitting again), finds the
opaque bodies inside the volume (``find_obstacles``) and keeps those that do not touch a declared body
(``merge_with_declared``: where the user declared a body, theirs wins).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..backdrop import resize_image, to_channels
from ..background.store import read_plate
from ..obstacles import engine_obstacle, join
from ..scene import Scene
from ..static import (STATIC_FILE, StaticConfig, find_obstacles, fit_static, load_static, merge_with_declared,
                      refine_balls)

log = logging.getLogger("fluidnexus")


@dataclass(frozen=True, eq=False)
class Scenery:
    """``layer``: the static layer or None; ``obstacle``: the engine body of every obstacle (declared and found)
    or None; ``record``: what was fitted and found, for run.json."""

    layer: object | None
    obstacle: object | None
    record: dict


def declared_scenery(scene: Scene) -> Scenery:
    """The declared obstacles alone (read before anything is written: a bad mesh stops the run first)."""
    body = engine_obstacle(scene.obstacles, scene.root, scene.volume)
    return Scenery(None, body, {"obstacles": [o.to_dict() for o in scene.obstacles]})


def plates_at(scene: Scene, cameras: dict, channels: int) -> tuple[list, list, list]:
    """(cameras, plates [H, W, C], confidences [H, W]) of the views that have a plate, at ``cameras``' sizes."""
    cams, plates, confidences = [], [], []
    for name, camera in cameras.items():
        found = read_plate(scene, name)
        if found is None:
            continue
        plate, confidence = found
        cams.append(camera)
        plates.append(to_channels(resize_image(plate, camera.width, camera.height), channels))
        confidences.append(resize_image(confidence[..., None], camera.width, camera.height)[..., 0])
    return cams, plates, confidences


def fit_scenery(scene: Scene, declared: Scenery, cameras: dict, channels: int, iterations: int, seed: int,
                saved: Path | None = None) -> Scenery:
    """With plates: the static layer (read from ``saved``, a run's static.npz, when it exists; else fitted) and
    the obstacles found in it; without: ``declared`` unchanged. Writes nothing.

    Args:
        cameras: view name -> camera at the run's resolution (the views with plates are used).
    """
    if not scene.backgrounds or scene.volume is None:
        return declared
    if saved is not None and saved.is_file():
        cams = [camera for name, camera in cameras.items() if name in scene.backgrounds]
        layer = load_static(saved)
        log.info("static layer: %d Gaussians read from %s", len(layer), saved)
    else:
        cams, plates, confidences = plates_at(scene, cameras, channels)
        layer = fit_static(cams, plates, confidences, scene.volume.min, scene.volume.max,
                           StaticConfig(iterations=iterations, seed=seed))
        log.info("static layer: %d Gaussians fitted to %d plates (loss %.4g)", len(layer), len(cams),
                 layer.info["loss"])
    found = refine_balls(find_obstacles(layer, cams, scene.volume.min, scene.volume.max), layer, cams)
    found = merge_with_declared(found, declared.obstacle)
    for body in found:
        log.info("obstacle found in the footage: centre %s, radius %.4g m%s", np.round(body.center, 4),
                 body.radius, " (sphere-like: a ball)" if body.sphere_like() else " (a carved grid)")
    obstacle = join(declared.obstacle, *(b.engine_body() for b in found))
    record = {**declared.record, "static_layer": {"file": STATIC_FILE, "gaussians": len(layer),
                                                  "plates": sorted(n for n in cameras if n in scene.backgrounds)},
              "found_obstacles": [b.to_dict() for b in found]}
    return replace(declared, layer=layer, obstacle=obstacle, record=record)


def run_scenery(run) -> Scenery:
    """The static scene of a finished run (``fluidnexus.runs.Run``): its declared obstacles, and with a static
    layer (``RUN/static.npz``) the obstacles found in it, exactly as recon found them (the finder is
    deterministic). Used by predict and interact; needs the engine started."""
    scene = run.scene(check_videos=False)
    declared = declared_scenery(scene)
    saved = run.root / STATIC_FILE
    if not saved.is_file():
        return declared
    cameras = {v.name: v.camera.scaled(run.resolution) for v in scene.usable_views()}
    return fit_scenery(scene, declared, cameras, run.channels, 0, 0, saved)
