"""``generate(seed, out_dir, size)``: draw a scene from the seed (``spec.draw``), simulate its smoke
(``smoke_solver``), render every camera (``raymarch``) and write it as a PINF capture with its truth (``pinf_out``).

Cameras: ``train00``-``train03`` (still; the inputs of the four-view protocol) and ``test00`` (the held-out camera,
between train01 and train02, moving in some scenes). Protocols written into truth.json:
four-view: train00-03 in, test00 held out; single-video: train01 in, train00, train02 and train03 novel (``synth``
writes them), test00 held out.
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import pinf_out
from .geometry import PinholeCamera
from .raymarch import render, static_image
from .smoke_solver import Grid, Inflow, simulate
from .spec import SceneSpec, draw
from .splits import split_of

INPUTS = ("train00", "train01", "train02", "train03")
HELD_OUT = "test00"
TRUTH_FORMAT = "fluidnexus-scenegen-truth/1"


def camera_at(spec: SceneSpec, azimuth_deg: float, elevation_deg: float) -> PinholeCamera:
    """A rig camera at ``distance`` from the target, at an azimuth (from +z towards +x) and an elevation."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    eye = np.asarray(spec.rig.target) + spec.rig.distance * np.array(
        [math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)])
    return PinholeCamera.look_at(spec.width, spec.height, spec.rig.fov_deg, eye, spec.rig.target)


def cameras(spec: SceneSpec) -> dict[str, list[PinholeCamera]]:
    """Name -> its camera per frame (one entry: a still camera)."""
    rig = spec.rig
    out = {name: [camera_at(spec, az, rig.elevation_deg)] for name, az in zip(INPUTS, rig.azimuths)}
    if rig.moving:
        azs = np.linspace(rig.held_out_az, rig.held_out_az_end, spec.frames)
        out[HELD_OUT] = [camera_at(spec, az, rig.held_out_elevation_deg) for az in azs]
    else:
        out[HELD_OUT] = [camera_at(spec, rig.held_out_az, rig.held_out_elevation_deg)]
    return out


def simulate_scene(spec: SceneSpec):
    """(grid, density [T, nx, ny, nz] (1 in the source cells), flow): the smoke of ``spec``."""
    grid = Grid.over(spec.lo, spec.hi, spec.cells)
    s = spec.source
    inflow = Inflow(s.center, s.radius, s.direction, s.speed, s.window, s.buoyancy)
    flow = simulate(grid, inflow, spec.frames, spec.fps, spec.bodies, spec.vorticity, seed=spec.seed)
    return grid, flow.density, flow


def extinction(spec: SceneSpec, grid: Grid) -> float:
    """kappa: the optical depth across the source's diameter (at least a cell) at the source's density (1) is
    the scene's ``tau``."""
    return spec.smoke.tau / (2.0 * max(spec.source.radius, grid.dx))


def truth(spec: SceneSpec, grid: Grid, flow, kappa: float) -> dict:
    """What the table scores against, in the scene's world (metres, +y up: what calibrate writes into scene.json
    with ``--metres-per-unit``), and the file's frame for the user."""
    s, rig = spec.source, spec.rig
    mpu = spec.metres_per_unit
    return {
        "format": TRUTH_FORMAT, "seed": spec.seed, "size": spec.size, "split": split_of(spec.seed),
        "frame": "scene: metres, +y up (calibrate --from-pinf info.json --metres-per-unit M)",
        "file": {"unit": spec.unit, "metres_per_unit": mpu, "up": spec.up,
                 "rotation_to_file": pinf_out.TO_FILE[spec.up].tolist(),
                 "source_center": pinf_out.to_file(s.center, spec.up, mpu).tolist(),
                 "source_radius": s.radius / mpu},
        "calibrate_args": ["--metres-per-unit", repr(mpu)],
        "fps": spec.fps, "frames": spec.frames, "width": spec.width, "height": spec.height,
        "volume": {"min": list(spec.lo), "max": list(spec.hi)}, "length_m": spec.length,
        "source": {"kind": s.kind, "center": list(s.center), "radius": s.radius, "direction": list(s.direction),
                   "speed": s.speed, "window": [s.window[0], s.window[1]], "buoyancy": s.buoyancy},
        "obstacles": [b.to_dict() for b in spec.obstacles],
        "set": [b.to_dict() for b in spec.set_pieces],
        "backdrop": {"kind": spec.backdrop.kind, "color": list(spec.backdrop.color) if spec.backdrop.room is None
                     else None, "room": spec.backdrop.room, "plates": "plates/NAME.png"},
        "needs_plates": spec.backdrop.kind != "black" or bool(spec.obstacles),
        "smoke": {"mode": spec.smoke.mode, "color": list(spec.smoke.color), "tau": spec.smoke.tau,
                  "kappa": kappa},
        "cameras": {"layout": rig.layout, "span_deg": rig.span_deg, "elevation": rig.elevation,
                    "elevation_deg": rig.elevation_deg, "fov_deg": rig.fov_deg, "distance": rig.distance,
                    "inputs": list(INPUTS), "held_out": HELD_OUT, "held_out_moving": rig.moving},
        "protocols": {"four-view": {"input": ",".join(INPUTS), "ground_truth": HELD_OUT},
                      "single-view": {"input": "train01", "novel": "train00,train02,train03",
                                      "ground_truth": HELD_OUT}},
        "grid": {"lo": list(grid.lo), "dx": grid.dx, "shape": list(grid.shape)},
        "mass": {"emitted": flow.emitted, "outflow": flow.outflow,
                 "final": float(flow.density[-1].sum()),
                 "step_factor_range": [min(flow.mass_factors, default=1.0), max(flow.mass_factors, default=1.0)]},
        "vorticity": spec.vorticity,
    }


def info_json(spec: SceneSpec, cams: dict) -> dict:
    mpu = spec.metres_per_unit
    entry = {name: pinf_out.video_entry(name, c, spec.fps, spec.frames, spec.up, mpu) for name, c in cams.items()}
    info = {"train_videos": [entry[n] for n in INPUTS], "test_videos": [entry[HELD_OUT]], "val_videos": [],
            **pinf_out.volume_fields(spec.lo, spec.hi, spec.up, mpu),
            "near": 0.2 * spec.rig.distance / mpu, "far": 3.0 * spec.rig.distance / mpu}
    if spec.up == "Z":
        info["rot"] = "Z"
    if spec.backdrop.kind in ("black", "white"):
        info["frame_bkg_color"] = list(spec.backdrop.color)
    return info


def generate(seed: int, out_dir, size: str = "small", **overrides) -> Path:
    """Write the scene of ``seed`` into ``out_dir`` (info.json, train00-03.mp4, test00.mp4, plates/, truth.json);
    return the info.json path. The same seed and size always write the same scene.

    ``overrides`` replace fields of the drawn ``SceneSpec`` (tests: ``unit="mm"``, ``up="Z"`` write the same
    scene in another unit or up axis)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec = replace(draw(seed, size), **overrides)
    grid, density, flow = simulate_scene(spec)
    kappa = extinction(spec, grid)
    cams = cameras(spec)
    for name, per_frame in cams.items():
        if len(per_frame) == 1:
            video = render(per_frame[0], density, grid, kappa, spec.smoke.color, spec.bodies, spec.backdrop)
            pinf_out.write_plate(out / "plates" / f"{name}.png", static_image(per_frame[0], spec.bodies, spec.backdrop))
        else:
            video = np.concatenate([render(c, density[t:t + 1], grid, kappa, spec.smoke.color, spec.bodies,
                                           spec.backdrop) for t, c in enumerate(per_frame)])
        pinf_out.write_mp4(out / f"{name}.mp4", video, spec.fps)
    pinf_out.write_json(out / "info.json", info_json(spec, cams))
    pinf_out.write_json(out / "truth.json", truth(spec, grid, flow, kappa))
    return out / "info.json"
