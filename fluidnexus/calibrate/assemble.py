"""Turn imported cameras plus role choices into a scene folder (shared by every calibrate mode)."""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_dir
from ..camera import Camera
from ..errors import InputError
from ..scene import (Floor, GroundTruth, Scene, Source, View, Volume, load_ground_truth, load_scene,
                     save_scene)
from ..scenery.obstacles import place_obstacles
from ..world_frame import SourceFrame


@dataclass(frozen=True, eq=False)
class Recording:
    """A camera found in a calibration source, with its footage (a video file, an image or a frame folder).

    ``poses`` ([frames, 4, 4] world-to-camera, or None) marks a camera that moves: ``camera`` is its pose at frame 0.
    """

    name: str
    camera: Camera
    media: Path | None
    poses: np.ndarray | None = None


@dataclass(frozen=True)
class Roles:
    """View names chosen on the command line for each role."""

    input: tuple[str, ...]
    novel: tuple[str, ...] = ()
    ground_truth: tuple[str, ...] = ()

    @classmethod
    def parse(cls, input: str | None, novel: str | None = None, ground_truth: str | None = None) -> "Roles":
        def split(text):
            return tuple(n.strip() for n in text.split(",") if n.strip()) if text else ()

        return cls(split(input), split(novel), split(ground_truth))


# View roles of the embedded samples' protocols (``calibrate --sample NAME --protocol P``)
PROTOCOLS = {
    # the paper's single-video protocol: the middle camera in, the four others synthesised and scored
    "single-view": Roles(("train02",), ("train00", "train01", "train03", "train04"),
                         ("train00", "train01", "train03", "train04")),
    # four real input views, the middle camera held out
    "four-view": Roles(("train00", "train01", "train03", "train04"), (), ("train02",)),
}


def assign_roles(recordings: dict[str, Recording], roles: Roles, source_file: Path
                 ) -> tuple[list[tuple[View, Path | None]], list[tuple[GroundTruth, Path]]]:
    """Pick the views for each role; errors name ``source_file`` and the option."""
    for option, names in (("--input", roles.input), ("--novel", roles.novel),
                          ("--ground-truth", roles.ground_truth)):
        for name in names:
            if name not in recordings:
                raise InputError(source_file, option, f"unknown view {name!r}; known: {sorted(recordings)}")
    if not roles.input:
        raise InputError(source_file, "--input", "name at least one input view")
    both = set(roles.input) & set(roles.novel)
    if both:
        raise InputError(source_file, "--novel", f"{sorted(both)} cannot be both input and novel")
    leak = set(roles.input) & set(roles.ground_truth)
    if leak:
        raise InputError(source_file, "--ground-truth", f"{sorted(leak)} cannot be both input and ground truth")
    for option, names in (("--input", roles.input), ("--novel", roles.novel)):
        moving = [n for n in names if recordings[n].poses is not None]
        if moving:
            raise InputError(source_file, option,
                             f"{moving} move during the video (one camera pose per frame); synth, refine and recon "
                             "need cameras that stand still: name a moving camera with --ground-truth instead")
    views = []
    for name in roles.input:
        rec = recordings[name]
        if rec.media is None:
            raise InputError(source_file, "--input", f"view {name!r} has no footage")
        views.append((View(name, "input", rec.camera, None), rec.media))
    views += [(View(name, "novel", recordings[name].camera, None), None) for name in roles.novel]
    gts = []
    for name in roles.ground_truth:
        rec = recordings[name]
        if rec.media is None:
            raise InputError(source_file, "--ground-truth", f"view {name!r} has no footage")
        gts.append((GroundTruth(name, rec.camera, "", rec.poses), rec.media))
    return views, gts


def _place(media: Path, folder: Path, name: str, link: bool) -> str:
    """Copy (or symlink) ``media`` into ``folder`` as ``name`` + suffix; return the path relative to the scene."""
    if not media.exists():
        raise InputError(media, None, "file not found")
    dest = folder / (name + media.suffix.lower())
    if link:
        os.symlink(media.resolve(), dest)
    elif media.is_dir():
        shutil.copytree(media, dest)
    else:
        shutil.copy2(media, dest)
    return f"{folder.name}/{dest.name}"


def write_scene(out: Path, fps: float, frame_count: int, views, ground_truth, volume: Volume | None,
                source: Source | None, extra: dict | None = None, link: bool = False,
                source_frame: SourceFrame | None = None, backdrop_color=None, obstacles=(),
                floor: Floor | None = None) -> Scene:
    """Write a complete, validated scene folder at ``out`` atomically and return it (loaded back).

    Args:
        views: ``[(View, media or None)]``; a view's media is placed under ``videos/``.
        ground_truth: ``[(GroundTruth, media)]``, placed under ``ground_truth/``.
        link: symlink the media instead of copying it.
        source_frame, backdrop_color: of an imported scene (see :class:`~fluidnexus.scene.Scene`).
        obstacles: ``calibrate --obstacle`` values in the imported file's frame (``obstacles.parse_option``);
            converted by ``source_frame``, meshes written under ``obstacles/``.
        floor: the plane the plume stands on, where the calibration knows it (None: the volume's bottom face).
    """
    out = Path(out)
    with atomic_dir(out) as tmp:
        (tmp / "videos").mkdir()
        placed = [View(v.name, v.role, v.camera, _place(m, tmp / "videos", v.name, link) if m else None,
                       v.provenance) for v, m in views]
        gts = ()
        if ground_truth:
            (tmp / "ground_truth").mkdir()
            gts = tuple(GroundTruth(g.name, g.camera, _place(m, tmp / "ground_truth", g.name, link), g.poses)
                        for g, m in ground_truth)
        bodies = place_obstacles(obstacles, tmp, source_frame, volume)
        save_scene(Scene(tmp, float(fps), int(frame_count), tuple(placed), volume, source, extra or {},
                         source_frame=source_frame, backdrop_color=backdrop_color, obstacles=bodies, floor=floor),
                   gts, tmp)
        try:
            load_scene(tmp)
            load_ground_truth(tmp)
        except InputError as err:  # report the user's file, not our temporary copy of it
            raise InputError(_original(err.path, tmp, views, ground_truth), err.field, err.message) from None
    return load_scene(out, check_videos=False)


def _original(path: str | None, tmp: Path, views, ground_truth) -> str | None:
    """Map a path inside the temporary scene back to the media file the user gave."""
    if path is None:
        return None
    p = Path(path)
    for item, media in list(views) + list(ground_truth):
        if media is not None and p.stem == item.name and p.parent.parent == tmp:
            return str(media)
    return path
