"""One step of one scene, as it runs in a Ray worker (or any process that sees the batch folder).

:func:`run_step` checks that the batch folder is the driver's (shared storage), clears what an unfinished earlier
attempt of the step left where the step cannot continue it, runs the step (``recon`` continues from its
last checkpoint), and writes the step's completion marker last, atomically. A step is complete exactly when its
marker exists with the same arguments, so a killed driver or worker loses nothing that finished.
"""
from __future__ import annotations

import logging
import os
import shutil
import socket
import time
from dataclasses import dataclass
from pathlib import Path

from ..atomic import read_json, write_json
from ..errors import InputError, RunError
from .steps import PREPARE, Layout, StepCommands, step_args

log = logging.getLogger("fluidnexus")
PROBE = ".batch-probe"  # a file the driver writes into the batch folder; every task reads it back


@dataclass(frozen=True)
class StepJob:
    """What a worker needs to run one step: all plain data, so Ray sends it as it is."""

    batch_dir: str
    probe: str  # the driver's token in batch_dir/.batch-probe
    scene: str
    step: str
    source: dict
    options: list[str]
    arch: str  # "cpu" or "cuda" (a task given a GPU)
    threads: int  # CPU threads of the engine (the task's CPUs)

    @property
    def layout(self) -> Layout:
        return Layout(Path(self.batch_dir) / "scenes" / self.scene)


def check_shared_storage(batch_dir: str | Path, probe: str) -> None:
    """Raise unless this process sees the driver's batch folder (same token in the probe file)."""
    path = Path(batch_dir) / PROBE
    try:
        seen = path.read_text().strip()
    except OSError:
        seen = None
    if seen != probe:
        raise InputError(batch_dir, None, f"node {socket.gethostname()} cannot see the batch folder the driver "
                                          "writes (every node needs it at the same path on shared storage; "
                                          "see docs/batch.md)")


def completed(layout: Layout, step: str, options: list[str]) -> dict | None:
    """The step's marker when it finished with these options (None: it has to run)."""
    marker = layout.marker(step)
    if not marker.is_file():
        return None
    try:
        data = read_json(marker, "step marker")
    except InputError:
        return None
    return data if data.get("options") == options else None


def run_step(job: StepJob, commands: StepCommands) -> dict:
    """Run one step; return ``{"status": "ok", "seconds": ...}`` or ``{"status": "failed", "error": one line}``.

    Bad input (and a run that stopped on its own) fails the scene at once; any other exception propagates so that
    Ray retries the task (a retry continues where the first attempt stopped).
    """
    check_shared_storage(job.batch_dir, job.probe)
    layout = job.layout
    layout.root.mkdir(parents=True, exist_ok=True)
    os.environ["TI_CPU_MAX_NUM_THREADS"] = str(max(1, job.threads))  # read by ti.init in this fresh worker
    handler = _log_to(layout.log)
    started = time.time()
    try:
        _clear_unfinished(job, layout)
        copy = job.step == PREPARE and job.source["kind"] == "scene"
        args = ["copy", job.source["scene"]] if copy else step_args(job.step, job.source, job.options, layout,
                                                                      job.arch, job.threads)
        log.info("batch: %s %s on %s: %s", job.scene, job.step, socket.gethostname(), " ".join(args))
        try:
            if copy:
                copy_scene(Path(job.source["scene"]), layout.scene)
            else:
                commands.run(job.step, args)
        except (InputError, RunError) as err:
            message = str(err)
            log.info("batch: %s %s failed: %s", job.scene, job.step, message)
            return {"status": "failed", "error": f"{job.step}: {message}"}
        seconds = round(time.time() - started, 3)
        write_json(layout.marker(job.step), {"step": job.step, "options": job.options, "args": args,
                                             "seconds": seconds, "started": started, "finished": time.time(),
                                             "host": socket.gethostname(), "arch": job.arch})
        log.info("batch: %s %s done in %.1f s", job.scene, job.step, seconds)
        return {"status": "ok", "seconds": seconds}
    finally:
        log.removeHandler(handler)
        handler.close()


def _clear_unfinished(job: StepJob, layout: Layout) -> None:
    """Remove what an unfinished attempt left where the step starts from scratch (recon resumes instead)."""
    layout.marker(job.step).unlink(missing_ok=True)
    partial = layout.partial_output(job.step)
    if partial is not None and partial.exists():
        shutil.rmtree(partial)
    if job.step == "recon" and layout.run.exists() and not (layout.run / "config.json").exists():
        shutil.rmtree(layout.run)  # stopped before its settings were written: no frame was finished


def copy_scene(src: Path, dest: Path) -> None:
    """Copy a scene folder's JSON files and link its footage, so synth and refine never write into ``src``."""
    from ..atomic import atomic_dir
    from ..scene import load_scene

    load_scene(src)  # a bad scene folder fails here, naming its file and field
    with atomic_dir(dest) as tmp:
        for item in src.rglob("*"):
            target = tmp / item.relative_to(src)
            if item.is_dir():
                target.mkdir(parents=True, exist_ok=True)
            elif item.suffix == ".json":
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(item, target)
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                target.symlink_to(item.resolve())


def _log_to(path: Path) -> logging.Handler:
    """Append the library's log lines of this step to the scene's log.txt."""
    handler = logging.FileHandler(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
    handler.setLevel(logging.INFO)
    log.setLevel(logging.INFO)
    log.addHandler(handler)
    return handler
