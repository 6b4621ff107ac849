"""A scene folder written by hand (scene.json only, videos optional) for tests of commands that read a run's scene
without reconstructing: export, view."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fluidnexus.camera import Camera

VOLUME = ((-0.5, 0.0, -0.5), (0.5, 1.0, 0.5))


def ring_camera(azimuth_deg: float, width: int = 64, height: int = 48, distance: float = 2.5) -> Camera:
    """A camera on a horizontal ring round the volume's centre, looking at it (+y up in the image)."""
    a = np.radians(azimuth_deg)
    target = np.array([0.0, 0.5, 0.0])
    eye = target + distance * np.array([np.sin(a), 0.0, np.cos(a)])
    return Camera.look_at(width, height, 1.2 * width, eye, target)


def write_scene(folder: Path, views: list[tuple[str, str, Camera, str | None]],
                ground_truth: list[tuple[str, Camera, str]] = (), frame_count: int = 4, fps: float = 25.0,
                obstacles: list[dict] = ()) -> Path:
    """A ``fluidnexus-scene/1`` folder: ``views`` as (name, role, camera, video or None) and ``ground_truth`` as
    (name, camera, video), over :data:`VOLUME` with an upward source at its foot."""
    folder.mkdir(parents=True, exist_ok=True)
    data = {"format": "fluidnexus-scene/1", "fps": fps, "frame_count": frame_count,
            "volume": {"min": list(VOLUME[0]), "max": list(VOLUME[1])},
            "source": {"center": [0.0, 0.05, 0.0], "radius": 0.1},
            "obstacles": list(obstacles),
            "views": [{"name": n, "role": r, "camera": c.to_dict(), "video": v} for n, r, c, v in views],
            "ground_truth": [{"name": n, "camera": c.to_dict(), "video": v} for n, c, v in ground_truth]}
    (folder / "scene.json").write_text(json.dumps(data))
    return folder
