"""Where the plume stands, from one view: the end the earliest smoke leaves from, cast onto the scene's floor.

From a single video the depth of the smoke along the input rays is not observed: any plume on the input ray through
each pixel looks the same. The tool fixes it with one stated assumption: the smoke leaves something that stands on
the scene's floor (``Scene.ground``: the declared ``floor`` of scene.json, else the volume's bottom face), or a
stated ``source_height`` above it (``Scene.source_plane``: a nozzle on a stand; the floor itself stays where the
static layer lays what it sees of the ground). So the input ray through the foot of the earliest smoke meets that
plane ("the floor" below) at the source:

1. the earliest frame in which at least ``MIN_PIXELS`` pixels differ from what the view sees behind the smoke by
   more than ``THRESHOLD`` (``scenery.backdrop.smoke_mask``);
2. the image direction of "down" (the floor normal, reversed) at the smoke, and the end of the smoke it leaves
   from, told by how its centroid moves over the next ``LEAVING_FRAMES`` frames: down the image, by more than a
   pixel and more than across (a puff from a nozzle above: the end is its top); across the image, by more than a
   pixel and more than along (a jet: the end is its trailing side, the one it moves away from); else its foot.
   The end is the smoke's ``FOOT_PERCENTILE`` extent away from where it goes, robust to a few noisy pixels,
   centred across the band of smoke pixels within ``FOOT_BAND`` of it;
3. the end pixel's ray meets the floor (for a puff or a jet, the plane of its nozzle: ``source_height``). A foot or
   a top lies on a rim of the inflow: the rim nearest the camera where the camera looks at the end from the side
   the smoke leaves to (seen from above, the lowest smoke in the image is the near rim), else the far rim; the
   centre lies one radius beyond the near rim along the ray's horizontal direction (one radius before the far
   rim). A jet's nozzle faces sideways, so the middle of its trailing side is the centre. The band's width at that
   depth gives the radius.

The cast is only as good as the angle at which the foot's ray meets the floor: a camera at the floor's height sees
it edge on, and a pixel of error in the foot moves the cast far along the ray (ScalarFlow's cameras stand 5.6 cm
above the volume's floor, looking up: 2.7 degrees, 1.8 m off for the 19 px between the visible foot and the inflow).
Below ``MIN_GRAZING_DEG`` the depth is not observed from this view, and the tool says so and takes the foot's ray at
the depth of the volume's centre instead (the box decides, as it did before any of this); the record names which.

A declared source (scene.json ``source``) always wins; this runs only without one. Errors (one line, exit 2): no
smoke in the input, a camera that looks along the floor's normal, a foot ray that misses the floor or meets it
outside the volume.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..scene import SCENE_FILE, Scene, Source
from ..scenery.backdrop import smoke_mask

log = logging.getLogger("fluidnexus")

THRESHOLD = 0.05  # a pixel is smoke where it differs from what is behind it by more than this (as recon's hull)
MIN_PIXELS = 12  # ... and a frame holds smoke from this many such pixels on
FOOT_PERCENTILE = 98.0  # the foot: this percentile of the smoke pixels' extent along the image's down direction
FOOT_BAND = 0.05  # the foot's band: pixels within this share of the smoke's extent above the foot
MIN_BAND_PIXELS = 2.0  # ... and at least this many pixels
MIN_GRAZING_DEG = 8.0  # a foot ray meeting the floor at a smaller angle does not fix the depth
LEAVING_FRAMES = 4  # the smoke's motion in the image over this many frames after the earliest tells which end it
#                     leaves from


@dataclass(frozen=True)
class PlumeFoot:
    """The source found in the input view (``source``) and how (``record``, for the provenance)."""

    source: Source
    record: dict


def down_in_image(camera: Camera, pixel: np.ndarray, depth: float, normal: np.ndarray, step: float) -> np.ndarray:
    """Unit image direction [2] of -``normal`` at ``pixel`` seen at camera-space ``depth``; InputError where the
    camera looks along the normal (the floor's down is then no direction in the image)."""
    p = camera.unproject(pixel[None], depth)[0]
    uv, z = camera.project(np.stack([p, p - step * normal]))
    d = uv[1] - uv[0]
    if z.min() <= 0 or not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-3:
        raise InputError(None, "floor", "the input camera looks along the floor's normal: the plume's foot has no "
                                        "direction in its image (declare the source in scene.json)")
    return d / np.linalg.norm(d)


def _upright_plane_hit(camera: Camera, ray: np.ndarray, point: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Where ``ray`` from the camera meets the plane through ``point`` that contains ``up`` and faces the camera."""
    facing = camera.center - point
    facing = facing - (facing @ up) * up
    if np.linalg.norm(facing) < 1e-9:
        raise InputError(None, "floor", "the input camera looks along the floor's normal: the plume's foot has no "
                                        "depth from this view (declare the source in scene.json)")
    facing /= np.linalg.norm(facing)
    along = float(ray @ facing)
    if abs(along) < 1e-12:
        raise InputError(None, "floor", "the foot's ray runs along the volume's centre plane (declare the source)")
    return camera.center + float((point - camera.center) @ facing) / along * ray


def earliest_smoke(footage: np.ndarray, behind) -> tuple[int, np.ndarray]:
    """(frame, [H, W] mask) of the earliest frame of ``footage`` [T, H, W, C] with smoke, or (-1, None)."""
    for t, frame in enumerate(footage):
        mask = smoke_mask(frame, THRESHOLD, behind)
        if mask.sum() >= MIN_PIXELS:
            return t, mask
    return -1, None


def leaving(footage: np.ndarray, behind, t0: int, centre: np.ndarray, down: np.ndarray) -> tuple[str, np.ndarray]:
    """Which end the smoke of frame ``t0`` (its pixels' centroid ``centre``) leaves from, by how its centroid moves
    over the next :data:`LEAVING_FRAMES` frames: ``("top", -down)`` where it moves along ``down`` by more than a
    pixel and more than across, ``("side", d)`` where it moves across by more than a pixel and more than along
    (``d``: the image direction across that it moves away from), else ``("foot", down)``. The direction points
    from the smoke towards that end."""
    t1 = min(t0 + LEAVING_FRAMES, len(footage) - 1)
    later = smoke_mask(footage[t1], THRESHOLD, behind) if t1 > t0 else None
    if later is None or later.sum() < MIN_PIXELS:
        return "foot", down
    rows, cols = np.nonzero(later)
    moved = np.array([cols.mean(), rows.mean()]) + 0.5 - centre
    side = np.array([-down[1], down[0]])
    along, across = float(moved @ down), float(moved @ side)
    if along > 1.0 and along > abs(across):
        return "top", -down
    if abs(across) > 1.0 and abs(across) > abs(along):
        return "side", -np.sign(across) * side
    return "foot", down


def plume_foot(scene: Scene, view_name: str, camera: Camera, footage: np.ndarray, behind,
               video: Path) -> PlumeFoot:
    """The source of ``scene`` found in the input view ``view_name`` (module docstring).

    Args:
        camera: the view's camera at ``footage``'s size.
        footage: [T, H, W, C] the view's frames in [0, 1].
        behind: what the view sees behind the smoke ([C] or [H, W, C]; None: black).
        video: the view's video, for the error messages.
    """
    floor = scene.source_plane()
    plane = "the floor" if not scene.source_height else f"the plane {scene.source_height:g} above the floor"
    if floor is None:
        raise InputError(scene.root / SCENE_FILE, "floor", "neither a source, a floor nor a volume: nothing says where "
                                                           "the plume stands (declare one in scene.json)")
    t0, mask = earliest_smoke(footage, behind)
    if mask is None:
        raise InputError(video, None, f"shows no smoke (no frame has {MIN_PIXELS} pixels that differ from what is "
                                      f"behind the smoke by more than {THRESHOLD})")
    rows, cols = np.nonzero(mask)
    uv = np.stack([cols + 0.5, rows + 0.5], axis=1)
    normal = np.asarray(floor.normal)
    centre = uv.mean(axis=0)
    ref = np.asarray(scene.volume.center if scene.volume is not None else floor.point)
    depth = float(camera.project(ref[None])[1][0])
    if depth <= 0:
        raise InputError(video, None, "the scene's volume lies behind the input camera")
    down = down_in_image(camera, centre, depth, normal, 0.05 * depth)
    end, leave = leaving(footage, behind, t0, centre, down)  # towards the end the smoke leaves from
    across = np.array([-leave[1], leave[0]])
    along = uv @ leave
    s_foot = float(np.percentile(along, FOOT_PERCENTILE))
    extent = s_foot - float(along.min())
    band = uv[along >= s_foot - max(MIN_BAND_PIXELS, FOOT_BAND * extent)]
    lateral = band @ across
    pixel = s_foot * leave + float(np.median(lateral)) * across
    ray = camera.unproject(pixel[None], 1.0)[0] - camera.center
    ray /= np.linalg.norm(ray)
    grazing = float(np.degrees(np.arcsin(min(1.0, abs(float(ray @ normal))))))
    hit = floor.hit(camera.center, ray)
    where = f"the ray through the smoke's {end} (pixel {np.round(pixel, 1).tolist()} of frame {t0})"
    if grazing < MIN_GRAZING_DEG and scene.volume is not None:
        hit = _upright_plane_hit(camera, ray, ref, normal)  # the box decides
        hit = np.clip(hit, scene.volume.min, scene.volume.max)
        method = (f"input view: the {end} of the earliest smoke on the upright plane through the volume's centre "
                  f"facing the camera (its ray meets {plane} at {grazing:.1f} degrees, under {MIN_GRAZING_DEG:g}: "
                  "that plane does not fix the depth)")
        log.warning("synth: %s; declare the source in scene.json where the box's centre is not the plume's", method)
    elif hit is None:
        raise InputError(scene.root / SCENE_FILE, "floor", f"{where} misses {plane}; declare the source, the floor "
                                                           "or source_height in scene.json")
    else:
        method = f"input view: the {end} of the earliest smoke cast onto {plane}"
        if scene.volume is not None:
            lo, hi = np.asarray(scene.volume.min), np.asarray(scene.volume.max)
            tol = 1e-6 * float(np.max(hi - lo))
            if np.any(hit < lo - tol) or np.any(hit > hi + tol):
                box = f"{list(scene.volume.min)}..{list(scene.volume.max)}"
                raise InputError(scene.root / SCENE_FILE, "floor", f"{where} meets {plane} at "
                                 f"{np.round(hit, 4).tolist()}, outside the volume {box}: the smoke does not start "
                                 f"on {plane}; declare the source, the floor or source_height in scene.json")
    hit_depth = float(camera.project(hit[None])[1][0])
    half_width = max(1.0, float(np.sqrt(2.0) * np.std(lateral)))  # a uniform disk's rms, as the hull finder
    radius = half_width * hit_depth / float(camera.K[0, 0])
    if grazing >= MIN_GRAZING_DEG and end != "side":  # from the rim the end's ray meets to the centre
        away = ray - (ray @ normal) * normal
        above = float((camera.center - np.asarray(floor.point)) @ normal) > 0.0
        near = above != (end == "top")  # the camera looks at the end from the side the smoke leaves to
        hit = hit + (1.0 if near else -1.0) * radius * away / max(np.linalg.norm(away), 1e-12)
    source = Source(tuple(float(v) for v in hit), radius)
    record = {"method": method, "view": view_name, "frame": t0, "pixel": [round(float(v), 2) for v in pixel],
              "end": end, "grazing_deg": round(grazing, 2), "floor": floor.to_dict(),
              "floor_declared": scene.floor is not None, "source_height": scene.source_height,
              "center": list(source.center), "radius": radius}
    return PlumeFoot(source, record)
