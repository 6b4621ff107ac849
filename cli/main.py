"""Entry point: the ``fluidnexus`` click group.

Bad input raised anywhere as :class:`fluidnexus.errors.InputError` is printed as one line on stderr and the
process exits with code 2, without a traceback.
"""
from __future__ import annotations

import logging

import click

from fluidnexus import __version__
from fluidnexus.errors import InputError, RunError

from .background import background
from .batch import batch
from .calibrate import calibrate
from .demo import demo
from .diagnose import diagnose
from .export import export
from .interact import interact
from .predict import predict
from .recon import recon
from .refine import refine
from .show import evaluate, render
from .synth import synth
from .view import view


class FluidnexusGroup(click.Group):
    """A click group that prints :class:`InputError` (exit code 2) and :class:`RunError` (exit code 1) as one
    ``error: ...`` line, without a traceback."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except InputError as err:
            click.echo(f"error: {err}", err=True)
            ctx.exit(2)
        except RunError as err:
            click.echo(f"error: {err}", err=True)
            ctx.exit(1)


@click.group(cls=FluidnexusGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="fluidnexus")
@click.option("-q", "--quiet", is_flag=True, help="Only print warnings and errors.")
def main(quiet: bool) -> None:
    """Reconstruct, predict and edit 3D smoke from video (FluidNexus, CVPR 2025)."""
    configure_logging(logging.WARNING if quiet else logging.INFO)


def configure_logging(console_level: int) -> None:
    """The library logs INFO to its run logs; the console shows ``console_level`` and up (one handler)."""
    logger = logging.getLogger("fluidnexus")
    logger.setLevel(logging.INFO)
    logger.propagate = False
    for handler in [h for h in logger.handlers if getattr(h, "fluidnexus_console", False)]:
        logger.removeHandler(handler)
    console = logging.StreamHandler()
    console.setLevel(console_level)
    console.setFormatter(logging.Formatter("%(message)s"))
    console.fluidnexus_console = True
    logger.addHandler(console)


main.add_command(calibrate)
main.add_command(recon)
main.add_command(render)
main.add_command(evaluate)
main.add_command(export)
main.add_command(demo)
main.add_command(synth)
main.add_command(refine)
main.add_command(predict)
main.add_command(interact)
main.add_command(diagnose)
main.add_command(background)
main.add_command(batch)
main.add_command(view)
