"""Where the smoke comes from, found in the footage: the inflow's position, direction, speed and start.

A reconstruction needs the inflow (``scene.Source``). A scene may declare it in scene.json; otherwise it is found
from the first frames with smoke, across every usable view, through multi-view visual hulls
(``hull.visual_hull``):

1. The earliest frame t0 of the run's range whose hull holds smoke (at least ``MIN_POINTS`` voxels).
2. The way the smoke moves: the hull of each of the next ``FOLLOW_FRAMES`` frames (on a grid ``FOLLOW_COARSENING``
   times coarser, to keep the search cheap), and of further ones up to ``FOLLOW_MAX`` until the smoke has moved a
   coarse voxel (slow smoke in a large volume, e.g. Sphere); the least-squares slope of the hull centroid over
   time gives the direction. Buoyancy makes every plume drift up in the end, but over the first
   frames a jet moves the way it was blown. Without a measurable motion (less than one hull voxel over the frames)
   the direction is up. Where the run's first frame already holds smoke, the start is not in the footage: the hulls
   follow a developed plume, whose centroid drifts sideways as its smoke spreads or flows around a body above the
   source, so a motion within ``PLUME_CONE_DEG`` of up is taken for a plume's and the direction is up (a developed
   jet still moves well outside it).
3. The position: the foot of the earliest smoke along that direction, i.e. the centre of the hull's slab of
   ``slab`` metres at its 2nd-percentile extent against the direction; the radius: the slab's spread about the axis
   (sqrt(2) times its rms distance, the radius of a uniform disk), at least one hull voxel.
4. The speed: the least-squares slope of the smoke front (98th-percentile extent along the direction) over the same
   frames, in m/s. The emission window starts at t0 when the smoke appears after the run's first frame.

The hulls see smoke where a view differs from what it sees behind the smoke (its clean plate, the scene's
``backdrop_color``, or black: ``scenery.backdrop``) and not inside an obstacle. A declared source keeps its
direction, radius, speed and window; its centre moves to the foot of the first frame's hull along its direction when
the frame has smoke (for an upward source: the centre of the hull's lowest slab, the behaviour of every earlier
version). What was found, and how, is recorded in run.json (``source_finder``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..engine.emitter import UP, rotation_from_up
from ..scene import Scene, Source
from .hull import visual_hull

MIN_POINTS = 8
FOLLOW_FRAMES = 8
FOLLOW_MAX = 32
FOLLOW_COARSENING = 2
FOOT_PERCENTILE = 2.0
FRONT_PERCENTILE = 98.0
#: Where the smoke is in view from the run's first frame, a motion within this many degrees of up is a developed
#: plume's, and its inflow points up: PINF Sphere's plume (under a ball) moves 18.5 degrees from up, the ScalarFlow
#: sample's 15.6, where both rise from an upward inflow; a jet moves far outside it (PINF Game's, whose start is
#: filmed, 106) (BENCHMARKS.md, "A developed plume's inflow points up").
PLUME_CONE_DEG = 40.0


@dataclass(frozen=True)
class FoundSource:
    """The inflow, the first frame's hull points (the visual seeds), the earliest frame of the run with smoke and
    its hull (``smoke_frame`` None when no frame has any: the initial look is fitted there) and a JSON record of how
    it was found."""

    source: Source
    hull_points: np.ndarray
    record: dict
    smoke_frame: int | None = None
    smoke_hull: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def _axes(direction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(d, e1, e2): the direction and two unit vectors across it (x and z for the up direction, exactly)."""
    r = np.eye(3) if tuple(float(v) for v in direction) == UP else rotation_from_up(direction)
    return r[:, 1], r[:, 0], r[:, 2]


def foot(points: np.ndarray, direction, slab: float) -> tuple[np.ndarray, np.ndarray]:
    """(centre (3,), slab points [K, 3]): the centre of ``points``' slab of ``slab`` metres at their
    2nd-percentile extent along ``direction``, on that plane."""
    d, e1, e2 = _axes(direction)
    s = points @ d
    s0 = np.percentile(s, FOOT_PERCENTILE)
    base = points[s <= s0 + slab]
    a, b = (base @ e1).mean(), (base @ e2).mean()
    return s0 * d + a * e1 + b * e2, base


def foot_radius(base: np.ndarray, center: np.ndarray, direction, voxel: float) -> float:
    """Radius of a uniform disk with the rms distance of ``base`` from the axis through ``center``."""
    d = np.asarray(direction, dtype=np.float64)
    rel = base - center
    perp = rel - np.outer(rel @ d, d)
    return float(max(voxel, np.sqrt(2.0 * np.mean(np.sum(perp**2, axis=1)))))


def _slope(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares slope of y [T, ...] over t [T]."""
    tc = t - t.mean()
    return np.tensordot(tc, y - y.mean(axis=0), axes=1) / float(tc @ tc)


def _degrees_from_up(direction) -> float:
    return float(np.degrees(np.arccos(np.clip(np.asarray(direction, dtype=np.float64) @ np.asarray(UP), -1.0, 1.0))))


def find_source(scene: Scene, obs, voxel: float, slab: float, fallback: Source, obstacle=None) -> FoundSource:
    """The run's inflow: the scene's declared source (centre at the first frame's hull foot), or one found in the
    footage of ``obs`` (module docstring); ``fallback`` when the footage shows no smoke at all.

    Args:
        obs: the run's observations (``observations.Observations``).
        voxel: hull voxel size, metres.
        slab: thickness of the foot slab, metres.
        obstacle: an engine body (or None); hull voxels inside it are not smoke.
    """
    first = obs.first
    if scene.volume is None:
        return FoundSource(fallback, np.zeros((0, 3)), {"method": "no volume: the scene's source or its default"})

    def hull(t: int, coarsening: int = 1) -> np.ndarray:
        points = visual_hull(obs.cameras, obs.frame(t), scene.volume, voxel * coarsening,
                             behind=obs.behind or None).points
        return points if obstacle is None or not len(points) else points[obstacle.distance(points) > 0]

    seeds = hull(first)
    last = first + obs.num_frames
    t0, h0 = first, seeds
    while len(h0) < MIN_POINTS and t0 + 1 < last:
        t0 += 1
        h0 = hull(t0)
    smoke = (t0, h0) if len(h0) >= MIN_POINTS else (None, np.zeros((0, 3)))
    if scene.source is not None:
        src = scene.source
        if len(seeds) < MIN_POINTS:
            return FoundSource(src, seeds, {"method": "declared", "centre": "declared (no smoke in the first frame)"},
                               *smoke)
        center, _ = foot(seeds, src.direction, slab)
        found = Source(tuple(float(v) for v in center), src.radius, src.direction, src.speed, src.window)
        return FoundSource(found, seeds, {"method": "declared", "centre": f"foot of the hull of frame {first}"},
                           *smoke)
    if smoke[0] is None:
        return FoundSource(fallback, seeds, {"method": "fallback: no smoke in any frame of the run",
                                             "source": fallback.to_dict()})
    coarse = voxel * FOLLOW_COARSENING
    times, hulls = [], []
    velocity, moved = np.zeros(3), 0.0
    for t in range(t0, min(last, t0 + 1 + FOLLOW_MAX)):
        h = hull(t, FOLLOW_COARSENING)
        if len(h) >= MIN_POINTS:
            times.append(t)
            hulls.append(h)
        if len(times) >= 2:
            tt = np.asarray(times, dtype=np.float64)
            velocity = _slope(tt, np.stack([p.mean(axis=0) for p in hulls]))  # m per frame
            moved = float(np.linalg.norm(velocity) * (tt[-1] - tt[0]))
        if t - t0 >= FOLLOW_FRAMES and moved >= coarse:
            break
    direction, speed, how, motion_angle = UP, 0.0, "up (no motion measured)", None
    if moved >= coarse:
        motion = velocity / np.linalg.norm(velocity)
        motion_angle = _degrees_from_up(motion)
        developed = t0 == first  # smoke in view from the run's first frame: its start is not seen
        direction, how = ((UP, f"up (smoke from the first frame, moving within {PLUME_CONE_DEG:g} degrees of up: "
                               "a developed plume)")
                          if developed and motion_angle < PLUME_CONE_DEG else
                          (tuple(float(v) for v in motion), "centroid motion"))
        d = np.asarray(direction)
        front = np.array([np.percentile(h @ d, FRONT_PERCENTILE) for h in hulls])
        speed = float(max(0.0, _slope(np.asarray(times, dtype=np.float64), front)) * scene.fps)
    center, base = foot(h0, direction, slab)
    radius = foot_radius(base, center, direction, voxel)
    source = Source(tuple(float(v) for v in center), radius, direction, speed, None if t0 == first else (t0, None))
    record = {"method": "found in the footage", "first_smoke_frame": t0, "frames_followed": times,
              "hull_voxels": [len(h) for h in hulls], "centroid_travel_m": round(moved, 6),
              "motion_degrees_from_up": None if motion_angle is None else round(motion_angle, 2),
              "degrees_from_up": round(_degrees_from_up(direction), 2), "direction": how}
    return FoundSource(source, seeds, record, t0, h0)
