"""``fluidnexus view``: a run in the browser (viser)."""
from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("run_dir", metavar="RUN", type=click.Path(path_type=Path))
@click.argument("run2", metavar="[RUN2]", required=False, type=click.Path(path_type=Path))
@click.option("--port", type=int, default=8080, show_default=True, help="Port of the viewer's web page.")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on: 127.0.0.1 is this machine only; 0.0.0.0 shares it with the network.")
def view(run_dir: Path, run2: Path | None, port: int, host: str) -> None:
    """Serve RUN (and RUN2, e.g. its prediction or an interaction, beside it) at http://HOST:PORT: the smoke's
    Gaussians as splats with a time slider and play, the physical particles coloured by speed, the cameras with
    their video frames (input, synthesised, held-out), the source, obstacles and static layer. Needs
    pip install 'fluidnexus[view]'."""
    from fluidnexus.viewer import serve

    serve([run_dir] + ([run2] if run2 is not None else []), host=host, port=port)
