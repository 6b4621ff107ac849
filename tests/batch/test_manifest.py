"""Bad manifests stop the batch before anything runs: exit 2, one line naming the entry and the field."""
from __future__ import annotations

import sys

import pytest

from fluidnexus.batch.manifest import load_manifest
from fluidnexus_cli.batch_steps import CommandSteps

from .conftest import invoke, sample_scenes, write_manifest

GOOD = '[defaults]\nsteps = ["recon", "eval"]\nrecon = { frames = "0:40", resolution = 0.5 }\n'


def run_bad(tmp_path, body: str):
    manifest = write_manifest(tmp_path, body)
    result = invoke("batch", manifest, "--out", tmp_path / "out")
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2, result.output
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()
    return lines[0]


def test_unknown_step(tmp_path):
    line = run_bad(tmp_path, GOOD + sample_scenes("single-view") + 'steps = ["recon", "render"]\n')
    assert "scene[0] (single-view).steps" in line and "'render'" in line


def test_unknown_option(tmp_path):
    line = run_bad(tmp_path, GOOD + sample_scenes("single-view") + "recon = { resolutoin = 0.5 }\n")
    assert "scene[0] (single-view).recon.resolutoin" in line and "unknown option" in line


def test_option_of_the_wrong_type(tmp_path):
    line = run_bad(tmp_path, GOOD.replace('resolution = 0.5', 'init_iters = "many"') + sample_scenes("four-view"))
    assert "defaults.recon.init_iters" in line and "many" in line


def test_option_the_batch_sets(tmp_path):
    line = run_bad(tmp_path, GOOD + sample_scenes("four-view") + 'recon = { out = "elsewhere" }\n')
    assert "scene[0] (four-view).recon.out" in line


def test_missing_scene_folder(tmp_path):
    line = run_bad(tmp_path, GOOD + '[[scene]]\nname = "lost"\nscene = "no/such/scene"\n')
    assert "scene[0] (lost).scene" in line and "not found" in line


def test_duplicate_names(tmp_path):
    line = run_bad(tmp_path, GOOD + sample_scenes("four-view", "single-view").replace('"single-view"\nsample',
                                                                                         '"four-view"\nsample'))
    assert "scene[1] (four-view).name" in line and "duplicate" in line


def test_required_option_missing(tmp_path):
    line = run_bad(tmp_path, GOOD.replace('"eval"]', '"eval", "predict"]') + sample_scenes("four-view"))
    assert "scene[0] (four-view).predict.frames" in line


def test_eval_without_recon(tmp_path):
    line = run_bad(tmp_path, GOOD.replace('"recon", ', "") + sample_scenes("four-view"))
    assert "defaults.steps" in line and "recon" in line


def test_not_toml(tmp_path):
    line = run_bad(tmp_path, "[defaults\n")
    assert "batch.toml" in line and "TOML" in line


ISSUE_EXAMPLE = """\
[defaults]
steps = ["synth", "refine", "recon", "eval"]
recon = { frames = "0:40", resolution = 0.5 }

[[scene]]
name = "sf-single"
sample = "scalarflow"
protocol = "single-view"

[[scene]]
name = "sf-four"
sample = "scalarflow"
protocol = "four-view"
steps = ["recon", "eval"]

[[scene]]
name = "sphere"
from_pinf = "../shared/data/pinf_sphere/info.json"   # relative paths: relative to the manifest
input = ["train00", "train01", "train02", "train03", "train04"]
ground_truth = ["test02", "test04"]
steps = ["recon", "eval"]
"""


def test_the_issue_example_reads(tmp_path):
    """The manifest of docs/batch.md's example as written (its PINF capture replaced by a file at the same relative
    path)."""
    info = tmp_path / "shared" / "data" / "pinf_sphere" / "info.json"
    info.parent.mkdir(parents=True)
    info.write_text("{}")
    single, four, sphere = load_manifest(write_manifest(tmp_path / "main", ISSUE_EXAMPLE), CommandSteps()).scenes
    assert single.steps == ("synth", "refine", "recon", "eval") and four.steps == ("recon", "eval")
    assert single.options["recon"] == four.options["recon"] == ["--frames", "0:40", "--resolution", "0.5"]
    assert single.source == {"kind": "sample", "sample": "scalarflow", "protocol": "single-view"}
    assert sphere.source == {"kind": "from_pinf", "from_pinf": str(info.resolve()),
                             "input": ["train00", "train01", "train02", "train03", "train04"],
                             "ground_truth": ["test02", "test04"]}


def test_background_is_a_step_before_synth(tmp_path):
    """Footage over a backdrop: the plates step runs first, with its own options, and replaces what a killed
    attempt left (--overwrite)."""
    from fluidnexus.batch.steps import Layout, step_args

    text = GOOD + sample_scenes("four-view") + 'steps = ["recon", "background"]\nbackground = { resolution = 0.5 }\n'
    scene = load_manifest(write_manifest(tmp_path, text), CommandSteps()).scenes[0]
    assert scene.steps == ("background", "recon")
    layout = Layout(tmp_path / "out")
    assert step_args("background", scene.source, scene.options["background"], layout, "cpu") == \
        [str(layout.scene), "--overwrite", "--resolution", "0.5"]


def test_options_of_a_step_not_run_are_checked_too(tmp_path):
    line = run_bad(tmp_path, GOOD + sample_scenes("four-view") + "predict = { anchr = false }\n")
    assert "scene[0] (four-view).predict.anchr" in line


def test_json_manifest(tmp_path):
    path = tmp_path / "batch.json"
    path.write_text('{"defaults": {"steps": ["recon"], "recon": {"anchor": true}}, '
                    '"scene": [{"name": "a", "sample": "scalarflow"}]}')
    with pytest.raises(Exception) as err:
        load_manifest(path, CommandSteps())
    assert "defaults.recon.anchor" in str(err.value)
    path.write_text('{"defaults": {"steps": ["recon", "predict"]}, "scene": [{"name": "a", "sample": "scalarflow", '
                    '"predict": {"anchor": false, "frames": 5}}]}')
    scene = load_manifest(path, CommandSteps()).scenes[0]
    assert scene.source == {"kind": "sample", "sample": "scalarflow", "protocol": "single-view"}
    assert scene.options["predict"] == ["--no-anchor", "--frames", "5"]


def test_without_ray_batch_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # what `import ray` meets where Ray is not installed
    manifest = write_manifest(tmp_path, GOOD + sample_scenes("four-view"))
    result = invoke("batch", manifest, "--out", tmp_path / "out")
    assert result.exit_code == 2 and "pip install 'fluidnexus[cluster]'" in result.output


def test_diagnose_gets_the_tasks_cpus_as_jobs(tmp_path):
    """A diagnose step runs its fits in as many processes as its task has CPUs, unless the manifest says."""
    from fluidnexus.batch.steps import Layout, step_args

    layout = Layout(tmp_path / "out")
    for extra, jobs in (("", "3"), ("diagnose = { jobs = 1 }\n", "1")):
        text = GOOD + sample_scenes("four-view") + 'steps = ["diagnose"]\n' + extra
        scene = load_manifest(write_manifest(tmp_path, text), CommandSteps()).scenes[0]
        args = step_args("diagnose", scene.source, scene.options["diagnose"], layout, "cpu", cpus=3)
        assert args.count("--jobs") == 1 and args[args.index("--jobs") + 1] == jobs, args
