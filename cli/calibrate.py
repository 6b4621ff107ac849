"""``fluidnexus calibrate``: make a scene folder from camera data in one of six ways."""
from __future__ import annotations

from pathlib import Path

import click

from fluidnexus.calibrate.assemble import PROTOCOLS


@click.command()
@click.option("--from-pinf", "from_pinf", type=click.Path(path_type=Path), help="PINF/HyFluid/ScalarFlow info.json.")
@click.option("--from-nerf", "from_nerf", type=click.Path(path_type=Path), help="NeRF transforms.json.")
@click.option("--from-colmap", "from_colmap", type=click.Path(path_type=Path), help="COLMAP sparse model folder.")
@click.option("--images", is_flag=True,
              help="Structure from motion on the PATHS that follow: images or videos, one per rig camera, or one "
                   "hand-held sweep video.")
@click.option("--video", type=click.Path(path_type=Path), help="A single video: build an arc rig around it.")
@click.option("--sample", type=str, help="An embedded sample by name (scalarflow).")
@click.option("--protocol", type=click.Choice(sorted(PROTOCOLS)), default="single-view", show_default=True,
              help="View roles for --sample.")
@click.option("--input", "input_names", help="Comma-separated input view names.")
@click.option("--novel", "novel_names", help="Comma-separated novel view names.")
@click.option("--ground-truth", "gt_names", help="Comma-separated ground-truth view names.")
@click.option("--media", type=click.Path(path_type=Path, file_okay=False),
              help="Folder with the footage, matched to cameras by file stem (--from-colmap, --images).")
@click.option("--scale-distance", help="NAME_A,NAME_B,METRES: metric scale from two camera centres (--images).")
@click.option("--fov-deg", type=float, help="Horizontal field of view of --video, degrees.")
@click.option("--rig", type=click.Choice(["arc"]), default="arc", show_default=True, help="Rig shape for --video.")
@click.option("--plate", type=click.Path(path_type=Path),
              help="An image of --video's empty backdrop (the clean plate), written into the scene as "
                   "'fluidnexus background --plate' would (without it, run fluidnexus background later).")
@click.option("--views", type=int, default=5, show_default=True, help="Cameras on the arc, the input included.")
@click.option("--arc-deg", type=float, default=120.0, show_default=True, help="Angle the arc spans.")
@click.option("--distance", type=float,
              help="Camera-to-plume-axis distance of --video's arc rig, m (default 1.2; with --tilt-deg or "
                   "--horizon-row it follows from the height and the tilt).")
@click.option("--camera-height", type=float,
              help="--video: the camera's height above the floor the plume stands on, m (the floor is the source's "
                   "level; default: the source at 90 % of the image height; required with --tilt-deg, --horizon-row).")
@click.option("--tilt-deg", type=float,
              help="--video: the camera's pitch down from level, degrees (0-90): the scene gets a floor, the arc "
                   "stands around where the centre ray meets it, and synth finds the plume's foot on it.")
@click.option("--horizon-row", type=float,
              help="--video: the image row of the horizon (pixels from the top; above the centre row), instead of "
                   "--tilt-deg: tan(tilt) = (H/2 - row) / fy.")
@click.option("--source", metavar="CX,CY,CZ,R",
              help="--from-pinf, --sample: the smoke inflow's disk (centre and radius) in the imported file's own "
                   "frame and unit. A PINF capture declares none: without it synth and recon find the inflow in the "
                   "footage (docs/calibration.md).")
@click.option("--source-radius", type=float, default=None,
              help="Radius of the smoke inflow, m (default 0.025 m x the scene's length scale, docs/scale.md).")
@click.option("--fps", type=float, help="Frame rate where the footage does not say (image folders).")
@click.option("--metres-per-unit", type=float,
              help="Length of one unit of the imported file's world, in metres (--from-pinf, --from-nerf, "
                   "--from-colmap; default 1). The scene is written in metres, +y up.")
@click.option("--obstacle", "obstacles", multiple=True,
              help="A rigid obstacle in the scene: sphere:CX,CY,CZ,R or mesh:FILE (a closed mesh trimesh reads), "
                   "in the imported file's own frame and unit (converted like its cameras). Repeatable.")
@click.option("--link", is_flag=True, help="Symlink the footage into the scene instead of copying it.")
@click.option("--to-pinf", type=click.Path(path_type=Path, dir_okay=False),
              help="Also write the scene as a PINF info.json here (for PINF/HyFluid baselines).")
@click.option("--overwrite", is_flag=True, help="Replace an existing scene folder.")
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False), help="Scene folder to write.")
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
def calibrate(out: Path, overwrite: bool, to_pinf: Path | None, paths: tuple[Path, ...], **opts) -> None:
    """Make a scene (cameras, roles, footage) from PINF, NeRF, COLMAP, images (SfM), one video, or a sample.

    \b
    fluidnexus calibrate --from-pinf info.json --input train02 \\
        --novel train00,train01,train03,train04 --ground-truth train00,train01,train03,train04 --out scene
    fluidnexus calibrate --sample scalarflow --protocol four-view --out scene
    fluidnexus calibrate --images cam0.mp4 cam1.mp4 cam2.mp4 --scale-distance cam0,cam2,0.9 --out scene
    fluidnexus calibrate --images cam*.png --media footage/ --out scene
    fluidnexus calibrate --video plume.mp4 --fov-deg 60 --rig arc --views 5 --arc-deg 120 --out scene
    fluidnexus calibrate --video plume.mp4 --plate empty_backdrop.png --fov-deg 60 --out scene
    fluidnexus calibrate --video plume.mp4 --fov-deg 60 --camera-height 1.1 --tilt-deg 25 --out scene
    """
    from fluidnexus.calibrate.make_scene import make_scene

    make_scene(out, paths, opts, overwrite, to_pinf)
