"""``fluidnexus export``: hand a run to other tools (splat viewers, ParaView, numpy)."""
from __future__ import annotations

import logging
from pathlib import Path

import click
import numpy as np

from fluidnexus.errors import InputError
from fluidnexus.world_frame import SourceFrame

from .options import arch_option, start_engine

log = logging.getLogger("fluidnexus")


def sample_fields(state, volume, voxel: float, h: float, frame=None):
    """Density and velocity of a state's physical particles on a grid of ``voxel`` metres over ``volume``.

    With ``frame`` (a :class:`~fluidnexus.world_frame.SourceFrame`) the grid is laid out in that frame instead:
    over the volume's box there, ``voxel`` metres converted to its unit, and the fields are in its units.

    Returns (origin, spacing, {"density": [nz, ny, nx], "velocity": [nz, ny, nx, 3]}).
    """
    import torch

    from fluidnexus import engine
    from fluidnexus.export.vti import grid_points

    lo, hi = np.asarray(volume.min), np.asarray(volume.max)
    if frame is not None:
        corners = frame.from_scene([np.where(np.array(p, bool), hi, lo) for p in np.ndindex(2, 2, 2)])
        lo, hi, voxel = corners.min(0), corners.max(0), float(frame.length_from_scene(voxel))
    counts = np.maximum(2, np.round((hi - lo) / voxel).astype(int) + 1)
    spacing = (hi - lo) / (counts - 1)
    shape = (int(counts[2]), int(counts[1]), int(counts[0]))
    pts = grid_points(lo, spacing, shape).reshape(-1, 3)
    if frame is not None:
        pts = frame.to_scene(pts)
    query = engine.FieldQuery(max(1, state.num_physical), len(pts), h)
    query.forward(torch.as_tensor(pts), torch.as_tensor(state.physical_positions, dtype=torch.float64),
                  torch.as_tensor(state.physical_velocities, dtype=torch.float64))
    density = query.density().numpy().reshape(shape)
    velocity = query.velocity().numpy().reshape(*shape, 3)
    if frame is not None:
        density, velocity = frame.density_from_scene(density), frame.from_scene(velocity)
    return lo, spacing, {"density": density, "velocity": velocity}


@click.command()
@click.argument("run_dir", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["ply", "vti", "npz"]), required=True)
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--voxel", type=float, default=0.01, show_default=True, help="Grid spacing of vti/npz fields, m.")
@click.option("--frame", "frame_name", type=click.Choice(["scene", "source"]), default="scene", show_default=True,
              help="Coordinates of the files: the scene's world (metres, +y up), or the world of the file the scene "
                   "was imported from (its axes and unit; scene.json source_frame).")
@arch_option
def export(run_dir: Path, fmt: str, out: Path, voxel: float, frame_name: str, arch: str) -> None:
    """One file per frame: 3DGS PLY (splat viewers), VTK ImageData .vti (ParaView) or raw .npz; PLY also writes the
    run's static layer (backdrop, obstacles) as static.ply when it has one."""
    from fluidnexus.export.npz import write_frame_npz
    from fluidnexus.export.ply import write_gaussians_ply
    from fluidnexus.export.vti import write_vti
    from fluidnexus.progress import track
    from fluidnexus.runs import open_run
    from fluidnexus.scenery.static_layer import STATIC_FILE, load_static

    if not voxel > 0:
        raise InputError(None, "--voxel", f"must be > 0, got {voxel}")
    run = open_run(run_dir)
    scene = run.scene(check_videos=False)
    volume = scene.volume
    frame = (scene.source_frame or SourceFrame.identity()) if frame_name == "source" else None
    if fmt != "ply":
        if volume is None:
            raise InputError(run.scene_dir / "scene.json", "volume", f"--format {fmt} needs the scene's volume")
        start_engine(arch)
    h = run.config["solver"]["h"]
    if fmt == "ply" and (run.root / STATIC_FILE).is_file():  # the static layer beside the frames
        static = load_static(run.root).as_state(run.frames[0])
        write_gaussians_ply(out / "static.ply", static if frame is None else frame.state_from_scene(static),
                            viewer_frame=frame is None)
    for t in track(run.frames, f"export {fmt}"):
        state = run.state(t)
        path = out / f"{t:06d}.{fmt}"
        if fmt == "ply":
            write_gaussians_ply(path, state if frame is None else frame.state_from_scene(state),
                                viewer_frame=frame is None)
            continue
        origin, spacing, fields = sample_fields(state, volume, voxel, h, frame)
        if frame is not None:
            state = frame.state_from_scene(state)
        if fmt == "vti":
            write_vti(path, origin, spacing, fields)
        else:
            write_frame_npz(path, state, origin, spacing, fields)
    log.info("wrote %d %s files to %s", len(run.frames), fmt, out)
