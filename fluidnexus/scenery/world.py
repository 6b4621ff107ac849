"""The scenery of a scene or run: its static layer (fitted to the input views' clean plates) and every obstacle the
gas flows around, declared and found.

A scene without plates has no static layer; its obstacles are the declared ones (scene.json ``obstacles``). With
plates, recon fits the layer at the run's resolution and colour channels (``static_layer.fit_static``, seeded by the
run's seed) and saves it as ``RUN/static.npz`` (a resumed run reads it back instead of fitting again), finds the
opaque bodies inside the volume (``found_obstacles.find_obstacles``: what the plates are sure of), each a boundary
of the scene or a solid in the flow, and keeps those that do not touch a declared body (``merge_with_declared``:
where the user declared a body, theirs wins). Predict, interact and diagnose rebuild
a run's bodies with :func:`run_scenery` (the finder is deterministic)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..images import resize_image, to_channels
from ..scene import Scene
from .found_obstacles import ball_obstacle, find_obstacles, merge_with_declared, refine_balls
from .obstacles import engine_obstacle, join
from ..video import read_video
from .backdrop import smoke_mask
from .plate_store import read_plate
from .static_layer import STATIC_FILE, StaticConfig, fit_static, load_static
from .view_objects import object_balls

log = logging.getLogger("fluidnexus")

SMOKE_FRAMES = 8  # frames of footage whose smoke the obstacle finder keeps free
SMOKE_THRESHOLD = 0.05  # a pixel shows smoke where it differs from the plate by more (recon's visual hull's)


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


def plates_at(scene: Scene, cameras: dict, channels: int) -> tuple[dict, list, list]:
    """(name -> camera, plates [H, W, C], confidences [H, W]) of the views that have a plate, at ``cameras``'
    sizes."""
    cams, plates, confidences = {}, [], []
    for name, camera in cameras.items():
        found = read_plate(scene, name)
        if found is None:
            continue
        plate, confidence = found
        cams[name] = camera
        plates.append(to_channels(resize_image(plate, camera.width, camera.height), channels))
        confidences.append(resize_image(confidence[..., None], camera.width, camera.height)[..., 0])
    return cams, plates, confidences


def smoke_masks(scene: Scene, cameras: dict, plates: list, frames: tuple[int, int]) -> list[list[np.ndarray]]:
    """Per frame of ``SMOKE_FRAMES`` spread evenly over ``frames``, per view of ``cameras`` (name -> camera, the
    views with a plate, in ``plates``' order): [H, W] bool, the pixels that show smoke over the view's plate."""
    start, stop = frames
    stride = max(1, (stop - start) // SMOKE_FRAMES)
    views = {v.name: v for v in scene.usable_views()}
    videos = [read_video(scene.video_path(views[name]), frames=slice(start, stop), stride=stride,
                         size=(camera.width, camera.height), channels=plate.shape[-1])
              for (name, camera), plate in zip(cameras.items(), plates)]
    return [[smoke_mask(video[k], SMOKE_THRESHOLD, plate) for video, plate in zip(videos, plates)]
            for k in range(len(videos[0]))]


def view_anchor(scene: Scene) -> np.ndarray | None:
    """Where a single view's objects over a plain backdrop stand (``view_objects``): the declared source's centre,
    else the plume's foot that ``synth`` found in the input view (a novel view's provenance), else None."""
    if scene.source is not None:
        return np.asarray(scene.source.center, np.float64)
    for view in scene.views:
        foot = ((view.provenance or {}).get("synth") or {}).get("plume_foot")
        if foot is not None:
            return np.asarray(foot["center"], np.float64)
    return None


def view_balls(scene: Scene, layer, cameras: list, plates: list, confidences: list) -> list:
    """A single view's objects over a plain backdrop, where its layer placed them (``objects_at``), as solid balls
    in the flow (``view_objects.object_balls``) whose centres lie inside the volume; none otherwise."""
    if "objects_at" not in layer.info:
        return []
    lo, hi = scene.volume.min, scene.volume.max
    balls = object_balls(cameras[0], plates[0], confidences[0], layer.background, layer.info["objects_at"],
                         StaticConfig().plain)
    return [ball_obstacle(c, r, lo, hi) for c, r in balls if np.all((c >= lo) & (c <= hi))]


def layer_floor(scene: Scene, views: int):
    """The floor the static layer of ``views`` input views seeds on (``fit_static(..., floor=)``): one view needs
    one and takes the volume's bottom face where none is declared (``Scene.ground``); several views only a declared
    one (``Scene.floor``): where the volume floats above a room's floor the bottom face is a wrong guess that their
    stereo does without (the generated family's development rooms 5 and 10, four views: -3.8 and -2.4 dB with it)."""
    return scene.ground() if views == 1 else scene.floor


def fit_scenery(scene: Scene, declared: Scenery, cameras: dict, channels: int, iterations: int, seed: int,
                frames: tuple[int, int], saved: Path | None = None) -> Scenery:
    """With plates: the static layer (read from ``saved``, a run's static.npz, when it exists; else fitted) and
    the obstacles found in it and in the footage of ``frames`` (``smoke_masks``); without: ``declared``
    unchanged. Writes nothing.

    Args:
        cameras: view name -> camera at the run's resolution (the views with plates are used).
    """
    if not scene.backgrounds or scene.volume is None:
        return declared
    named, plates, confidences = plates_at(scene, cameras, channels)
    smoke, cams = smoke_masks(scene, named, plates, frames), list(named.values())
    if saved is not None and saved.is_file():
        layer = load_static(saved)
        log.info("static layer: %d Gaussians read from %s", len(layer), saved)
    else:
        layer = fit_static(cams, plates, confidences, scene.volume.min, scene.volume.max,
                           StaticConfig(iterations=iterations, seed=seed), backdrop=scene.backdrop_color,
                           floor=layer_floor(scene, len(cams)), anchor=view_anchor(scene))
        log.info("static layer: %d Gaussians fitted to %d plates (loss %.4g)", len(layer), len(cams),
                 layer.info["loss"])
    found = find_obstacles(layer, cams, scene.volume.min, scene.volume.max, confidences=confidences, smoke=smoke)
    found = merge_with_declared(refine_balls(found, layer, cams) + view_balls(scene, layer, cams, plates, confidences),
                                declared.obstacle)
    for body in found:
        log.info("obstacle found in the footage, a %s: centre %s, radius %.4g m, volume %.4g m^3; the gas %s",
                 body.kind, np.round(body.center, 4), body.radius, body.volume, body.gas())
    obstacle = join(declared.obstacle, *(b.engine_body() for b in found))
    placed = {"objects_at": layer.info["objects_at"]} if "objects_at" in layer.info else {}
    record = {**declared.record, "static_layer": {"file": STATIC_FILE, "gaussians": len(layer),
                                                  "plates": sorted(named), **placed},
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
    return fit_scenery(scene, declared, cameras, run.channels, 0, 0, tuple(run.info["frames"]), saved)


# Diagnose simulates the same bodies in worker processes (``diagnose --jobs``): it passes where they come from, not
# the engine bodies (a carved body is a Taichi field), and every process rebuilds them.
@dataclass(frozen=True)
class Obstacles:
    """Where the bodies come from: ``scene_dir``'s declared obstacles, or with ``run_dir`` that run's declared and
    found ones."""

    scene_dir: str
    run_dir: str | None = None

    def body(self):
        """The engine body of every obstacle (``engine.obstacle``), or None; needs the engine started."""
        from ..runs import open_run
        from ..scene import load_scene

        if self.run_dir is not None:
            return run_scenery(open_run(self.run_dir)).obstacle
        return declared_scenery(load_scene(self.scene_dir)).obstacle


def scene_obstacles(scene_dir: Path, run_dir: Path | None = None) -> tuple[Obstacles | None, object | None]:
    """(the source of the bodies, or None when there are none; the bodies themselves, for this process)."""
    source = Obstacles(str(scene_dir), None if run_dir is None else str(run_dir))
    body = source.body()
    return (source, body) if body is not None else (None, None)
