"""A scene of the family drawn from a seed: every choice (box, unit, up axis, source, obstacles, backdrop, smoke look,
cameras) sampled from one ``numpy.random.default_rng(seed)``, in a fixed order, so a seed always gives the same scene.

Everything here is in the generator's own world: metres, +y up (the scene's convention, docs/conventions.md). The
file's unit and up axis (``unit``, ``up``) are applied only when the PINF files are written (``pinf_out``). The
ranges are relative to the box (a scene 2 m tall and one 20 cm tall differ only in scale and unit), so none of them
encodes one capture.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# length of one file unit in metres, by the unit's name
UNITS = {"mm": 0.001, "cm": 0.01, "m": 1.0}


@dataclass(frozen=True)
class Size:
    """Image size (width and height of a landscape frame; a portrait scene swaps them), frames, and grid cells
    along the box's longest side."""

    width: int
    height: int
    frames: int
    cells: int


SIZES = {"tiny": Size(48, 36, 12, 16), "small": Size(128, 96, 40, 28), "medium": Size(240, 136, 40, 40)}


@dataclass(frozen=True)
class Source:
    """A disk of ``radius`` at ``center`` perpendicular to ``direction``; gas leaves it at ``speed`` m/s during the
    frames [window[0], window[1]) (None: to the end); ``kind`` is plume, jet or puff."""

    kind: str
    center: tuple
    radius: float
    direction: tuple
    speed: float
    window: tuple
    buoyancy: float        # m/s^2 per unit of smoke density (1 in the source cells), along +y


@dataclass(frozen=True)
class Body:
    """A rigid body: ``sphere`` (center, radius) or ``box`` (center, half: half-extents); ``role`` says whether it
    stands in the flow (``obstacle``, scored) or belongs to the backdrop set (``set``: floor pieces, steps)."""

    kind: str
    center: tuple
    radius: float = 0.0
    half: tuple = (0.0, 0.0, 0.0)
    role: str = "obstacle"
    color: tuple = (0.6, 0.6, 0.6)

    def to_dict(self) -> dict:
        out = {"kind": self.kind, "center": list(self.center), "role": self.role}
        if self.kind == "sphere":
            out["radius"] = self.radius
        else:
            out["min"] = [c - h for c, h in zip(self.center, self.half)]
            out["max"] = [c + h for c, h in zip(self.center, self.half)]
        return out

    @property
    def size(self) -> float:
        """The body's radius (sphere) or half-diagonal (box): the length its errors are measured in."""
        return self.radius if self.kind == "sphere" else float(np.linalg.norm(self.half))


@dataclass(frozen=True)
class Backdrop:
    """``black`` or ``white`` (a plain colour), ``wall`` (a textured room around the rig) or ``set`` (the room with a
    floor at the box's foot and boxes and steps standing on it). ``texture_seed`` and the two colours make the
    procedural texture; ``room`` is the room's (min, max)."""

    kind: str
    color: tuple = (0.0, 0.0, 0.0)
    texture_seed: int = 0
    colors: tuple = ((0.2, 0.2, 0.2), (0.8, 0.8, 0.8))
    texture_scale: float = 1.0
    room: tuple | None = None


@dataclass(frozen=True)
class Smoke:
    """How the smoke looks: its colour (``glowing``: brighter than what is behind it, ``absorbing``: darker) and its
    optical depth across the source's diameter at unit density."""

    mode: str
    color: tuple
    tau: float


@dataclass(frozen=True)
class Rig:
    """Camera layout: ``arc`` (``span_deg``) or ``ring``; ``elevation`` class and angle, horizontal FOV, distance
    from the target; the held-out camera ``test00`` at ``held_out_az`` (moving from ``held_out_az`` to
    ``held_out_az_end`` when ``moving``)."""

    layout: str
    azimuths: tuple
    span_deg: float
    elevation: str
    elevation_deg: float
    fov_deg: float
    distance: float
    target: tuple
    held_out_az: float
    held_out_az_end: float
    held_out_elevation_deg: float
    moving: bool


@dataclass(frozen=True)
class SceneSpec:
    seed: int
    size: str
    width: int
    height: int
    frames: int
    fps: float
    unit: str
    up: str
    lo: tuple
    hi: tuple
    cells: int
    source: Source
    obstacles: tuple
    set_pieces: tuple
    backdrop: Backdrop
    smoke: Smoke
    rig: Rig
    vorticity: float
    extra: dict = field(default_factory=dict)

    @property
    def length(self) -> float:
        """The box's height, the scene's length scale (metres)."""
        return self.hi[1] - self.lo[1]

    @property
    def metres_per_unit(self) -> float:
        return UNITS[self.unit]

    @property
    def bodies(self) -> tuple:
        return self.obstacles + self.set_pieces


def _unit_vector(v) -> tuple:
    v = np.asarray(v, dtype=float)
    return tuple(float(x) for x in v / np.linalg.norm(v))


def _tilted(axis, max_deg: float, rng) -> tuple:
    """``axis`` tilted by up to ``max_deg`` degrees in a random azimuth."""
    axis = np.asarray(axis, dtype=float)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    tilt, az = math.radians(rng.uniform(0, max_deg)), rng.uniform(0, 2 * math.pi)
    return _unit_vector(math.cos(tilt) * axis + math.sin(tilt) * (math.cos(az) * e1 + math.sin(az) * e2))


def draw_source(rng, lo, hi, frames: int) -> Source:
    """Plume (up, low in the box), sideways jet (from near a side wall, inward) or downward puff (high in the box),
    anywhere across the box; continuous, late-starting or a burst."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    ext, L = hi - lo, hi[1] - lo[1]
    kind = str(rng.choice(["plume", "jet", "puff"], p=[0.45, 0.35, 0.2]))
    if kind == "plume":
        d = _tilted((0, 1, 0), 20, rng)
        f = (rng.uniform(0.25, 0.75), rng.uniform(0.08, 0.3), rng.uniform(0.25, 0.75))
        speed, buoy = rng.uniform(0.1, 0.5), rng.uniform(1.0, 3.0)
    elif kind == "jet":
        phi, elev = rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(-10, 20))
        d = _unit_vector((math.cos(elev) * math.cos(phi), math.sin(elev), math.cos(elev) * math.sin(phi)))
        f = (0.5 - 0.32 * d[0] + rng.uniform(-0.08, 0.08), rng.uniform(0.2, 0.55),
             0.5 - 0.32 * d[2] + rng.uniform(-0.08, 0.08))
        speed, buoy = rng.uniform(0.6, 1.5), rng.uniform(0.3, 1.0)
    else:
        d = _tilted((0, -1, 0), 20, rng)
        f = (rng.uniform(0.3, 0.7), rng.uniform(0.7, 0.85), rng.uniform(0.3, 0.7))
        speed, buoy = rng.uniform(0.5, 1.2), rng.uniform(0.05, 0.4)
    radius = L * rng.uniform(0.05, 0.1)
    if rng.uniform() < 0.5:
        window = (int(rng.integers(0, 4)), None)
    else:
        start = int(rng.integers(0, 4))
        window = (start, start + int(rng.integers(max(3, frames // 6), max(4, frames // 2))))
    center = tuple(float(x) for x in lo + np.asarray(f) * ext)
    return Source(kind, center, float(radius), d, float(speed * L), window, float(buoy * L))


def draw_obstacles(rng, lo, hi, source: Source) -> tuple:
    """0-2 spheres or boxes in the smoke's path (ahead of the source, off its axis by up to most of their size),
    inside the box and clear of the source."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    L = hi[1] - lo[1]
    count = int(rng.choice([0, 1, 1, 2]))
    out = []
    for _ in range(count):
        for _attempt in range(20):
            size = L * rng.uniform(0.07, 0.15)
            ahead = np.asarray(source.center) + np.asarray(source.direction) * L * rng.uniform(0.25, 0.45)
            c = ahead + rng.uniform(-0.6, 0.6, 3) * size
            far_from_source = np.linalg.norm(c - source.center) > 1.8 * size + source.radius
            inside = np.all(c - size > lo + 0.05 * L) and np.all(c + size < hi - 0.05 * L)
            apart = all(np.linalg.norm(c - o.center) > 1.8 * (size + o.size) for o in out)
            if far_from_source and inside and apart:
                break
        else:
            continue
        color = tuple(float(x) for x in rng.uniform(0.25, 0.9, 3))
        if rng.uniform() < 0.5:
            out.append(Body("sphere", tuple(float(x) for x in c), radius=float(size), color=color))
        else:
            half = tuple(float(x) for x in size * rng.uniform(0.6, 1.0, 3))
            out.append(Body("box", tuple(float(x) for x in c), half=half, color=color))
    return tuple(out)


def draw_set(rng, lo, hi) -> tuple:
    """Boxes and a flight of steps standing on the floor (the box's foot), around the box's footprint."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    L, mid = hi[1] - lo[1], 0.5 * (lo + hi)
    pieces = []
    for k in range(int(rng.integers(1, 4))):
        phi, r = rng.uniform(0, 2 * math.pi), L * rng.uniform(0.55, 0.95)
        half = np.array([rng.uniform(0.06, 0.15), rng.uniform(0.05, 0.2), rng.uniform(0.06, 0.15)]) * L
        c = (mid[0] + r * math.cos(phi), lo[1] + half[1], mid[2] + r * math.sin(phi))
        pieces.append(Body("box", tuple(float(x) for x in c), half=tuple(float(x) for x in half), role="set",
                           color=tuple(float(x) for x in rng.uniform(0.2, 0.9, 3))))
    phi, r = rng.uniform(0, 2 * math.pi), L * rng.uniform(0.6, 0.9)
    step = L * rng.uniform(0.04, 0.07)
    color = tuple(float(x) for x in rng.uniform(0.3, 0.8, 3))
    for k in range(3):  # three steps: each one tread deeper behind and one riser higher than the last
        rad = r + k * 2 * step
        c = (mid[0] + rad * math.cos(phi), lo[1] + (k + 1) * step / 2, mid[2] + rad * math.sin(phi))
        width = L * 0.25
        half = (abs(math.cos(phi)) * step + abs(math.sin(phi)) * width, (k + 1) * step / 2,
                abs(math.sin(phi)) * step + abs(math.cos(phi)) * width)
        pieces.append(Body("box", tuple(float(x) for x in c), half=tuple(float(x) for x in half), role="set",
                           color=color))
    return tuple(pieces)


def draw_rig(rng, lo, hi, aspect: float, backdrop_kind: str) -> Rig:
    """Four input cameras on an arc (60-150 degrees) or a full ring, all level, elevated or low, a FOV of 35-70
    degrees (horizontal; ``aspect`` = width / height), about far enough that the box's bounding sphere fits the
    narrower side of the view; test00 between two of them, moving in 30 % of the scenes."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    L = hi[1] - lo[1]
    layout = str(rng.choice(["arc", "ring"], p=[0.6, 0.4]))
    base = rng.uniform(0, 360)
    if layout == "arc":
        span = rng.uniform(60, 150)
        az = tuple(float(base + span * (k / 3 - 0.5)) for k in range(4))
        gap = span / 3
    else:
        span = 360.0
        az = tuple(float(base + 90 * k + rng.uniform(-10, 10)) for k in range(4))
        gap = 90.0
    elevation = str(rng.choice(["level", "elevated", "low"], p=[0.4, 0.35, 0.25]))
    elev = {"level": rng.uniform(-5, 10), "elevated": rng.uniform(20, 40), "low": rng.uniform(-20, -8)}[elevation]
    fov = rng.uniform(35, 70)
    bound = 0.5 * float(np.linalg.norm(hi - lo))
    half_fx = math.radians(0.5 * fov)
    narrow = min(half_fx, math.atan(math.tan(half_fx) / aspect))
    distance = bound / math.sin(narrow) * rng.uniform(0.85, 1.05)
    target = 0.5 * (lo + hi) + rng.uniform(-0.05, 0.05, 3) * L
    if backdrop_kind == "set":  # every camera above the floor
        floor_elev = math.degrees(math.asin(max(-1.0, (lo[1] + 0.05 * L - target[1]) / distance)))
        elev = max(elev, floor_elev)
    held = az[1] + gap * rng.uniform(0.3, 0.7)
    moving = bool(rng.uniform() < 0.3)
    held_end = held + (gap * rng.uniform(0.4, 0.8) * rng.choice([-1, 1]) if moving else 0.0)
    return Rig(layout, az, float(span), elevation, float(elev), float(fov), float(distance),
               tuple(float(x) for x in target), float(held), float(held_end),
               float(elev + rng.uniform(-5, 5)), moving)


def draw_backdrop(rng, lo, hi) -> tuple[Backdrop, Smoke]:
    """The backdrop and the smoke's look, drawn together so the smoke stands out: glowing smoke on black or on a
    dark textured room, absorbing (grey or coloured) smoke on white or on a bright one."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    kind = str(rng.choice(["black", "white", "wall", "set"], p=[0.25, 0.2, 0.25, 0.3]))
    mode = {"black": "glowing", "white": "absorbing"}.get(kind) or str(rng.choice(["glowing", "absorbing"]))
    smoke = draw_smoke(rng, mode)
    if kind in ("black", "white"):
        return Backdrop(kind, (0.0, 0.0, 0.0) if kind == "black" else (1.0, 1.0, 1.0)), smoke
    a = rng.uniform(0.02, 0.2, 3) if mode == "glowing" else rng.uniform(0.45, 0.7, 3)
    b = np.clip(a + rng.uniform(0.1, 0.3, 3), 0, 1)
    return Backdrop(kind, texture_seed=int(rng.integers(0, 2**31)),
                    colors=(tuple(float(x) for x in a), tuple(float(x) for x in b)),
                    texture_scale=float((hi[1] - lo[1]) * rng.uniform(0.3, 0.8))), smoke


def draw_smoke(rng, mode: str) -> Smoke:
    """Glowing: a bright grey or tinted colour; absorbing: a dark grey or a coloured dye."""
    coloured = rng.uniform() < 0.3
    tint = rng.uniform(0.2, 1.0, 3) if coloured else np.ones(3) * rng.uniform(0.9, 1.0)
    level = rng.uniform(0.75, 1.0) if mode == "glowing" else rng.uniform(0.05, 0.35)
    color = np.clip(tint / tint.max() * level, 0, 1) if mode == "glowing" or not coloured else tint * 0.5
    return Smoke(mode, tuple(float(x) for x in color), float(rng.uniform(0.8, 3.0)))


def room_for(rig: Rig, lo, hi, floor_y: float | None) -> tuple:
    """A room (min, max) around the box and every camera: walls 1.5 camera distances from the target."""
    t, d = np.asarray(rig.target), rig.distance
    L = hi[1] - lo[1]
    y_cam = [t[1] + d * math.sin(math.radians(e)) for e in (rig.elevation_deg, rig.held_out_elevation_deg)]
    bottom = floor_y if floor_y is not None else min(lo[1], min(y_cam)) - 0.3 * L
    top = max(hi[1], max(y_cam)) + 1.0 * L
    return ((float(t[0] - 1.5 * d), float(bottom), float(t[2] - 1.5 * d)),
            (float(t[0] + 1.5 * d), float(top), float(t[2] + 1.5 * d)))


def draw(seed: int, size: str = "small") -> SceneSpec:
    """The scene of ``seed`` at ``size`` (``tiny``: tests, ``small``: the table, ``medium``)."""
    if size not in SIZES:
        raise ValueError(f"size {size!r}: expected one of {sorted(SIZES)}")
    rng = np.random.default_rng(seed)
    sz = SIZES[size]
    unit = str(rng.choice(list(UNITS)))
    up = str(rng.choice(["Y", "Z"]))
    fps = float(rng.choice([24.0, 25.0, 30.0]))
    L = float(math.exp(rng.uniform(math.log(0.15), math.log(3.0))))   # box height, metres
    ext = np.array([rng.uniform(0.6, 1.0), 1.0, rng.uniform(0.6, 1.0)]) * L
    lo = rng.uniform(-1.0, 1.0, 3) * L                                  # the box is anywhere, not at the origin
    hi = lo + ext
    portrait = bool(rng.uniform() < 0.5)
    width, height = (sz.height, sz.width) if portrait else (sz.width, sz.height)
    source = draw_source(rng, lo, hi, sz.frames)
    obstacles = draw_obstacles(rng, lo, hi, source)
    backdrop, smoke = draw_backdrop(rng, lo, hi)
    set_pieces = draw_set(rng, lo, hi) if backdrop.kind == "set" else ()
    rig = draw_rig(rng, lo, hi, width / height, backdrop.kind)
    if backdrop.kind in ("wall", "set"):
        floor = float(lo[1]) if backdrop.kind == "set" else None
        backdrop = Backdrop(backdrop.kind, backdrop.color, backdrop.texture_seed, backdrop.colors,
                            backdrop.texture_scale, room_for(rig, lo, hi, floor))
    return SceneSpec(seed, size, width, height, sz.frames, fps, unit, up, tuple(map(float, lo)),
                     tuple(map(float, hi)), sz.cells, source, obstacles, set_pieces, backdrop, smoke, rig,
                     float(rng.uniform(0.0, 0.3)))
