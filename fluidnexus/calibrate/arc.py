"""A camera rig for a single video (a phone on a tripod): the input camera plus novel cameras on an arc.

Geometry (all in metres, world +y up, see docs/calibration.md):

- The plume axis is the world y axis; the smoke source sits at its foot, the world origin.
- The input camera stands at distance ``d`` from the axis, at ``(0, h, d)``, looking horizontally at
  ``(0, h, 0)``. Its focal length is ``fx = fy = 0.5 W / tan(0.5 fov)`` with the principal point at the image
  centre. Its height ``h`` puts the source at 90 % of the image height (``h = 0.4 H d / fy``), so the plume has
  the rest of the frame to rise into, unless ``height`` is given.
- ``views`` cameras in all (the input included) stand on the horizontal circle of radius ``d`` at height ``h``,
  all looking at ``(0, h, 0)``, ``arc / (views - 1)`` degrees apart; the input camera is the middle one (index
  ``(views - 1) // 2``, azimuth 0), and the others are the ``novel`` views ``arc00``, ``arc01``, ...
  Positive azimuth turns counter-clockwise seen from above (from +z towards +x).
- The volume is the box the input camera sees at the axis distance: ``|x|, |z| <= W d / (2 fx)``,
  ``0 <= y <= h + cy d / fy``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..scene import Source, Volume
from ..scene_scale import SCALARFLOW_SOURCE_RADIUS, volume_factor


@dataclass(frozen=True)
class ArcRig:
    """The rig's cameras and their placement."""

    input_camera: Camera
    novel: dict[str, Camera]
    azimuths_deg: dict[str, float]
    volume: Volume
    source: Source


def arc_rig(width: int, height: int, fov_deg: float, views: int = 5, arc_deg: float = 120.0,
            distance: float = 1.2, camera_height: float | None = None, source_radius: float | None = None,
            input_name: str = "input") -> ArcRig:
    """Build the single-video rig described in the module docstring; without ``source_radius`` the inflow's
    radius is ScalarFlow's 0.025 m times the rig volume's length scale (docs/scale.md)."""
    checks = (("--fov-deg", 0 < fov_deg < 180, fov_deg), ("--views", views >= 2, views),
              ("--arc-deg", 0 < arc_deg <= 360, arc_deg), ("--distance", distance > 0, distance),
              ("--source-radius", source_radius is None or source_radius > 0, source_radius))
    for option, ok, value in checks:
        if not ok or (isinstance(value, float) and not math.isfinite(value)):
            raise InputError(None, option, f"impossible value {value!r}")
    fx = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    h = 0.4 * height * distance / fx if camera_height is None else float(camera_height)
    target = np.array([0.0, h, 0.0])
    step = arc_deg / (views - 1)
    mid = (views - 1) // 2
    cams, azimuths = {}, {}
    for i in range(views):
        az = (i - mid) * step
        a = math.radians(az)
        eye = np.array([distance * math.sin(a), h, distance * math.cos(a)])
        name = input_name if i == mid else f"arc{i - (i > mid):02d}"
        cams[name] = Camera.look_at(width, height, fx, eye, target)
        azimuths[name] = az
    half = 0.5 * width * distance / fx
    volume = Volume((-half, 0.0, -half), (half, h + 0.5 * height * distance / fx, half))
    input_camera = cams.pop(input_name)
    radius = SCALARFLOW_SOURCE_RADIUS * volume_factor(volume) if source_radius is None else float(source_radius)
    return ArcRig(input_camera, cams, azimuths, volume, Source((0.0, 0.0, 0.0), radius))
