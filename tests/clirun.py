"""Run ``fluidnexus`` commands in-process for tests."""
from click.testing import CliRunner

from fluidnexus_cli.main import main


def invoke(*args):
    """Run the CLI with ``args`` (converted to strings); return click's result."""
    return CliRunner().invoke(main, [str(a) for a in args])


def ok(*args):
    """Run the CLI and require exit code 0."""
    result = invoke(*args)
    assert result.exit_code == 0, result.output + repr(result.exception)
    return result


def assert_clean_failure(result, *needles):
    """Require the project's bad-input contract: exit code 2, one ``error:`` line holding every needle, no
    traceback."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
