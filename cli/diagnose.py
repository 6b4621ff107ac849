"""``fluidnexus diagnose``: what the PBF model gets wrong on measured footage, its cause, and the gain."""
from __future__ import annotations

import click

from fluidnexus.errors import InputError
from fluidnexus.runs import open_run
from fluidnexus.video import parse_frame_range

from .options import arch_option, max_memory_option, start_engine


def _window(text: str, name: str) -> tuple[int, int]:
    s = parse_frame_range(text)
    if s.start is None or s.stop is None or s.start < 0 or s.stop <= s.start:
        raise InputError(None, name, f"expected A:B with 0 <= A < B, got {text!r}")
    return int(s.start), int(s.stop)


@click.command()
@click.argument("source", type=click.Path(exists=True, file_okay=False))
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--train-frames", default="0:60", show_default=True, help="Training window A:B (half-open).")
@click.option("--validate-frames", default="60:90", show_default=True, help="Validation window C:D (half-open).")
@click.option("--height", default=48, show_default=True, type=click.IntRange(16, 512),
              help="Observation image height [px].")
@click.option("--spacing", default=None, type=click.FloatRange(0, min_open=True),
              help="Particle spacing of the simulated plume [m]; default 0.02 m x the scene's length scale "
                   "(docs/scale.md).")
@click.option("--evals", default=20, show_default=True, type=click.IntRange(3, 200),
              help="Rollouts per fit (Nelder-Mead evaluations).")
@click.option("--jobs", default=None, type=click.IntRange(1, 64),
              help="Fits run side by side in this many processes (the report does not depend on it); default on "
                   "the CPU: the cores this process may use, at most 6; on a GPU: 1.")
@max_memory_option
@arch_option
def diagnose(source, out, train_frames, validate_frames, height, spacing, evals, jobs, max_memory, arch):
    """Find what the simulation gets wrong on the measured footage of SOURCE (a scene, or a run folder whose
    scene is used and whose found obstacles the plume flows around): choose the base structure (the paper's gas,
    or the gas in ambient air), name the cause among the candidate extensions, and measure the validation gains.
    Over a backdrop (a scene with clean plates) it fits the smoke's opacity over each view's plate."""
    from pathlib import Path

    from fluidnexus.diagnose import diagnose as run_diagnose
    from fluidnexus.diagnose.parallel import plan_jobs
    from fluidnexus.memory import parse_limit

    scene_dir, run_dir = Path(source), None
    if (scene_dir / "run.json").exists():
        run_dir, scene_dir = scene_dir, open_run(scene_dir).scene_dir
    arch = start_engine(arch)
    jobs = plan_jobs(jobs, arch, parse_limit(max_memory))
    report = run_diagnose(scene_dir, out, _window(train_frames, "--train-frames"),
                          _window(validate_frames, "--validate-frames"), height=height, spacing=spacing,
                          maxfev=evals, jobs=jobs, run_dir=run_dir)
    g, st, em = report["finding"]["gain"], report["structure"], report["emission"]
    stop = "the end" if em["window"][1] is None else f"frame {em['window'][1]} (exclusive)"
    click.echo(f"emission: from frame {em['window'][0]} to {stop} (from the {em['from']})")
    click.echo(f"structure: {st['name']} (validation image error {st['gain']['before']:.4f} -> "
               f"{st['gain']['after']:.4f})")
    click.echo(f"finding: {report['finding']['effect']} {report['finding']['params']} "
               f"(validation image error {g['before']:.4f} -> {g['after']:.4f}); report in {out}/report.md")
