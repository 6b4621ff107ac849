"""Entry point: the ``fluidnexus`` click group.

Bad input raised anywhere as :class:`fluidnexus.errors.InputError` is printed as one line on stderr and the
process exits with code 2, without a traceback.
"""
from __future__ import annotations

import logging

import click

from fluidnexus import __version__
from fluidnexus.errors import InputError

from .calibrate import calibrate


class FluidnexusGroup(click.Group):
    """A click group that turns :class:`InputError` into ``error: ...`` and exit code 2."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except InputError as err:
            click.echo(f"error: {err}", err=True)
            ctx.exit(2)


@click.group(cls=FluidnexusGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="fluidnexus")
@click.option("-q", "--quiet", is_flag=True, help="Only print warnings and errors.")
def main(quiet: bool) -> None:
    """Reconstruct, predict and edit 3D smoke from video (FluidNexus, CVPR 2025)."""
    logging.basicConfig(level=logging.WARNING if quiet else logging.INFO, format="%(message)s")


main.add_command(calibrate)
