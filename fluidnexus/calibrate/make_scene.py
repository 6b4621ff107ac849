"""``fluidnexus calibrate``'s work: a scene folder from camera data in one of six ways (docs/calibration.md):
a PINF/HyFluid info.json, a NeRF transforms.json, a COLMAP model, images or videos (pycolmap SfM), a single video
(an arc rig around it), or an embedded sample."""
from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from ..atomic import write_json
from ..errors import InputError, require_positive
from ..samples import sample_path
from ..scene import SCENE_FILE, Scene, Source, View, load_ground_truth, load_scene
from ..scenery.obstacles import parse_option, parse_sphere
from ..video import VIDEO_SUFFIXES, probe_video
from ..world_frame import SourceFrame
from .arc import arc_rig
from .assemble import PROTOCOLS, Recording, Roles, assign_roles, write_scene
from .colmap import media_by_stem, read_colmap
from .nerf import read_nerf
from .pinf import pinf_dict, read_pinf, source_at_volume_foot

log = logging.getLogger("fluidnexus")

MODES = ("from_pinf", "from_nerf", "from_colmap", "images", "video", "sample")
IMPORTS = ("from_pinf", "from_nerf", "from_colmap")  # modes that read a world in the file's own unit


def _parse_scale_distance(text: str | None):
    if text is None:
        return None
    parts = text.split(",")
    try:
        a, b, metres = parts[0].strip(), parts[1].strip(), float(parts[2])
        assert len(parts) == 3 and a and b and metres > 0
    except (AssertionError, IndexError, ValueError):
        raise InputError(None, "--scale-distance", f"expected NAME_A,NAME_B,METRES with METRES > 0, got {text!r}")
    return a, b, metres


def make_scene(out: Path, paths: tuple[Path, ...], opts: dict, overwrite: bool = False,
               to_pinf: Path | None = None) -> Scene:
    """Write the scene folder ``out`` from the source ``opts`` names (``calibrate``'s options by their parameter
    names: exactly one of ``from_pinf``, ``from_nerf``, ``from_colmap``, ``images`` with ``paths``, ``video``,
    ``sample``); with ``to_pinf`` also a PINF info.json of it. Bad input is an InputError before anything is
    written."""
    opts = dict(opts)
    if bool(paths) != opts["images"]:
        raise InputError(None, "--images", "list the images or videos after --images (and only there)")
    opts["paths"] = paths
    opts["obstacles"] = tuple(parse_option(text) for text in opts["obstacles"])
    chosen = [m for m in MODES if opts[m]]
    if len(chosen) != 1:
        raise InputError(None, "calibrate", "give exactly one of --from-pinf, --from-nerf, --from-colmap, "
                                            f"--images, --video, --sample (got {len(chosen)})")
    if opts["plate"] is not None and chosen[0] != "video":
        raise InputError(None, "--plate", "applies to --video only; give the plates of other scenes with "
                                          "'fluidnexus background SCENE --plate NAME=FILE'")
    for option in ("tilt_deg", "horizon_row"):
        if opts[option] is not None and chosen[0] != "video":
            raise InputError(None, "--" + option.replace("_", "-"), "applies to --video only (the phone's tilt)")
    if opts["source"] is not None and chosen[0] not in ("from_pinf", "sample"):
        raise InputError(None, "--source", "applies to --from-pinf and --sample (other scenes: scene.json source)")
    if opts["metres_per_unit"] is not None:
        if chosen[0] not in IMPORTS:
            raise InputError(None, "--metres-per-unit", "applies to imported files only (--from-pinf, --from-nerf, "
                                                        "--from-colmap)")
        require_positive(opts["metres_per_unit"], None, "--metres-per-unit")
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise InputError(out, None, "already exists and is not empty (use --overwrite to replace it)")
    scene = {"from_pinf": _from_pinf, "from_nerf": _from_nerf, "from_colmap": _from_colmap,
             "images": _from_images, "video": _from_video, "sample": _from_sample}[chosen[0]](out, opts)
    _report(scene)
    if to_pinf is not None:
        write_pinf(scene.root, to_pinf)
        log.info("PINF info.json: %s", to_pinf)
    return scene


def _roles(opts) -> Roles:
    return Roles.parse(opts["input_names"], opts["novel_names"], opts["gt_names"])


def declared_source(text: str | None, frame: SourceFrame, volume) -> Source | None:
    """``--source CX,CY,CZ,R`` in the imported file's frame and unit, in the scene (None without it); InputError
    naming ``--source`` for anything but four finite numbers with R > 0 or a disk centre outside the volume."""
    if text is None:
        return None
    ball = parse_sphere(text, "--source", "CX,CY,CZ,R (the inflow disk's centre and radius)")
    center = frame.to_scene(np.asarray(ball.center))
    if volume is not None and (np.any(center < np.asarray(volume.min)) or np.any(center > np.asarray(volume.max))):
        raise InputError(None, "--source", f"the centre {np.round(center, 4).tolist()} (in the scene, metres) lies "
                                           f"outside the volume {list(volume.min)}..{list(volume.max)}")
    return Source(tuple(float(v) for v in center), float(frame.length_to_scene(ball.radius)))


def _from_pinf(out: Path, opts, info: Path | None = None, roles: Roles | None = None, sample: bool = False) -> Scene:
    """A PINF capture declares no inflow: the scene gets the user's ``--source`` or none (synth and recon find it in
    the footage). The embedded samples' inflow is known: the foot of their volume (``source_at_volume_foot``)."""
    info = info or opts["from_pinf"]
    cap = read_pinf(info, opts["metres_per_unit"] or 1.0)
    views, gts = assign_roles(cap.recordings, roles or _roles(opts), info)
    source = declared_source(opts["source"], cap.frame, cap.volume)
    if sample and source is None:
        source = source_at_volume_foot(cap.volume, opts["source_radius"])
    return write_scene(out, cap.fps, cap.frame_count, views, gts, cap.volume, source,
                       {"pinf": cap.kept, "imported_from": str(info)}, link=opts["link"],
                       source_frame=_recorded(cap.frame), backdrop_color=cap.backdrop_color,
                       obstacles=opts["obstacles"])


def _import_frame(opts) -> SourceFrame:
    """The world of a NeRF or COLMAP file: its axes as they are, its unit ``--metres-per-unit`` metres."""
    return SourceFrame.for_import("Y", opts["metres_per_unit"] or 1.0)


def _recorded(frame: SourceFrame) -> SourceFrame | None:
    """What scene.json records: nothing when the file's world already is the scene's."""
    return None if frame.is_identity else frame


def _in_scene(recordings: dict[str, Recording], frame: SourceFrame) -> dict[str, Recording]:
    return {n: Recording(n, frame.camera_to_scene(r.camera), r.media) for n, r in recordings.items()}


def _from_sample(out: Path, opts) -> Scene:
    roles = _roles(opts) if opts["input_names"] else PROTOCOLS[opts["protocol"]]
    return _from_pinf(out, opts, sample_path(opts["sample"]) / "info.json", roles, sample=True)


def _timing(source: Path, recordings, fps: float | None) -> tuple[float, int]:
    """fps and frame count of the first recording with footage."""
    for rec in recordings:
        if rec.media is not None:
            info = probe_video(rec.media)
            rate = fps or info.fps
            if not rate:
                raise InputError(rec.media, "fps", "the footage does not state a frame rate; pass --fps")
            return float(rate), info.frame_count
    raise InputError(source, None, "no camera has footage")


def _write_recordings(out: Path, source: Path, recordings: dict[str, Recording], opts, default_roles: Roles,
                      volume=None, source_disk=None, extra=None, fps=None, source_frame=None) -> Scene:
    roles = _roles(opts) if opts["input_names"] else default_roles
    views, gts = assign_roles(recordings, roles, source)
    rate, count = _timing(source, [recordings[n] for n in roles.input], fps or opts["fps"])
    return write_scene(out, rate, count, views, gts, volume, source_disk, extra, link=opts["link"],
                       source_frame=source_frame, obstacles=opts["obstacles"])


def _from_nerf(out: Path, opts) -> Scene:
    recordings, fps = read_nerf(opts["from_nerf"])
    frame = _import_frame(opts)
    default = Roles(tuple(n for n, r in recordings.items() if r.media is not None))
    return _write_recordings(out, opts["from_nerf"], _in_scene(recordings, frame), opts, default, fps=fps,
                             extra={"imported_from": str(opts["from_nerf"])}, source_frame=_recorded(frame))


def _from_colmap(out: Path, opts) -> Scene:
    recordings = read_colmap(opts["from_colmap"], opts["media"])
    frame = _import_frame(opts)
    default = Roles(tuple(n for n, r in recordings.items() if r.media is not None))
    return _write_recordings(out, opts["from_colmap"], _in_scene(recordings, frame), opts, default,
                             extra={"imported_from": str(opts["from_colmap"])}, source_frame=_recorded(frame))


def _from_images(out: Path, opts) -> Scene:
    from fluidnexus.calibrate.sfm import calibrate_images

    inputs = list(opts["paths"])
    with tempfile.TemporaryDirectory(prefix="fluidnexus-sfm-") as work:
        result = calibrate_images(inputs, Path(work), _parse_scale_distance(opts["scale_distance"]))
    log.info("structure from motion: %d cameras, %d points, mean reprojection error %.3f px",
             len(result.cameras), result.num_points, result.mean_reprojection_error_px)
    # footage: --media by stem, else a rig camera's own video; a sweep's frames and still images have none
    by_stem = media_by_stem(opts["media"]) if opts["media"] else {}
    own = {p.stem: p for p in inputs if p.suffix.lower() in VIDEO_SUFFIXES} if len(inputs) > 1 else {}
    recordings = {n: Recording(n, cam, by_stem.get(n, own.get(n))) for n, cam in result.cameras.items()}
    footage = tuple(n for n, r in recordings.items() if r.media is not None)
    if not footage and not opts["input_names"]:
        raise InputError(opts["media"] or inputs[0], "--media",
                         "the cameras are calibrated but none has footage: pass --media DIR holding one video "
                         "per camera, named like its image (e.g. cam0.mp4 for cam0.png)")
    default = Roles(footage, tuple(n for n in recordings if n not in footage))
    extra = {"calibration": {"method": "pycolmap-sfm", "mean_reprojection_error_px":
                             result.mean_reprojection_error_px, "num_points": result.num_points,
                             "metric": result.metric, "up": result.up_axis_source}}
    return _write_recordings(out, inputs[0], recordings, opts, default, extra=extra)


def _from_video(out: Path, opts) -> Scene:
    video = opts["video"]
    if opts["fov_deg"] is None:
        raise InputError(None, "--fov-deg", "required with --video (the camera's horizontal field of view)")
    info = probe_video(video)
    plate = None
    if opts["plate"] is not None:  # checked before anything is written
        from fluidnexus.scenery.plate_estimate import given_plate
        from fluidnexus.scenery.plate_store import read_plate_file

        image = read_plate_file(opts["plate"], info.width, info.height, "--plate", f"the video {video}")
        plate = given_plate(opts["plate"], image, video, info.frame_count)
    rig = arc_rig(info.width, info.height, opts["fov_deg"], opts["views"], opts["arc_deg"], opts["distance"],
                  opts["camera_height"], opts["source_radius"], input_name=video.stem, tilt_deg=opts["tilt_deg"],
                  horizon_row=opts["horizon_row"])
    views = [(View(video.stem, "input", rig.input_camera), video)]
    views += [(View(n, "novel", cam, provenance={"rig": "arc", "azimuth_deg": rig.azimuths_deg[n]}), None)
              for n, cam in rig.novel.items()]
    rate = opts["fps"] or info.fps
    if not rate:
        raise InputError(video, "fps", "the footage does not state a frame rate; pass --fps")
    extra = {"rig": {"kind": "arc", "fov_deg": opts["fov_deg"], "views": opts["views"], "arc_deg": opts["arc_deg"],
                     "distance": rig.distance}}
    if rig.floor is not None:
        extra["rig"].update(camera_height=opts["camera_height"], tilt_deg=rig.tilt_deg,
                            horizon_row=opts["horizon_row"])
    scene = write_scene(out, rate, info.frame_count, views, [], rig.volume, rig.source, extra, link=opts["link"],
                        obstacles=opts["obstacles"], floor=rig.floor)
    if plate is None:
        log.info("no --plate: 'fluidnexus background %s' estimates the clean plate from the footage", out)
        return scene
    from fluidnexus.scenery.plate_sheet import contact_sheet
    from fluidnexus.scenery.plate_store import write_backgrounds

    estimate, middle = plate
    records = write_backgrounds(scene, {video.stem: estimate}, contact_sheet([(video.stem, middle, estimate)]))
    log.info("plate of %s: %s", video.stem, scene.root / records[video.stem].plate)
    return load_scene(out, check_videos=False)


def write_pinf(scene_dir: Path, dest: Path) -> None:
    """Write a scene as a PINF info.json whose video paths are relative to ``dest``'s folder."""
    scene, gts = load_scene(scene_dir, check_videos=False), load_ground_truth(scene_dir, check_videos=False)
    data = pinf_dict(scene, gts)
    rel = os.path.relpath(scene.root.resolve(), dest.resolve().parent)
    for entry in data["train_videos"] + data["test_videos"]:
        entry["file_name"] = str(Path(rel) / entry["file_name"]) if rel != "." else entry["file_name"]
    write_json(dest, data)


def _report(scene: Scene) -> None:
    gts = load_ground_truth(scene.root, check_videos=False)
    log.info("scene: %s (%d frames at %g fps)", scene.root / SCENE_FILE, scene.frame_count, scene.fps)
    for v in scene.views:
        log.info("  %-8s %-12s %dx%d  %s", v.role, v.name, v.camera.width, v.camera.height, v.video or "-")
    for g in gts:
        log.info("  %-8s %-12s %dx%d  %s", "truth", g.name, g.camera.width, g.camera.height, g.video)
