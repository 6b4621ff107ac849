"""``fluidnexus export``: hand a run to other tools (splat viewers, ParaView, numpy)."""
from __future__ import annotations

import logging
from pathlib import Path

import click

from fluidnexus.errors import InputError
from fluidnexus.world_frame import SourceFrame

from .options import arch_option, start_engine

log = logging.getLogger("fluidnexus")


@click.command()
@click.argument("run_dir", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["ply", "vti", "vdb", "npz"]), required=True)
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--voxel", type=float, default=0.01, show_default=True, help="Grid spacing of vti/vdb/npz fields, m.")
@click.option("--frame", "frame_name", type=click.Choice(["scene", "source"]), default="scene", show_default=True,
              help="Coordinates of the files: the scene's world (metres, +y up), or the world of the file the scene "
                   "was imported from (its axes and unit; scene.json source_frame).")
@arch_option
def export(run_dir: Path, fmt: str, out: Path, voxel: float, frame_name: str, arch: str) -> None:
    """One file per frame: 3DGS PLY (splat viewers), VTK ImageData .vti (ParaView), OpenVDB .vdb (Blender, Houdini)
    or raw .npz; PLY also writes the run's static layer (backdrop, obstacles) as static.ply when it has one."""
    from fluidnexus.export.fields import sample_fields
    from fluidnexus.export.npz import write_frame_npz
    from fluidnexus.export.ply import write_gaussians_ply
    from fluidnexus.export.vdb import write_vdb
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
        elif fmt == "vdb":
            write_vdb(path, origin, spacing, fields)
        else:
            write_frame_npz(path, state, origin, spacing, fields)
    log.info("wrote %d %s files to %s", len(run.frames), fmt, out)
