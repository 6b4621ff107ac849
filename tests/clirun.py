"""Run ``fluidnexus`` commands in-process for tests."""
from click.testing import CliRunner

from cli.main import main


def invoke(*args):
    """Run the CLI with ``args`` (converted to strings); return click's result."""
    return CliRunner().invoke(main, [str(a) for a in args])


def ok(*args):
    """Run the CLI and require exit code 0."""
    result = invoke(*args)
    assert result.exit_code == 0, result.output + repr(result.exception)
    return result
