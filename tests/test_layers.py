"""The layers point down (docs/architecture.md): no module imports a layer above its own, and no two modules
import each other, directly or around a loop. Read from the source by scripts/import_graph.py."""
import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "import_graph.py"


@pytest.fixture(scope="module")
def graph_tools():
    spec = importlib.util.spec_from_file_location("import_graph", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_layers_of_known_modules(graph_tools):
    assert graph_tools.layer("cli.recon") == "cli"
    assert graph_tools.layer("fluidnexus.recon.run") == "pipelines"
    assert graph_tools.layer("fluidnexus.scenery.backdrop") == "scene"
    assert graph_tools.layer("fluidnexus.engine.pbf") == "engine"


def test_the_graph_sees_upward_imports_and_cycles(graph_tools):
    graph = {"fluidnexus.engine.pbf": {"fluidnexus.scene"}, "fluidnexus.scene": {"fluidnexus.engine.pbf"},
             "fluidnexus.recon.run": {"cli.main"}, "cli.main": set()}
    assert graph_tools.upward(graph) == [("fluidnexus.engine.pbf", "fluidnexus.scene"),
                                         ("fluidnexus.recon.run", "cli.main")]
    assert graph_tools.cycles(graph) == [["fluidnexus.engine.pbf", "fluidnexus.scene"]]


def test_no_import_runs_up_and_no_cycle(graph_tools):
    graph = graph_tools.edges(graph_tools.modules())
    assert len(graph) > 100  # the whole tree was read
    assert graph_tools.upward(graph) == []
    assert graph_tools.cycles(graph) == []
