"""``fluidnexus demo``: the main job end to end on the embedded ScalarFlow sample, with no arguments."""
from __future__ import annotations

import logging
import time
from pathlib import Path

import click

from .options import arch_option

log = logging.getLogger("fluidnexus")

# Reduced settings that finish in minutes on a 2-core CPU (the full defaults are in docs/reconstruction.md): every
# step at half the sample's resolution (synth and refine too, so that they make the videos recon reads, not four
# times the pixels), recon on frames 0-39 with fewer iterations.
DEMO_SCALE = ["--resolution", "0.5"]
DEMO_RECON = ["--frames", "0:40", *DEMO_SCALE, "--init-iters", "150", "--dynamics-iters", "12", "--appearance-iters",
              "8", "--stabilization-steps", "10"]


@click.command()
@click.option("--out", type=click.Path(path_type=Path, file_okay=False), default=Path("demo-out"),
              show_default=True, help="Where the scene, the run, the videos and the scores go.")
@click.option("--overwrite", is_flag=True, help="Replace an earlier demo in --out.")
@arch_option
@click.pass_context
def demo(ctx: click.Context, out: Path, overwrite: bool, arch: str) -> None:
    """The paper's single-video protocol on the embedded ScalarFlow sample, end to end.

    The middle camera (train02) is the only input. The four other cameras get synthesised videos (axisym, then the
    temporal refiner), the smoke is reconstructed from all five, and the real videos of the four other cameras,
    never seen by the pipeline, are used only for the comparison videos and the scores.
    """
    from fluidnexus.errors import InputError

    from .calibrate import calibrate
    from .recon import recon
    from .refine import refine
    from .show import evaluate, render
    from .synth import synth

    if out.exists() and any(out.iterdir()) and not overwrite:
        raise InputError(out, None, "already exists and is not empty (use --overwrite)")
    tic = time.perf_counter()
    scene, run, videos = out / "scene", out / "run", out / "videos"
    steps = [
        ("calibrate the sample (train02 in, four novel cameras)", calibrate,
         ["--sample", "scalarflow", "--protocol", "single-view", "--out", str(scene), "--overwrite"]),
        ("synthesise the four novel views (axisym)", synth, [str(scene), *DEMO_SCALE]),
        ("refine them (temporal)", refine, [str(scene), *DEMO_SCALE]),
        ("reconstruct from the input and the synthesised views", recon,
         [str(scene), "--out", str(run), "--arch", arch, *DEMO_RECON]),
        ("render the held-out cameras beside the real footage", render,
         [str(run), "--out", str(videos), "--compare", "--orbit", "60", "--arch", arch]),
        ("score against the held-out real videos", evaluate,
         [str(run), "--json", str(out / "eval.json"), "--arch", arch]),
    ]
    if overwrite and run.exists():
        import shutil

        shutil.rmtree(run)
    for k, (title, command, args) in enumerate(steps, start=1):
        log.info("[%d/%d] %s", k, len(steps), title)
        ctx.invoke(command, **_parse(command, args))
    click.echo(f"\ndemo finished in {time.perf_counter() - tic:.0f} s")
    click.echo(f"  comparison videos: {videos}/train0X_compare.mp4 (left: reconstruction, right: real, unseen)")
    click.echo(f"  orbit video:       {videos / 'orbit.mp4'}")
    click.echo(f"  scores:            {out / 'eval.json'}")


def _parse(command: click.Command, args: list[str]) -> dict:
    """Command-line words -> the keyword arguments of ``command``'s callback (defaults filled in)."""
    with command.make_context(command.name, list(args)) as sub:
        return dict(sub.params)
