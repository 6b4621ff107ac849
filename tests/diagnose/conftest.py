"""Fixtures of the diagnose tests."""
from __future__ import annotations

import pytest
from click.testing import CliRunner

from fluidnexus_cli.main import main


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    """A scene of the ScalarFlow sample's cameras (four views and the ground truth) for the generator's footage."""
    out = tmp_path_factory.mktemp("tpl") / "four"
    result = CliRunner().invoke(main, ["calibrate", "--sample", "scalarflow", "--protocol", "four-view",
                                       "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out
