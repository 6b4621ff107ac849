"""Scenes: a folder with ``scene.json`` (format ``fluidnexus-scene/1``, see docs/scene-format.md).

Two loaders, on purpose:

- :func:`load_scene` is the pipeline's loader (synth, refine, recon, predict, interact). Its :class:`Scene` holds
  the ``input`` and ``novel`` views only; ground-truth videos are not reachable from it.
- :func:`load_ground_truth` is for evaluation and comparison renders only.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fluidnexus.scenery.obstacles import parse_obstacles

from .atomic import read_json, write_json
from .camera import Camera
from .errors import InputError, require_finite, require_positive
from .world_frame import SourceFrame

FORMAT = "fluidnexus-scene/1"
SCENE_FILE = "scene.json"
ROLES = ("input", "novel")


@dataclass(frozen=True)
class Volume:
    """Axis-aligned box in world metres."""

    min: tuple[float, float, float]
    max: tuple[float, float, float]

    @property
    def center(self) -> np.ndarray:
        return 0.5 * (np.asarray(self.min) + np.asarray(self.max))

    @property
    def bottom_center(self) -> np.ndarray:
        c = self.center
        c[1] = self.min[1]
        return c

    def to_dict(self) -> dict:
        return {"min": list(self.min), "max": list(self.max)}


UP = (0.0, 1.0, 0.0)


def in_window(window: tuple[int, int | None], frame: int) -> bool:
    """Whether ``frame`` lies in the emission window [A, B) (B None: to the end)."""
    start, stop = window
    return start <= frame and (stop is None or frame < stop)


@dataclass(frozen=True)
class Source:
    """The smoke inflow: a disk of ``radius`` metres centred at ``center``, perpendicular to the unit vector
    ``direction`` (the way the smoke leaves it; default up), seeding gas at ``speed`` m/s along it during the
    frames ``window`` = [A, B) (B None: to the end; the whole window None: always)."""

    center: tuple[float, float, float]
    radius: float
    direction: tuple[float, float, float] = UP
    speed: float = 0.0
    window: tuple[int, int | None] | None = None

    def emits_at(self, frame: int) -> bool:
        """Whether the source is on at scene frame ``frame``."""
        return self.window is None or in_window(self.window, frame)

    @property
    def velocity(self) -> tuple[float, float, float]:
        """The inflow velocity [m/s]: ``speed`` along ``direction``."""
        return tuple(float(self.speed * d) for d in self.direction)

    def to_dict(self) -> dict:
        out = {"center": list(self.center), "radius": self.radius, "direction": list(self.direction),
               "speed": self.speed}
        if self.window is not None:
            out["window"] = list(self.window)
        return out

    @classmethod
    def from_dict(cls, data, path=None, fld: str = "source") -> "Source":
        """Parse and check a source record (scene.json, run.json); errors name ``path`` and ``fld``."""
        if not isinstance(data, dict) or "center" not in data or "radius" not in data:
            raise InputError(path, fld, "expected {center: [x, y, z], radius: r, direction?, speed?, window?}")
        direction = UP
        if data.get("direction") is not None:
            d = np.asarray(_triple(data["direction"], path, f"{fld}.direction"))
            norm = float(np.linalg.norm(d))
            if norm < 1e-9:
                raise InputError(path, f"{fld}.direction", f"has zero length ({d.tolist()}); give the way the smoke "
                                                           "leaves the source, e.g. [0, 1, 0] for up")
            direction = tuple(float(v) for v in d / norm)
        speed = float(require_finite(data.get("speed", 0.0), path, f"{fld}.speed"))
        if speed < 0:
            raise InputError(path, f"{fld}.speed", f"must be >= 0 m/s, got {speed}")
        return cls(_triple(data["center"], path, f"{fld}.center"),
                   require_positive(data["radius"], path, f"{fld}.radius"), direction, speed,
                   parse_window(data.get("window"), path, f"{fld}.window"))


@dataclass(frozen=True)
class Floor:
    """The plane the scene stands on: through ``point``, ``normal`` (unit) pointing up out of it. From one view the
    depth of the smoke is not observed; where no source is declared, the plume is taken to leave something standing
    on this floor, or ``Scene.source_height`` above it (``Scene.source_plane``, ``gen/plume_foot.py``). The static
    layer of a single view lays the floor it sees on this plane."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float] = UP

    def to_dict(self) -> dict:
        return {"point": list(self.point), "normal": list(self.normal)}

    @classmethod
    def from_dict(cls, data, path=None, fld: str = "floor") -> "Floor":
        """Parse and check a floor record: a non-zero normal (the plane may lie below the volume: a room's floor)."""
        if not isinstance(data, dict) or "point" not in data:
            raise InputError(path, fld, "expected {point: [x, y, z], normal?: [nx, ny, nz]} (normal default up)")
        n = np.asarray(_triple(data.get("normal", UP), path, f"{fld}.normal"))
        norm = float(np.linalg.norm(n))
        if norm < 1e-9:
            raise InputError(path, f"{fld}.normal", f"has zero length ({n.tolist()})")
        return cls(_triple(data["point"], path, f"{fld}.point"), tuple(float(v) for v in n / norm))

    def raised(self, height: float) -> "Floor":
        """The parallel plane ``height`` above this one (along the normal)."""
        return Floor(tuple(float(v) for v in np.asarray(self.point) + height * np.asarray(self.normal)), self.normal)

    def meets(self, volume: "Volume") -> bool:
        """Whether the plane passes through the box ``volume`` (its faces included)."""
        corners = np.array([[(volume.max if b else volume.min)[a] for a, b in enumerate(bits)]
                            for bits in np.ndindex(2, 2, 2)])
        side = (corners - np.asarray(self.point)) @ np.asarray(self.normal)
        return bool(side.min() <= 0.0 <= side.max())

    def reach(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """[N] the s > 0 at which each ray ``origin + s directions[i]`` meets the plane; inf where a ray runs
        parallel to it or points away from it."""
        n = np.asarray(self.normal, np.float64)
        along = np.asarray(directions, np.float64) @ n
        height = float(np.dot(np.asarray(self.point, np.float64) - origin, n))
        ok = np.abs(along) >= 1e-12
        s = np.full(along.shape, np.inf)
        s[ok] = height / along[ok]
        return np.where(s > 0, s, np.inf)

    def hit(self, origin: np.ndarray, direction: np.ndarray) -> np.ndarray | None:
        """Where the ray ``origin + s direction`` (s > 0) meets the plane, or None."""
        s = float(self.reach(origin, np.asarray(direction)[None])[0])
        return None if not np.isfinite(s) else origin + s * np.asarray(direction)


@dataclass(frozen=True)
class View:
    """A camera of the scene with its role and its video (relative to the scene folder, or None)."""

    name: str
    role: str
    camera: Camera
    video: str | None = None
    provenance: dict | None = None

    def to_dict(self) -> dict:
        out = {"name": self.name, "role": self.role, "camera": self.camera.to_dict(), "video": self.video}
        if self.provenance:
            out["provenance"] = self.provenance
        return out


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """A real held-out video with its camera; read only by eval and comparison renders.

    ``poses`` ([frame_count, 4, 4] world-to-camera, or None) makes it a moving camera: frame t is seen from
    ``camera_at(t)`` (``camera``'s intrinsics, pose t); ``camera`` holds pose 0.
    """

    name: str
    camera: Camera
    video: str
    poses: np.ndarray | None = None

    def camera_at(self, frame: int) -> Camera:
        """The camera that filmed scene frame ``frame``."""
        if self.poses is None:
            return self.camera
        return Camera(self.camera.width, self.camera.height, self.camera.K, self.poses[frame])

    def to_dict(self) -> dict:
        out = {"name": self.name, "camera": self.camera.to_dict(), "video": self.video}
        if self.poses is not None:
            out["poses"] = self.poses.tolist()
        return out


@dataclass(frozen=True)
class Background:
    """A view's clean plate (``fluidnexus background``): the backdrop image and its per-pixel confidence, both
    PNG files of the camera's size relative to the scene folder, with the source it came from."""

    view: str
    plate: str
    confidence: str
    source: str
    summary: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"plate": self.plate, "confidence": self.confidence, "source": self.source, "summary": self.summary}


@dataclass(frozen=True)
class Scene:
    """What the pipeline may see of a scene: fps, frame count, bounds, source and the input/novel views."""

    root: Path
    fps: float
    frame_count: int
    views: tuple[View, ...]
    volume: Volume | None = None
    source: Source | None = None
    extra: dict = field(default_factory=dict)
    backgrounds: dict[str, Background] = field(default_factory=dict)
    obstacles: tuple = ()  # scenery.obstacles.SphereBody / MeshBody, scene coordinates
    source_frame: SourceFrame | None = None  # None: the scene is its own source frame (world_frame.py)
    backdrop_color: tuple[float, float, float] | None = None  # a known backdrop colour (PINF frame_bkg_color)
    floor: Floor | None = None  # declared in scene.json; ``ground()`` also gives the default
    source_height: float = 0.0  # scene.json: how far above the floor the plume leaves (``source_plane()``)

    def ground(self) -> Floor | None:
        """The floor the plume stands on: the declared one, else the volume's bottom face (normal up), else None."""
        if self.floor is not None:
            return self.floor
        return None if self.volume is None else Floor(tuple(float(v) for v in self.volume.bottom_center))

    def source_plane(self) -> Floor | None:
        """The plane a single video's plume is taken to leave from where no source is declared: the floor, raised
        by ``source_height`` (a nozzle on a stand)."""
        floor = self.ground()
        return None if floor is None else floor.raised(self.source_height)

    def view(self, name: str) -> View:
        for v in self.views:
            if v.name == name:
                return v
        raise InputError(self.root / SCENE_FILE, "views", f"unknown view {name!r}; known: {self.view_names()}")

    def view_names(self) -> list[str]:
        return [v.name for v in self.views]

    def with_role(self, role: str) -> tuple[View, ...]:
        return tuple(v for v in self.views if v.role == role)

    def usable_views(self) -> tuple[View, ...]:
        """Views with footage: every ``input`` view plus ``novel`` views that have a video."""
        return tuple(v for v in self.views if v.video is not None)

    def video_path(self, view: View) -> Path:
        if view.video is None:
            raise InputError(self.root / SCENE_FILE, f"views[{view.name}].video", "this view has no video")
        return self.root / view.video


# ---- reading --------------------------------------------------------------------------------------------
def _read_json(path: Path) -> dict:
    scene_file = path / SCENE_FILE if path.is_dir() else path
    data = read_json(scene_file)
    if data.get("format") != FORMAT:
        raise InputError(scene_file, "format", f"unknown format tag {data.get('format')!r}; expected {FORMAT!r}")
    return data


def _scene_file(path: str | Path) -> tuple[Path, Path]:
    path = Path(path)
    scene_file = path / SCENE_FILE if path.is_dir() or path.suffix != ".json" else path
    return scene_file.parent, scene_file


def _triple(value, path, fld: str) -> tuple[float, float, float]:
    arr = require_finite(value, path, fld)
    if arr.shape != (3,):
        raise InputError(path, fld, f"expected 3 numbers, got {value!r}")
    return tuple(float(x) for x in arr)


def _parse_volume(data, path) -> Volume | None:
    if data is None:
        return None
    if not isinstance(data, dict) or "min" not in data or "max" not in data:
        raise InputError(path, "volume", "expected {min: [x, y, z], max: [x, y, z]}")
    lo, hi = _triple(data["min"], path, "volume.min"), _triple(data["max"], path, "volume.max")
    if not all(a < b for a, b in zip(lo, hi)):
        raise InputError(path, "volume", f"min {lo} must be below max {hi} on every axis")
    return Volume(lo, hi)


def parse_window(value, path, fld: str) -> tuple[int, int | None] | None:
    """An emission window [A, B] of frame indices (B null: to the end), or None."""
    if value is None:
        return None
    ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(
        v is None or (isinstance(v, int) and not isinstance(v, bool)) for v in value) and value[0] is not None
    if not ok or value[0] < 0 or (value[1] is not None and value[1] <= value[0]):
        raise InputError(path, fld, f"expected frames [A, B] with 0 <= A < B (B null: to the end), got {value!r}")
    return int(value[0]), None if value[1] is None else int(value[1])


def _parse_source(data, path) -> Source | None:
    return None if data is None else Source.from_dict(data, path)


def _parse_views(items, path, key: str) -> list[dict]:
    if not isinstance(items, list):
        raise InputError(path, key, "expected a list")
    names = set()
    for i, item in enumerate(items):
        if not isinstance(item, dict) or not isinstance(item.get("name"), str) or not item["name"]:
            raise InputError(path, f"{key}[{i}].name", "missing or not a string")
        if item["name"] in names:
            raise InputError(path, f"{key}[{i}].name", f"duplicate view name {item['name']!r}")
        names.add(item["name"])
    return items


BACKGROUND_SOURCES = ("plate", "clean-frames", "color", "temporal")


def _parse_backgrounds(data, views: list[View], root: Path, path: Path, check_files: bool) -> dict[str, Background]:
    """The ``backgrounds`` record: plates of known views; with ``check_files`` every PNG exists and has its
    camera's size."""
    if data is None:
        return {}
    if not isinstance(data, dict) or not isinstance(data.get("views", {}), dict):
        raise InputError(path, "backgrounds", "expected {views: {NAME: {plate, confidence, source}}}")
    cameras = {v.name: v.camera for v in views}
    out = {}
    for name, item in data.get("views", {}).items():
        fld = f"backgrounds.views.{name}"
        if name not in cameras:
            raise InputError(path, fld, f"a plate for unknown view {name!r}; known: {sorted(cameras)}")
        if not isinstance(item, dict) or not all(isinstance(item.get(k), str) for k in ("plate", "confidence")):
            raise InputError(path, fld, "expected {plate: FILE, confidence: FILE, source: ...}")
        if item.get("source") not in BACKGROUND_SOURCES:
            raise InputError(path, f"{fld}.source",
                             f"must be one of {BACKGROUND_SOURCES}, got {item.get('source')!r}")
        cam = cameras[name]
        for key in ("plate", "confidence") if check_files else ():
            size = png_size(root / item[key])
            if size != (cam.width, cam.height):
                raise InputError(root / item[key], f"{fld}.{key}", f"is {size[0]}x{size[1]}, but view {name!r}'s "
                                                                   f"camera is {cam.width}x{cam.height}")
        out[name] = Background(name, item["plate"], item["confidence"], item["source"], item.get("summary", {}))
    return out


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) from a PNG file's header, without decoding it."""
    try:
        head = Path(path).read_bytes()[:24]
    except OSError:
        raise InputError(path, None, "file not found or unreadable") from None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n":
        raise InputError(path, None, "not a PNG file")
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def _parse_frame_and_backdrop(data: dict, path: Path) -> dict:
    """The ``source_frame`` and ``backdrop_color`` records as Scene keyword arguments."""
    frame = data.get("source_frame")
    color = data.get("backdrop_color")
    if color is not None:
        color = _triple(color, path, "backdrop_color")
        if not all(0.0 <= c <= 1.0 for c in color):
            raise InputError(path, "backdrop_color", f"expected 3 values in [0, 1], got {list(color)}")
    return {"source_frame": None if frame is None else SourceFrame.from_dict(frame, path),
            "backdrop_color": color}


def _parse_poses(value, camera: Camera, frame_count, path: Path, fld: str) -> np.ndarray | None:
    """A moving camera's per-frame world-to-camera matrices: one per frame, pose 0 equal to ``camera``'s."""
    if value is None:
        return None
    poses = require_finite(value, path, f"{fld}.poses")
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or poses.shape[0] != frame_count:
        raise InputError(path, f"{fld}.poses", f"expected {frame_count} (frame_count) 4x4 world-to-camera "
                                               f"matrices, got shape {poses.shape}")
    for t, w2c in enumerate(poses):
        try:
            Camera(camera.width, camera.height, camera.K, w2c)
        except InputError as err:
            raise err.at(path, f"{fld}.poses[{t}]") from None
    if not np.allclose(poses[0], camera.w2c, rtol=0, atol=1e-9 * max(1.0, np.abs(camera.w2c).max())):
        raise InputError(path, f"{fld}.poses[0]", "must equal camera.world_to_camera (the pose at frame 0)")
    return poses


def load_scene(path: str | Path, check_videos: bool = True) -> Scene:
    """Load the pipeline's view of a scene (no ground truth).

    Args:
        path: the scene folder or its scene.json.
        check_videos: probe every video and require the scene's frame count and one shared resolution that
            matches the cameras; check that every background plate exists and has its camera's size.
    Raises:
        InputError naming scene.json (or a video) and the field.
    """
    root, scene_file = _scene_file(path)
    data = _read_json(scene_file)
    fps = require_positive(data.get("fps", 0), scene_file, "fps")
    frame_count = data.get("frame_count")
    if isinstance(frame_count, bool) or not isinstance(frame_count, int) or frame_count <= 0:
        raise InputError(scene_file, "frame_count", f"must be an integer > 0, got {frame_count!r}")
    views = []
    for i, item in enumerate(_parse_views(data.get("views"), scene_file, "views")):
        role = item.get("role")
        if role not in ROLES:
            raise InputError(scene_file, f"views[{i}].role", f"must be one of {ROLES}, got {role!r}")
        video = item.get("video")
        if video is not None and not isinstance(video, str):
            raise InputError(scene_file, f"views[{i}].video", "must be a path string or null")
        camera = Camera.from_dict(item.get("camera"), scene_file, f"views[{i}].camera")
        if "poses" in item:
            raise InputError(scene_file, f"views[{i}].poses",
                             f"view {item['name']!r} moves during the video (one camera pose per frame); synth, "
                             "refine, recon, predict and interact need cameras that stand still: make a moving "
                             "camera ground truth (eval and render --compare follow it frame by frame)")
        views.append(View(item["name"], role, camera, video, item.get("provenance")))
    if not views:
        raise InputError(scene_file, "views", "the scene has no views")
    volume = _parse_volume(data.get("volume"), scene_file)
    floor = None if data.get("floor") is None else Floor.from_dict(data["floor"], scene_file)
    source_height = data.get("source_height", 0.0)
    if isinstance(source_height, bool) or require_finite(source_height, scene_file, "source_height").ndim != 0:
        raise InputError(scene_file, "source_height", f"expected a number (scene units), got {source_height!r}")
    source_height = float(source_height)
    scene = Scene(root, fps, frame_count, tuple(views), volume, _parse_source(data.get("source"), scene_file),
                  data.get("extra", {}), _parse_backgrounds(data.get("backgrounds"), views, root, scene_file,
                                                            check_videos),
                  **_parse_frame_and_backdrop(data, scene_file),
                  obstacles=parse_obstacles(data.get("obstacles"), scene_file, volume, root), floor=floor,
                  source_height=source_height)
    plane = scene.source_plane()
    if volume is not None and plane is not None and not plane.meets(volume):
        raise InputError(scene_file, "source_height" if source_height else "floor",
                         f"the plane the plume leaves from (through {[round(v, 6) for v in plane.point]}, normal "
                         f"{list(plane.normal)}: the floor raised by source_height {source_height:g}) lies outside "
                         f"the volume {list(volume.min)}..{list(volume.max)}")
    if check_videos:
        check_media(root, scene_file, frame_count,
                    [(f"views[{i}].video", v.video, v.camera) for i, v in enumerate(views) if v.video])
    return scene


def load_ground_truth(path: str | Path, check_videos: bool = True) -> tuple[GroundTruth, ...]:
    """The held-out real videos of a scene (for ``eval`` and ``render --compare`` only)."""
    root, scene_file = _scene_file(path)
    data = _read_json(scene_file)
    out = []
    for i, item in enumerate(_parse_views(data.get("ground_truth", []), scene_file, "ground_truth")):
        if not isinstance(item.get("video"), str):
            raise InputError(scene_file, f"ground_truth[{i}].video", "missing: a ground-truth entry needs a video")
        camera = Camera.from_dict(item.get("camera"), scene_file, f"ground_truth[{i}].camera")
        poses = _parse_poses(item.get("poses"), camera, data.get("frame_count"), scene_file, f"ground_truth[{i}]")
        out.append(GroundTruth(item["name"], camera, item["video"], poses))
    if check_videos and out:
        check_media(root, scene_file, int(data["frame_count"]),
                    [(f"ground_truth[{i}].video", g.video, g.camera) for i, g in enumerate(out)])
    return tuple(out)


def _fits_camera(width: int, height: int, camera: Camera) -> bool:
    """A video fits its camera at the camera's size or uniformly scaled (``Camera.scaled``), as ``synth`` and
    ``refine`` write their videos at the working resolution."""
    if (width, height) == (camera.width, camera.height):
        return True
    sizes = (camera.scaled(f) for f in (width / camera.width, height / camera.height))
    return any((c.width, c.height) == (width, height) for c in sizes)


def check_media(root: Path, scene_file: Path, frame_count: int, entries) -> None:
    """Require every video to exist, decode, have ``frame_count`` frames and fit its camera (its size, or that
    size uniformly scaled: ``_fits_camera``), and every camera to share one resolution. ``entries`` is a list
    of ``(field, relative_path, camera)``."""
    from .video import probe_video

    first = None
    for fld, rel, camera in entries:
        video = root / rel
        if not video.exists():
            raise InputError(video, None, f"file not found (referenced by {scene_file} field {fld})")
        info = probe_video(video)
        if info.frame_count != frame_count:
            raise InputError(video, "frame_count",
                             f"has {info.frame_count} frames, but {scene_file.name} says frame_count={frame_count}")
        if not _fits_camera(info.width, info.height, camera):
            raise InputError(video, "resolution",
                             f"is {info.width}x{info.height}, but its camera ({fld}) is "
                             f"{camera.width}x{camera.height}")
        if first is None:
            first = (rel, camera.width, camera.height)
        elif (camera.width, camera.height) != first[1:]:
            raise InputError(video, "resolution",
                             f"is {camera.width}x{camera.height}, but {first[0]} is {first[1]}x{first[2]}; "
                             "all videos of a scene share one resolution")


# ---- writing --------------------------------------------------------------------------------------------
def scene_dict(scene: Scene, ground_truth: tuple[GroundTruth, ...] = ()) -> dict:
    """The JSON document of a scene (with its ground truth)."""
    out = {"format": FORMAT, "fps": scene.fps, "frame_count": scene.frame_count}
    if scene.volume is not None:
        out["volume"] = scene.volume.to_dict()
    if scene.source is not None:
        out["source"] = scene.source.to_dict()
    out["views"] = [v.to_dict() for v in scene.views]
    out["ground_truth"] = [g.to_dict() for g in ground_truth]
    if scene.extra:
        out["extra"] = scene.extra
    if scene.backgrounds:
        out["backgrounds"] = {"views": {name: b.to_dict() for name, b in scene.backgrounds.items()}}
    if scene.obstacles:
        out["obstacles"] = [o.to_dict() for o in scene.obstacles]
    if scene.source_frame is not None:
        out["source_frame"] = scene.source_frame.to_dict()
    if scene.backdrop_color is not None:
        out["backdrop_color"] = list(scene.backdrop_color)
    if scene.floor is not None:
        out["floor"] = scene.floor.to_dict()
    if scene.source_height:
        out["source_height"] = scene.source_height
    return out


def save_scene(scene: Scene, ground_truth: tuple[GroundTruth, ...] = (), root: str | Path | None = None) -> Path:
    """Write ``scene.json`` atomically into ``root`` (default ``scene.root``); return its path."""
    dest = Path(root if root is not None else scene.root) / SCENE_FILE
    write_json(dest, scene_dict(scene, ground_truth))
    return dest


def save_views(scene_dir: str | Path, views: tuple[View, ...]) -> Path:
    """Rewrite the views of an existing scene (e.g. after ``synth`` gave novel views a video), keeping its
    ground truth and every other field; atomic."""
    _, scene_file = _scene_file(scene_dir)
    data = _read_json(scene_file)
    data["views"] = [v.to_dict() for v in views]
    write_json(scene_file, data)
    return scene_file
