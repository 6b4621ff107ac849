"""One step of one scene as the arguments of the single-scene command that does it.

A batch step runs exactly what ``fluidnexus STEP ...`` runs: the step's command is called in-process (through
:class:`StepCommands`, which the command line provides) with the arguments built here, so a scene of a batch gets
the same files as the same commands typed by hand. The manifest's options for a step are that command's options
(``frames = "0:40"`` is ``--frames 0:40``); the batch sets the folders, ``--arch`` and ``--resume`` itself.

Layout of one scene's output folder (``DIR/scenes/NAME``)::

    scene/            the scene folder (``calibrate``; background adds the plates, synth and refine the novel videos)
    run/              the reconstruction run (``recon``)
    eval.json         the scores (``eval`` of run/)
    predict/          the prediction run (``predict`` after run/)
    diagnose/         the model diagnosis (``diagnose`` of scene/)
    steps/STEP.json   completion marker of each finished step: its arguments and seconds
    log.txt           the log of every step, appended
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

PREPARE = "scene"  # the first step of every scene: make its scene folder (``calibrate``, or a copy of a folder)
STEPS = ("background", "synth", "refine", "recon", "eval", "predict", "diagnose")  # the order they run in
NEEDS_RUN = ("eval", "predict")  # steps that read the reconstruction run
SCENE_SOURCES = ("sample", "from_pinf", "scene")

class StepCommands(Protocol):
    """What runs the steps: the options a manifest may give each step, and one step's run. The command line
    provides it (``fluidnexus_cli.batch_steps.CommandSteps``): a step is the ``fluidnexus`` command of its name
    (``scene`` is ``calibrate``), its options are that command's, and it is called in-process with the arguments
    :func:`step_args` builds. Ray sends it to the workers by reference."""

    def option_tokens(self, step: str, key: str, value, base: Path) -> list[str]:
        """Command-line tokens for one manifest option; ValueError with a plain message when it is bad."""

    def required(self, step: str) -> list[str]:
        """Manifest keys the step requires that the batch does not set (e.g. predict's ``frames``)."""

    def run(self, step: str, args: list[str]) -> None:
        """Run ``step`` with ``args``; bad input is an InputError, a run that stopped on its own a RunError."""


@dataclass(frozen=True)
class Layout:
    """Where one scene's outputs go (see the module docstring)."""

    root: Path

    @property
    def scene(self) -> Path:
        return self.root / "scene"

    @property
    def run(self) -> Path:
        return self.root / "run"

    @property
    def eval_json(self) -> Path:
        return self.root / "eval.json"

    @property
    def predict(self) -> Path:
        return self.root / "predict"

    @property
    def diagnose(self) -> Path:
        return self.root / "diagnose"

    @property
    def log(self) -> Path:
        return self.root / "log.txt"

    def marker(self, step: str) -> Path:
        return self.root / "steps" / f"{step}.json"

    def partial_output(self, step: str) -> Path | None:
        """A folder that an unfinished ``step`` may have left and that it recreates from scratch."""
        return {"predict": self.predict, "diagnose": self.diagnose}.get(step)


def step_args(step: str, source: dict, options: list[str], layout: Layout, arch: str, cpus: int = 1) -> list[str]:
    """The full argument list of ``step``'s command for one scene (resume decided from the files already there);
    ``cpus``: the task's CPUs, diagnose's ``--jobs`` unless the manifest sets it."""
    if step == PREPARE:
        return source_args(source) + options + ["--out", str(layout.scene), "--overwrite"]
    if step == "background":  # a re-run after a kill replaces what the killed step left
        return [str(layout.scene), "--overwrite"] + options
    if step in ("synth", "refine"):
        return [str(layout.scene)] + _device(options, arch)
    if step == "recon":
        resume = ["--resume"] if (layout.run / "config.json").exists() else []
        return [str(layout.scene), "--out", str(layout.run), "--arch", arch] + resume + options
    if step == "eval":
        return [str(layout.run), "--json", str(layout.eval_json), "--arch", arch] + options
    if step == "predict":
        return [str(layout.run), "--out", str(layout.predict), "--arch", arch] + _device(options, arch)
    if step == "diagnose":
        jobs = [] if "--jobs" in options else ["--jobs", str(max(1, cpus))]
        return [str(layout.scene), "--out", str(layout.diagnose), "--arch", arch] + options + jobs
    raise ValueError(step)


def source_args(source: dict) -> list[str]:
    """calibrate's arguments naming a sample or PINF source (a scene folder is copied instead: tasks.copy_scene)."""
    if source["kind"] == "sample":
        return ["--sample", source["sample"], "--protocol", source["protocol"]]
    if source["kind"] == "from_pinf":
        roles = [(flag, source[key]) for flag, key in (("--input", "input"), ("--novel", "novel"),
                                                       ("--ground-truth", "ground_truth")) if source.get(key)]
        return ["--from-pinf", source["from_pinf"]] + [t for flag, names in roles for t in (flag, ",".join(names))]
    raise ValueError(source["kind"])


def _device(options: list[str], arch: str) -> list[str]:
    """The torch device of the generative models follows the task's resources unless the manifest names one."""
    return options if "--device" in options else options + ["--device", arch]
