"""The steps of ``fluidnexus batch`` as the commands of the same names (docs/batch.md; the library's side is
``fluidnexus.batch.steps.StepCommands``): a manifest's options for a step are that command's long options, and a
step runs that command in-process, exactly as ``fluidnexus STEP ...`` typed by hand."""
from __future__ import annotations

from pathlib import Path

import click

from fluidnexus.batch.steps import PREPARE
from fluidnexus.errors import InputError

# click parameters that the batch sets for every step (folders, engine, resume)
BATCH_SET = {"out", "json_file", "resume", "arch", "overwrite", "to_pinf"}
# calibrate parameters that the scene entry itself names (its source and view roles)
SOURCE_SET = {"from_pinf", "from_nerf", "from_colmap", "images", "video", "sample", "protocol", "input_names",
              "novel_names", "gt_names", "paths"}


def command(step: str) -> click.Command:
    """The click command of a step (``scene`` is ``calibrate``)."""
    from .background import background
    from .calibrate import calibrate
    from .diagnose import diagnose
    from .predict import predict
    from .recon import recon
    from .refine import refine
    from .show import evaluate
    from .synth import synth

    return {PREPARE: calibrate, "background": background, "synth": synth, "refine": refine, "recon": recon,
            "eval": evaluate, "predict": predict, "diagnose": diagnose}[step]


def settable(step: str) -> dict[str, click.Option]:
    """The options a manifest may give for ``step``, by manifest key (the long option name, '-' as '_')."""
    reserved = BATCH_SET | (SOURCE_SET if step == PREPARE else set())
    out = {}
    for param in command(step).params:
        if not isinstance(param, click.Option) or param.name in reserved:
            continue
        for name in param.opts:
            if name.startswith("--"):
                out[name[2:].replace("-", "_")] = param
    return out


class CommandSteps:
    """``fluidnexus.batch.steps.StepCommands`` by the click commands (stateless: Ray sends it by reference)."""

    def required(self, step: str) -> list[str]:
        return sorted(k for k, p in settable(step).items() if p.required)

    def option_tokens(self, step: str, key: str, value, base: Path) -> list[str]:
        """Booleans switch flags (``offload = true``, ``anchor = false`` -> ``--no-anchor``), lists become
        comma-separated values, paths are taken relative to ``base`` (the manifest's folder)."""
        params = settable(step)
        if key not in params:
            raise ValueError(f"unknown option for {step}; known: {', '.join(sorted(params))}")
        param = params[key]
        if param.is_flag and not param.count:
            if not isinstance(value, bool):
                raise ValueError(f"expected true or false, got {value!r}")
            if value:
                return [param.opts[0]]
            if param.secondary_opts:
                return [param.secondary_opts[0]]
            return []
        if isinstance(value, (bool, dict)) or value == []:
            raise ValueError(f"expected a value, got {value!r}")
        text = ",".join(str(v) for v in value) if isinstance(value, list) else str(value)
        if isinstance(param.type, click.Path):
            text = str((base / text).resolve())
        else:
            try:
                param.type.convert(text, param, None)
            except click.BadParameter as err:
                raise ValueError(err.message) from None
        return [param.opts[0], text]

    def run(self, step: str, args: list[str]) -> None:
        cmd = command(step)
        try:
            cmd.main(args=args, prog_name=f"fluidnexus {cmd.name}", standalone_mode=False)
        except click.ClickException as err:
            raise InputError(None, None, err.format_message()) from None
