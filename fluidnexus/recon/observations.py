"""The footage a reconstruction fits: every usable view of a scene, at the run's resolution and frame range."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..scene import SCENE_FILE, Scene
from ..scenery.backdrop import Backdrop, Behind, scene_backdrop
from ..video import read_video


@dataclass(frozen=True, eq=False)
class Observations:
    """Frames of the views a reconstruction may use (never ground truth).

    Attributes:
        names: view names, [V].
        cameras: the views' cameras at the run resolution, [V].
        first: scene frame index of ``images[:, 0]``.
        images: float32 [V, T, H, W, C] in [0, 1]; memory V*T*H*W*C*4 bytes.
        behind: what each view sees behind the smoke, at the run resolution [V] (``scenery.backdrop``); empty:
            black.
    """

    names: tuple[str, ...]
    cameras: tuple[Camera, ...]
    first: int
    images: np.ndarray
    behind: tuple[Behind, ...] = ()

    @property
    def num_frames(self) -> int:
        return int(self.images.shape[1])

    def frame(self, t: int) -> np.ndarray:
        """All views at scene frame ``t``: [V, H, W, C]."""
        return self.images[:, t - self.first]


def resolve_frames(scene: Scene, frames: tuple[int, int | None]) -> tuple[int, int]:
    """Clamp nothing: a range outside the videos is an error naming the scene and ``--frames``."""
    start, stop = frames
    stop = scene.frame_count if stop is None else stop
    if not (0 <= start < stop <= scene.frame_count):
        raise InputError(scene.root / SCENE_FILE, "--frames",
                         f"range {start}:{stop} is outside the videos' {scene.frame_count} frames")
    if stop - start < 2:
        raise InputError(scene.root / SCENE_FILE, "--frames", "a reconstruction needs at least 2 frames")
    return start, stop


def load_observations(scene: Scene, frames: tuple[int, int], resolution: float, channels: int,
                      backdrop: Backdrop | None = None) -> Observations:
    """Read every usable view (input views, and novel views that have a video) of ``frames`` at ``resolution``,
    with what each sees behind the smoke (``backdrop``, default the scene's own: plates, colour or black)."""
    views = scene.usable_views()
    if not views:
        raise InputError(scene.root / SCENE_FILE, "views",
                         "no usable view: no input view has a video (and no novel view has one yet)")
    cameras = tuple(v.camera.scaled(resolution) for v in views)
    size = (cameras[0].width, cameras[0].height)
    images = np.stack([read_video(scene.video_path(v), frames=slice(*frames), size=size, channels=channels)
                       for v in views])
    if backdrop is None:
        backdrop = scene_backdrop(scene, channels)
    behind = tuple(backdrop.behind(cam, v.name) for v, cam in zip(views, cameras))
    return Observations(tuple(v.name for v in views), cameras, frames[0], images, behind)
