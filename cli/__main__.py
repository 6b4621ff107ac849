"""``python -m cli`` runs the ``fluidnexus`` command."""
from .main import main

main()
