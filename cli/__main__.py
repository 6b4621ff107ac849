"""``python -m fluidnexus_cli`` runs the ``fluidnexus`` command."""
from .main import main

main()
