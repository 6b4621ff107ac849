"""``fluidnexus batch``: run the pipeline over the scenes of a manifest on Ray (docs/batch.md)."""
from __future__ import annotations

import logging
import time
from pathlib import Path

import click

from fluidnexus.errors import InputError

log = logging.getLogger("fluidnexus")


@click.command()
@click.argument("manifest", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--out", required=True, type=click.Path(path_type=Path, file_okay=False),
              help="Batch folder: scenes/NAME/, results.csv, results.md, results.png, batch.json.")
@click.option("--address", help="Join a running Ray cluster: 'auto' or ray://HOST:PORT (default: start Ray here).")
@click.option("--resume", is_flag=True,
              help="Continue a batch in --out (re-running into the same folder does the same; this flag only "
                   "insists that --out holds an earlier batch).")
@click.option("--cpus-per-scene", type=click.FloatRange(min=0, min_open=True), default=1.0, show_default=True,
              help="CPUs of each task (the engine uses that many threads).")
@click.option("--gpus-per-scene", type=click.FloatRange(min=0), default=0.0, show_default=True,
              help="GPUs of each task; a task with a GPU runs with --arch cuda.")
def batch(manifest: Path, out: Path, address: str | None, resume: bool, cpus_per_scene: float,
          gpus_per_scene: float) -> None:
    """Run the steps of every scene in MANIFEST, scenes in parallel, and tabulate the scores.

    \b
    fluidnexus batch scenes.toml --out batch/                      # local Ray, this machine's cores
    fluidnexus batch scenes.toml --out /shared/batch --address auto --gpus-per-scene 1
    Exit code: 0 all scenes finished, 1 some failed (results.md says which), 2 bad manifest or options.
    """
    from fluidnexus.batch.manifest import load_manifest
    from fluidnexus.batch.results import write_record, write_results
    from fluidnexus.batch.runner import Resources, require_ray, run_batch

    from .batch_steps import CommandSteps

    require_ray()
    commands = CommandSteps()
    spec = load_manifest(manifest, commands)
    if resume and not (out / "batch.json").is_file() and not (out / "scenes").is_dir():
        raise InputError(out, None, "--resume: no earlier batch here")
    out.mkdir(parents=True, exist_ok=True)
    started = time.time()
    options = {"address": address, "cpus_per_scene": cpus_per_scene, "gpus_per_scene": gpus_per_scene}
    states, cluster = run_batch(spec, out, address, Resources(cpus_per_scene, gpus_per_scene),
                                lambda s: write_results(s, out), commands)
    stats = write_results(states, out)
    write_record(out, spec, cluster, options, states, started, stats)
    failed = [s.job.name for s in states if s.status != "ok"]
    log.info("%d of %d scenes finished; table: %s", len(states) - len(failed), len(states), out / "results.md")
    if failed:
        click.echo(f"failed: {', '.join(failed)} (errors in {out / 'results.md'})", err=True)
        raise click.exceptions.Exit(1)
