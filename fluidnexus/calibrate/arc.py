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

On a floor (``tilt_deg`` or ``horizon_row`` given, with ``camera_height``): the camera stands ``h`` above the floor
y = 0, pitched down by the tilt ``t`` (from a horizon row v: ``tan t = (cy - v) / fy``, the horizon being the image
of the floor's far edge). The world origin is where the input camera's centre ray meets the floor, so the axis
distance follows, ``d = h / tan t``; every camera stands on the circle of radius d at height h looking at the origin
(pitched down by t as well). The scene declares the floor and no source: ``synth`` casts the plume's foot onto the
floor (``gen/plume_foot.py``). The volume stands on the floor up to where the input's top image edge meets the axis,
``h + d tan(atan(cy / fy) - t)``, and reaches ``max(W r / (2 fx), e)`` across (r the slant distance to the origin,
e how far in front of it the image's bottom edge meets the floor).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..scene import Floor, Source, Volume
from ..scene_scale import SCALARFLOW_SOURCE_RADIUS, volume_factor


@dataclass(frozen=True)
class ArcRig:
    """The rig's cameras and their placement; a rig on a floor has a ``floor`` and no ``source``."""

    input_camera: Camera
    novel: dict[str, Camera]
    azimuths_deg: dict[str, float]
    volume: Volume
    source: Source | None
    distance: float  # of every camera from the y axis, m
    floor: Floor | None = None
    tilt_deg: float | None = None


def _check(*checks) -> None:
    for option, ok, value in checks:
        if not ok or (isinstance(value, float) and not math.isfinite(value)):
            raise InputError(None, option, f"impossible value {value!r}")


def camera_tilt(height: int, fy: float, tilt_deg: float | None, horizon_row: float | None) -> float | None:
    """The input camera's pitch down, degrees, from ``--tilt-deg`` or ``--horizon-row`` (None: neither given);
    InputError for both, or for a camera whose centre ray never meets the floor."""
    if tilt_deg is not None and horizon_row is not None:
        raise InputError(None, "--horizon-row", "give the camera's tilt either as --tilt-deg or as --horizon-row, "
                                                "not both")
    if horizon_row is not None:
        _check(("--horizon-row", True, float(horizon_row)))
        tilt_deg, option = math.degrees(math.atan2(0.5 * height - horizon_row, fy)), "--horizon-row"
    else:
        option = "--tilt-deg"
    if tilt_deg is None:
        return None
    _check((option, True, float(tilt_deg)))
    if tilt_deg <= 0:
        raise InputError(None, option, f"a tilt of {tilt_deg:.4g} degrees below the horizon: the camera's centre ray "
                                       "never meets the floor (the horizon must lie above the image's centre row)")
    if tilt_deg >= 90:
        raise InputError(None, option, f"a tilt of {tilt_deg:.4g} degrees: the camera looks straight down or behind "
                                       "itself; give a tilt between 0 and 90 degrees")
    return float(tilt_deg)


def arc_rig(width: int, height: int, fov_deg: float, views: int = 5, arc_deg: float = 120.0,
            distance: float | None = None, camera_height: float | None = None, source_radius: float | None = None,
            input_name: str = "input", tilt_deg: float | None = None, horizon_row: float | None = None) -> ArcRig:
    """Build the single-video rig described in the module docstring (``distance`` default 1.2 m); without
    ``source_radius`` the inflow's radius is ScalarFlow's 0.025 m times the rig volume's length scale
    (docs/scale.md). With ``tilt_deg`` or ``horizon_row`` the rig stands on a floor (``camera_height`` required)."""
    _check(("--fov-deg", 0 < fov_deg < 180, fov_deg), ("--views", views >= 2, views),
           ("--arc-deg", 0 < arc_deg <= 360, arc_deg), ("--distance", distance is None or distance > 0, distance),
           ("--camera-height", camera_height is None or camera_height > 0, camera_height),
           ("--source-radius", source_radius is None or source_radius > 0, source_radius))
    fx = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    tilt = camera_tilt(height, fx, tilt_deg, horizon_row)
    if tilt is not None:
        return _floor_rig(width, height, fx, views, arc_deg, distance, camera_height, source_radius, input_name, tilt)
    distance = 1.2 if distance is None else float(distance)
    h = 0.4 * height * distance / fx if camera_height is None else float(camera_height)
    cams, azimuths = _circle(width, height, fx, views, arc_deg, distance, h, np.array([0.0, h, 0.0]),
                             input_name)
    half = 0.5 * width * distance / fx
    volume = Volume((-half, 0.0, -half), (half, h + 0.5 * height * distance / fx, half))
    input_camera = cams.pop(input_name)
    radius = SCALARFLOW_SOURCE_RADIUS * volume_factor(volume) if source_radius is None else float(source_radius)
    return ArcRig(input_camera, cams, azimuths, volume, Source((0.0, 0.0, 0.0), radius), distance)


def _circle(width: int, height: int, fx: float, views: int, arc_deg: float, distance: float, h: float,
            target: np.ndarray, input_name: str) -> tuple[dict[str, Camera], dict[str, float]]:
    """``views`` cameras at height ``h`` on the circle of radius ``distance`` about the y axis, all looking at
    ``target``; the middle one (azimuth 0, on +z) is ``input_name``, the others ``arc00``, ``arc01``, ..."""
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
    return cams, azimuths


def _floor_rig(width: int, height: int, fx: float, views: int, arc_deg: float, distance: float | None,
               camera_height: float | None, source_radius: float | None, input_name: str, tilt: float) -> ArcRig:
    """The rig on a floor (module docstring, last paragraph)."""
    option = "--tilt-deg or --horizon-row"
    if camera_height is None:
        raise InputError(None, "--camera-height", f"required with {option} (the camera's height above the floor, m)")
    if distance is not None:
        raise InputError(None, "--distance", f"follows from --camera-height and {option} (the centre ray meets the "
                                             "floor at the plume's axis); give one or the other")
    if source_radius is not None:
        raise InputError(None, "--source-radius", f"with {option} the scene declares no source: synth finds the "
                                                  "plume's foot, and its radius, on the floor")
    h, t = float(camera_height), math.radians(tilt)
    distance = h / math.tan(t)
    cams, azimuths = _circle(width, height, fx, views, arc_deg, distance, h, np.zeros(3), input_name)
    top = h + distance * math.tan(math.atan(0.5 * height / fx) - t)
    below = t + math.atan(0.5 * height / fx)  # the image's bottom edge, degrees below the horizon
    near = distance - h / math.tan(below) if below < 0.5 * math.pi else distance
    half = max(0.5 * width * math.hypot(h, distance) / fx, near)
    volume = Volume((-half, 0.0, -half), (half, top, half))
    return ArcRig(cams.pop(input_name), cams, azimuths, volume, None, distance, Floor((0.0, 0.0, 0.0)), tilt)
