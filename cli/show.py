"""``fluidnexus render`` and ``fluidnexus eval``: look at a run and score it."""
from __future__ import annotations

import logging
from pathlib import Path

import click

from .options import arch_option, start_engine

log = logging.getLogger("fluidnexus")


@click.command()
@click.argument("run_dir", type=click.Path(path_type=Path))
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--views", "which", default="all", show_default=True,
              help="Comma-separated view names, 'all' (the scene's views) or 'ground-truth'.")
@click.option("--orbit", type=int, default=0, help="Also write orbit.mp4: N frames, one turn around the volume.")
@click.option("--compare", is_flag=True, help="Put the real ground-truth video beside the render.")
@click.option("--png", is_flag=True, help="Also write PNG frames.")
@click.option("--background", "background", default="plates", show_default=True,
              help="What the smoke is composited over: 'plates' (what each camera saw behind the smoke: its clean "
                   "plate or the run's static layer, else the scene's backdrop colour or black), 'black', or an "
                   "image FILE (resized to each camera).")
@click.option("--alpha", "with_alpha", is_flag=True, help="Also write the smoke's alpha matte (NAME_alpha.mp4).")
@arch_option
def render(run_dir: Path, out: Path, which: str, orbit: int, compare: bool, png: bool, background: str,
           with_alpha: bool, arch: str) -> None:
    """Write MP4 videos of a run from the scene's cameras or an orbit around the volume."""
    from fluidnexus.render_run import render_run
    from fluidnexus.runs import open_run

    run = open_run(run_dir)
    start_engine(arch)
    render_run(run, out, which, orbit, compare, png, background, with_alpha)


@click.command("eval")
@click.argument("run_dir", type=click.Path(path_type=Path))
@click.option("--json", "json_file", type=click.Path(path_type=Path, dir_okay=False), help="Write the scores here.")
@click.option("--lpips-weights", type=click.Path(path_type=Path, file_okay=False),
              help="Folder with local LPIPS AlexNet weights (see docs/evaluation.md); LPIPS is skipped without it.")
@click.option("--background", type=click.Choice(["plates", "black"]), default="plates", show_default=True,
              help="What the renders composite the smoke over: what each camera saw behind it (the run's static "
                   "layer, the scene's backdrop colour, or black), or black (to score smoke layers against footage "
                   "on black).")
@arch_option
def evaluate(run_dir: Path, json_file: Path | None, lpips_weights: Path | None, background: str, arch: str) -> None:
    """Score a run against the scene's ground-truth videos: novel views, re-simulation, divergence."""
    from fluidnexus.atomic import write_json
    from fluidnexus.evaluation import evaluate as score
    from fluidnexus.runs import open_run
    from fluidnexus.scenery.backdrop import black_backdrop

    run = open_run(run_dir)
    weights = None
    if lpips_weights is not None:
        from fluidnexus.lpips import load_weights

        weights = load_weights(lpips_weights)
    else:
        log.info("LPIPS skipped: no --lpips-weights folder given")
    start_engine(arch)
    result = score(run, weights, black_backdrop(run.channels) if background == "black" else None)
    if json_file is not None:
        write_json(json_file, result)
    nv, rs, dv = result["novel_view"], result["resimulation"], result["divergence"]
    res = result["resolution"]
    click.echo(f"frames {result['frames'][0]}:{result['frames'][1]} at {res['width']}x{res['height']}")
    for name, s in nv["per_view"].items():
        click.echo(f"  {name:10s} PSNR {s['psnr']:.2f} dB  SSIM {s['ssim']:.4f}"
                   + (f"  LPIPS {s['lpips']:.4f}" if s["lpips"] is not None else ""))
    _line("novel views", nv)
    _line("re-simulation", rs)
    in_smoke = dv["mean_abs_in_smoke"]
    click.echo(f"divergence     mean |div V| {dv['mean_abs']:.4g} 1/s"
               + (f", in smoke {in_smoke:.4g} 1/s" if in_smoke is not None else ""))
    pred = result.get("prediction")
    if pred is not None:
        click.echo(f"prediction after frame {pred['start_frame']}, frames {pred['frames'][0]}:{pred['frames'][1]}")
        _line("  input views", pred["input_view"])
        _line("  repeat last", pred["repeat_last_input_view"])
        _line("  novel views", pred["novel_views"])
    if json_file is not None:
        log.info("scores: %s", json_file)


def _line(label: str, scores: dict) -> None:
    """One line of mean scores (a score that could not be computed, e.g. no view, shows as -)."""
    def fmt(v, digits):
        return "-" if v is None else f"{v:.{digits}f}"

    click.echo(f"{label:15s}PSNR {fmt(scores['psnr'], 2)} dB  SSIM {fmt(scores['ssim'], 4)}"
               + (f"  LPIPS {scores['lpips']:.4f}" if scores.get("lpips") is not None else ""))
