"""What the viewer reads from a run folder, loaded lazily: frame states on demand (a small cache), the cameras of
its scene with their roles, the videos' frames as thumbnails (decoded in the background), the obstacles (declared,
found by recon, added by ``interact``) and the static layer."""
from __future__ import annotations

import logging
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..runs import Run, open_run
from ..scene import load_ground_truth
from ..state import FrameState

log = logging.getLogger("fluidnexus")

STATIC_LAYER_FILE = "static.npz"  # RUN/static.npz, written by recon for a scene with clean plates
THUMBNAIL_WIDTH = 192  # pixels: a video frame shown on its camera's frustum


@dataclass(frozen=True, eq=False)
class CameraMark:
    """A camera to draw: ``role`` is ``input``, ``synthesised`` (a novel view; ``video`` None until ``synth``
    writes one) or ``held-out`` (a ground-truth camera); ``poses`` [T, 4, 4] for a camera that moves."""

    name: str
    role: str
    camera: Camera
    video: Path | None
    poses: np.ndarray | None = None

    def camera_at(self, frame: int) -> Camera:
        if self.poses is None:
            return self.camera
        pose = self.poses[min(max(frame, 0), len(self.poses) - 1)]
        return Camera(self.camera.width, self.camera.height, self.camera.K, pose)


@dataclass(frozen=True, eq=False)
class Body:
    """An obstacle to draw: a ball (``center``, ``radius``) or a mesh (``vertices``, ``faces``); ``origin`` is
    ``declared`` (scene.json), ``found`` (by recon in the footage) or ``interaction`` (``interact --ball/--mesh``)."""

    origin: str
    label: str
    center: tuple | None = None
    radius: float | None = None
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None


class RunContent:
    """One run folder as the viewer shows it. Frame states are read when asked for and kept in a small cache."""

    def __init__(self, run: Run, cache_frames: int = 6):
        self.run = run
        self.name = run.root.name
        self.scene = run.scene(check_videos=False)
        self.frames = run.frames
        self._cache: OrderedDict[int, FrameState] = OrderedDict()
        self._cache_frames = cache_frames
        self._lock = threading.Lock()

    @classmethod
    def open(cls, path: str | Path) -> "RunContent":
        return cls(open_run(path))

    def state(self, frame: int) -> FrameState | None:
        """The state after ``frame``, or None when the run has no such frame."""
        if frame not in self.frames:
            return None
        with self._lock:
            if frame in self._cache:
                self._cache.move_to_end(frame)
                return self._cache[frame]
        state = self.run.state(frame)
        with self._lock:
            self._cache[frame] = state
            while len(self._cache) > self._cache_frames:
                self._cache.popitem(last=False)
        return state

    def source(self):
        """The inflow the run used (run.json ``source``: declared, or found in the footage), else the scene's."""
        from ..scene import Source

        recorded = self.run.info.get("source")
        if recorded:
            try:
                return Source.from_dict(recorded, self.run.root / "run.json")
            except (InputError, KeyError, TypeError):
                log.warning("viewer: run.json's source is unreadable; showing the scene's")
        return self.scene.source

    def parent(self) -> Run | None:
        """The run a ``predict`` / ``interact`` run continues (None for a recon run or a parent that is gone)."""
        parent = self.run.info.get("parent")
        if not parent:
            return None
        try:
            return open_run(parent)
        except InputError:
            return None

    def cameras(self) -> list[CameraMark]:
        """The scene's views (input, synthesised) and its ground-truth cameras (held out)."""
        marks = [CameraMark(v.name, "input" if v.role == "input" else "synthesised", v.camera,
                            None if v.video is None else self.scene.root / v.video) for v in self.scene.views]
        try:
            truths = load_ground_truth(self.scene.root, check_videos=False)
        except InputError as err:
            log.warning("viewer: ground-truth cameras not shown (%s)", err)
            truths = ()
        marks += [CameraMark(g.name, "held-out", g.camera, self.scene.root / g.video, g.poses) for g in truths]
        return marks

    def bodies(self) -> list[Body]:
        """Declared obstacles, those recon found (its run.json, or the parent's) and an interaction's body."""
        from ..scenery.obstacles import SphereBody, load_mesh

        out = []
        for body in self.scene.obstacles:
            if isinstance(body, SphereBody):
                out.append(Body("declared", "declared ball", tuple(body.center), float(body.radius)))
            else:
                mesh = load_mesh(self.scene.root / body.file)
                out.append(Body("declared", f"declared mesh {body.file}", vertices=np.asarray(mesh.vertices),
                                faces=np.asarray(mesh.faces)))
        parent = self.parent()
        found = self.run.info.get("found_obstacles") or (parent.info.get("found_obstacles") if parent else None) or []
        for item in found:
            shape = "ball" if item.get("sphere_like") else f"{item.get('kind', 'body')} (its fitted ball shown)"
            out.append(Body("found", f"found {shape}", tuple(item["center"]), float(item["radius"])))
        added = (self.run.info.get("interaction") or {}).get("obstacle")
        if added and added.get("kind") == "ball":
            out.append(Body("interaction", "interaction ball", tuple(added["center"]), float(added["radius"])))
        elif added and added.get("kind") == "mesh":
            try:
                mesh = load_mesh(Path(added["file"]))
                out.append(Body("interaction", f"interaction mesh {Path(added['file']).name}",
                                vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces)))
            except InputError as err:
                log.warning("viewer: the interaction's mesh is not shown (%s)", err)
        return out

    def static_layer_file(self) -> Path | None:
        """RUN/static.npz (or the parent run's), or None when the run has no static layer."""
        parent = self.parent()
        for root in (self.run.root, parent.root if parent else None):
            if root is not None and (root / STATIC_LAYER_FILE).is_file():
                return root / STATIC_LAYER_FILE
        return None


class Thumbnails:
    """Video frames of cameras as small uint8 RGB images, decoded in a background thread one video at a time;
    :meth:`get` returns None until a video is decoded (or when it cannot be read)."""

    def __init__(self, marks: list[CameraMark], width: int = THUMBNAIL_WIDTH, on_ready=None):
        self._marks = [m for m in marks if m.video is not None]
        self._width = width
        self._frames: dict[str, np.ndarray] = {}
        self._on_ready = on_ready
        self._thread = threading.Thread(target=self._decode_all, name="viewer-thumbnails", daemon=True)

    def start(self) -> "Thumbnails":
        self._thread.start()
        return self

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)

    def get(self, name: str, frame: int) -> np.ndarray | None:
        video = self._frames.get(name)
        if video is None or not 0 <= frame < len(video):
            return None
        return video[frame]

    def _decode_all(self) -> None:
        from ..video import read_video

        for mark in self._marks:
            cam = mark.camera
            height = max(1, round(self._width * cam.height / cam.width))
            try:
                video = read_video(mark.video, size=(self._width, height), channels=3)
            except InputError as err:
                log.warning("viewer: no video frames on camera %s (%s)", mark.name, err)
                continue
            self._frames[mark.name] = np.round(np.clip(video, 0, 1) * 255).astype(np.uint8)
            if self._on_ready is not None:
                self._on_ready(mark.name)
