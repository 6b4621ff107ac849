"""Packaging: the library ``fluidnexus`` and its command line, which lives in the ``cli/`` folder and installs as
the package ``fluidnexus_cli`` (a top-level package named ``cli`` would collide with other projects' ``cli``).
Everything else is in setup.cfg."""
from setuptools import find_packages, setup

setup(packages=find_packages(include=["fluidnexus", "fluidnexus.*"]) + ["fluidnexus_cli"],
      package_dir={"fluidnexus_cli": "cli"})
