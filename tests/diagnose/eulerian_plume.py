"""Test-only generator of measured data: a small Eulerian grid smoke solver (not the PBF model under diagnosis).

Collocated grid, semi-Lagrangian advection (trilinear), Jacobi pressure projection, buoyancy proportional to the
smoke density, inflow disk at the bottom (fixed inflow velocity, constant smoke flux; a burst switches it off from
a frame on: the disk then neither adds smoke nor imposes its velocity). Each effect of diagnose can be switched on:
ambient wind (the air moves: everything is advected by u + wind), buoyancy decay with parcel age (an advected age
field), vorticity confinement (Fedkiw et al. 2001), viscosity (explicit diffusion of u), dissipation (density
fades), inflow swirl.
The density is rendered additively through the scene's cameras (voxel centres splatted, as emission only).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from fluidnexus.camera import Camera
from fluidnexus.diagnose.observe import splat_points
from fluidnexus.video import write_frames


@dataclass(frozen=True)
class PlumeEffects:
    """The hidden effects (all off by default)."""

    wind: tuple = (0.0, 0.0, 0.0)     # ambient air velocity [m/s]
    tau: float = np.inf               # buoyancy e-folding time with parcel age [s]
    epsilon: float = 0.0              # vorticity confinement (dimensionless, x dx)
    nu: float = 0.0                   # kinematic viscosity [m^2/s]
    rate: float = 0.0                 # dissipation [1/s]
    omega: float = 0.0                # inflow angular velocity about +y [rad/s]


@dataclass(frozen=True)
class Grid:
    lo: tuple = (0.08, -0.12, -0.50)
    dx: float = 0.0245
    shape: tuple = (20, 33, 20)
    source: tuple = (0.3273, -0.0446, -0.2504)
    source_radius: float = 0.05
    inflow_speed: float = 0.25        # m/s upward
    buoyancy: float = 1.6             # m/s^2 per unit density
    emission: float = 8.0             # smoke density added per second in the inflow cells
    fps: float = 30.0
    substeps: int = 2
    extra: dict = field(default_factory=dict)

    def centres(self) -> np.ndarray:
        idx = np.stack(np.meshgrid(*[np.arange(n) for n in self.shape], indexing="ij"), -1)
        return np.asarray(self.lo) + (idx + 0.5) * self.dx


def _advect(q: np.ndarray, vel: np.ndarray, dt: float, dx: float) -> np.ndarray:
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in q.shape[:3]], indexing="ij"), 0).astype(float)
    back = idx - np.moveaxis(vel, -1, 0) * dt / dx
    if q.ndim == 3:
        return ndimage.map_coordinates(q, back, order=1, mode="constant")
    return np.stack([ndimage.map_coordinates(q[..., c], back, order=1, mode="constant") for c in range(3)], -1)


def _grad(f: np.ndarray, dx: float) -> np.ndarray:
    return np.stack(np.gradient(f, dx), -1)


def _project(u: np.ndarray, dx: float, iters: int = 30) -> np.ndarray:
    div = sum(np.gradient(u[..., a], dx, axis=a) for a in range(3))
    p = np.zeros(div.shape)
    for _ in range(iters):
        s = np.zeros_like(p)
        for a in range(3):
            s += np.roll(p, 1, a) + np.roll(p, -1, a)
        p_new = (s - dx * dx * div) / 6.0
        p_new[0], p_new[-1], p_new[:, 0], p_new[:, -1], p_new[:, :, 0], p_new[:, :, -1] = 0, 0, 0, 0, 0, 0
        p = p_new
    return u - _grad(p, dx)


def simulate(frames: int, effects: PlumeEffects = PlumeEffects(), grid: Grid = Grid(),
             stop: int | None = None, start: int = 0) -> np.ndarray:
    """Density [frames, nx, ny, nz] at each frame (frame 0: before any inflow).

    ``stop``: a burst: the source is on for frames [start, stop) only (the step into frame t emits while
    start <= t < stop, the convention of scene.Source.emits_at); None: on to the end. ``start``: a source that
    switches on late."""
    dx, dt = grid.dx, 1.0 / (grid.fps * grid.substeps)
    c = grid.centres()
    r = c - np.asarray(grid.source)
    disk = (np.hypot(r[..., 0], r[..., 2]) <= grid.source_radius) & (r[..., 1] >= 0) & (r[..., 1] < 2 * dx)
    d, age = np.zeros(grid.shape), np.zeros(grid.shape)
    u = np.zeros(grid.shape + (3,))
    wind = np.asarray(effects.wind, float)
    out = [d.copy()]
    for t in range(1, frames):
        on = t >= start and (stop is None or t < stop)
        for _ in range(grid.substeps):
            if on:
                d[disk] += dt * grid.emission  # constant smoke flux, as a particle source
                age[disk] = 0.0
                u[disk] = [0.0, grid.inflow_speed, 0.0]
                u[disk, 0] += effects.omega * r[disk][:, 2]
                u[disk, 2] += -effects.omega * r[disk][:, 0]
            decay = np.exp(-age / effects.tau) if np.isfinite(effects.tau) else 1.0
            u[..., 1] += dt * grid.buoyancy * d * decay
            if effects.epsilon > 0:
                g = [np.gradient(u[..., a], dx) for a in range(3)]  # g[a][b] = d u_a / d x_b
                w = np.stack([g[2][1] - g[1][2], g[0][2] - g[2][0], g[1][0] - g[0][1]], -1)
                gn = _grad(np.linalg.norm(w, axis=-1), dx)
                n = gn / (np.linalg.norm(gn, axis=-1, keepdims=True) + 1e-9)
                u += dt * effects.epsilon * dx * np.cross(n, w)
            if effects.nu > 0:
                lap = sum(np.roll(u, 1, a) + np.roll(u, -1, a) for a in range(3)) - 6 * u
                u += dt * effects.nu * lap / (dx * dx)
            flow = u + wind
            u = _project(_advect(u, flow, dt, dx), dx)
            moved = _advect(d, flow, dt, dx)
            # semi-Lagrangian advection does not conserve mass; rescale to the smoke present before it
            d = moved * (d.sum() / max(moved.sum(), 1e-12)) * np.exp(-effects.rate * dt)
            age = _advect(age, flow, dt, dx) + dt
        out.append(d.copy())
    return np.asarray(out)


def write_scene(template_scene: Path, out: Path, density: np.ndarray, grid: Grid = Grid(),
                size: tuple = (34, 60), peak: float = 0.8, window: tuple | None = None) -> Path:
    """A scene (all views as ``input``, PNG frame folders) of ``density`` seen by the template's cameras
    (its views and ground truth) at ``size`` (width, height); the brightest pixel of all views is ``peak``.
    ``window``: the source's emission window [A, B) declared as ``source.window`` (None: not declared)."""
    tpl = json.loads((Path(template_scene) / "scene.json").read_text())
    cams = [(v["name"], v["camera"]) for v in tpl["views"]] + [(g["name"], g["camera"]) for g in tpl["ground_truth"]]
    pts = grid.centres().reshape(-1, 3)
    views, rendered = [], []
    for name, cd in cams:
        cam = Camera.from_dict(cd).resized(*size)
        sigma = cam.K[0, 0] * grid.dx / np.linalg.norm(cam.center - np.asarray(grid.source)) * 0.5
        rendered.append(np.stack([splat_points(cam, pts, f.ravel(), sigma) for f in density]))
        views.append({"name": name, "role": "input", "camera": cam.to_dict(), "video": f"videos/{name}"})
    scale = peak / max(max(r.max() for r in rendered), 1e-12)
    for view, imgs in zip(views, rendered):
        write_frames(out / view["video"], np.clip(imgs * scale, 0, 1)[..., None].astype(np.float32))
    hi = np.asarray(grid.lo) + np.asarray(grid.shape) * grid.dx
    scene = {"format": "fluidnexus-scene/1", "fps": grid.fps, "frame_count": len(density),
             "volume": {"min": list(grid.lo), "max": [float(x) for x in hi]},
             "source": {"center": list(grid.source), "radius": grid.source_radius}, "views": views,
             "ground_truth": []}
    if window is not None:
        scene["source"]["window"] = [int(w) if w is not None else None for w in window]
    (out / "scene.json").write_text(json.dumps(scene, indent=1))
    return out
