"""The Ray driver: each scene's steps as Ray tasks, in order per scene, scenes in parallel.

Without an address a local Ray instance starts with this machine's cores (small object store, no dashboard) and
stops at the end; with ``--address auto`` or ``ray://host:port`` the batch joins a running cluster. Only paths and
small dicts travel between machines: every node must see the batch folder and the inputs at the same paths.
"""
from __future__ import annotations

import logging
import os
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..progress import progress
from .manifest import Manifest, SceneJob
from .steps import PREPARE, Layout, StepCommands
from .tasks import PROBE, StepJob, completed, run_step

log = logging.getLogger("fluidnexus")
INSTALL = "pip install 'fluidnexus[cluster]'"
OBJECT_STORE_BYTES = 128 * 1024 ** 2  # only small dicts go through it; the machine's memory stays for the steps
RETRIES = 1  # a task whose worker died or that crashed runs once more, continuing where it stopped


def require_ray():
    """The ray module, or an InputError that says how to install it."""
    try:
        import ray
    except ImportError:
        raise InputError(None, "batch", f"needs Ray, which is not installed: {INSTALL}") from None
    return ray


@dataclass
class SceneState:
    """Where one scene is: the steps still to run, seconds of each finished step, its error."""

    job: SceneJob
    todo: list[str]
    seconds: dict[str, float] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    status: str = "waiting"  # waiting, running, ok, failed
    error: str | None = None


@dataclass(frozen=True)
class Resources:
    cpus: float
    gpus: float

    @property
    def arch(self) -> str:
        return "cuda" if self.gpus > 0 else "cpu"


def plan(manifest: Manifest, out: Path) -> list[SceneState]:
    """Each scene's steps, with the steps already complete in ``out`` (same options) taken off the front."""
    states = []
    for job in manifest.scenes:
        layout = Layout(out / "scenes" / job.name)
        state = SceneState(job, [PREPARE, *job.steps])
        while state.todo:
            marker = completed(layout, state.todo[0], job.options[state.todo[0]])
            if marker is None:
                break
            state.seconds[state.todo[0]] = marker["seconds"]
            state.skipped.append(state.todo.pop(0))
        if not state.todo:
            state.status = "ok"
        states.append(state)
    return states


def connect(ray, address: str | None) -> dict:
    """Start a local Ray instance (no address) or join a cluster; return how (for batch.json)."""
    common = {"log_to_driver": False, "configure_logging": False}
    if address is None:
        ray.init(num_cpus=os.cpu_count(), object_store_memory=OBJECT_STORE_BYTES, include_dashboard=False,
                 **common)
    else:
        try:
            ray.init(address=address, **common)
        except (ConnectionError, ValueError, RuntimeError) as err:
            raise InputError(None, "--address", f"cannot join the Ray cluster at {address}: {err}") from None
    nodes = [{"host": n.get("NodeManagerHostname"), "address": n.get("NodeManagerAddress"),
              "resources": n.get("Resources", {})} for n in ray.nodes() if n.get("Alive")]
    return {"address": address or "local", "ray_version": ray.__version__, "nodes": nodes,
            "resources": ray.cluster_resources()}


def run_batch(manifest: Manifest, out: Path, address: str | None, resources: Resources, on_change,
              commands: StepCommands) -> tuple[list[SceneState], dict]:
    """Run every scene's remaining steps with ``commands``; ``on_change(states)`` is called after each state
    change.

    Returns the scene states and the cluster description. Ray is stopped (a local instance ends) on return.
    """
    ray = require_ray()
    out = out.resolve()
    states = plan(manifest, out)
    probe = uuid.uuid4().hex
    (out / PROBE).write_text(probe)
    cluster = connect(ray, address)
    try:
        _check_resources(cluster["resources"], resources)
        remote = ray.remote(max_calls=1, max_retries=RETRIES, retry_exceptions=True)(run_step).options(
            num_cpus=resources.cpus, num_gpus=resources.gpus)
        _drive(ray, remote, states, out, probe, resources, on_change, commands)
    finally:
        ray.shutdown()
    return states, cluster


def _check_resources(available: dict, resources: Resources) -> None:
    if resources.cpus > available.get("CPU", 0):
        raise InputError(None, "--cpus-per-scene", f"{resources.cpus:g} CPUs asked, the Ray cluster has "
                                                   f"{available.get('CPU', 0):g}")
    if resources.gpus > available.get("GPU", 0):
        raise InputError(None, "--gpus-per-scene", f"{resources.gpus:g} GPUs asked, the Ray cluster has "
                                                   f"{available.get('GPU', 0):g}")


def _drive(ray, remote, states: list[SceneState], out: Path, probe: str, resources: Resources, on_change,
           commands: StepCommands) -> None:
    from ray.exceptions import RayError

    threads = max(1, int(resources.cpus))
    running = {}  # object ref -> (scene state, step, submit time)

    def submit(state: SceneState) -> None:
        step = state.todo[0]
        job = StepJob(str(out), probe, state.job.name, step, state.job.source, state.job.options[step],
                      resources.arch, threads)
        running[remote.remote(job, commands)] = (state, step)
        state.status = "running"
        log.info("%s: %s scheduled", state.job.name, step)

    for state in states:
        if state.skipped:
            log.info("%s: %s complete from an earlier batch, skipped", state.job.name, ", ".join(state.skipped))
        if state.todo:
            submit(state)
    on_change(states)
    with progress("scenes", len(states)) as bar:
        bar.advance(sum(s.status == "ok" for s in states))
        _status(bar, states)
        while running:
            ready, _ = ray.wait(list(running), num_returns=1, timeout=1.0)
            if not ready:
                _status(bar, states)
                continue
            ref = ready[0]
            state, step = running.pop(ref)
            try:
                result = ray.get(ref)
            except RayError as err:
                result = {"status": "failed", "error": f"{step}: {_one_line(err)}"}
            if result["status"] == "ok":
                state.seconds[step] = result["seconds"]
                state.todo.pop(0)
                log.info("%s: %s done in %.1f s", state.job.name, step, result["seconds"])
                if state.todo:
                    submit(state)
                else:
                    state.status = "ok"
                    log.info("%s: finished", state.job.name)
            else:
                state.status, state.error = "failed", result["error"]
                log.warning("%s: failed: %s", state.job.name, state.error)
            _status(bar, states)
            if state.status != "running":
                bar.advance()
            on_change(states)


def _status(bar, states: list[SceneState]) -> None:
    bar.status(done=sum(s.status == "ok" for s in states), running=sum(s.status == "running" for s in states),
               failed=sum(s.status == "failed" for s in states))


def _one_line(err: Exception) -> str:
    """A Ray error as one line: the cause's type and message (a crashed or killed worker says so)."""
    from ray.exceptions import RayTaskError

    if isinstance(err, RayTaskError):
        cause = err.cause if err.cause is not None else err
        text = f"{type(cause).__name__}: {cause}"
    else:
        text = f"{type(err).__name__}: {err}"
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    return lines[0] if len(lines) == 1 else f"{lines[0]} ... {lines[-1]}"
