"""synth and refine end to end on a tiny scene cut from the ScalarFlow sample."""
import json

from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.calibrate.pinf import read_pinf, source_at_volume_foot
from fluidnexus.samples import sample_path
from fluidnexus.scene import Scene, View, load_scene, save_scene
from fluidnexus.video import read_video, write_video


def tiny_scene(root, frames=6, scale=0.2):
    """Input train02 (first ``frames`` frames at ``scale`` of the sample), novel train00 and train04."""
    cap = read_pinf(sample_path("scalarflow") / "info.json")
    cams = {name: rec.camera for name, rec in cap.recordings.items()}
    inp = cams["train02"].scaled(scale)
    video = read_video(cap.recordings["train02"].media, frames=slice(0, frames), size=(inp.width, inp.height))
    root.mkdir(parents=True, exist_ok=True)
    write_video(root / "videos" / "train02.mp4", video, cap.fps)
    views = (View("train02", "input", inp, "videos/train02.mp4"),
             View("train00", "novel", cams["train00"].resized(inp.width, inp.height)),
             View("train04", "novel", cams["train04"].resized(inp.width, inp.height)))
    save_scene(Scene(root, cap.fps, frames, views, cap.volume, source_at_volume_foot(cap.volume)))
    return root


def test_synth_then_refine_writes_novel_videos_with_provenance(tmp_path):
    scene_dir = tiny_scene(tmp_path / "scene")
    runner = CliRunner()
    res = runner.invoke(main, ["synth", str(scene_dir)])
    assert res.exit_code == 0, res.output
    scene = load_scene(scene_dir)  # checks every video's size and frame count
    for name in ("train00", "train04"):
        view = scene.view(name)
        assert view.video == f"videos/{name}_synth.mp4"
        assert view.provenance["synth"]["method"] == "axisym" and view.provenance["synth"]["input"] == "train02"
        assert read_video(scene.video_path(view)).max() > 0.1  # smoke is there
    res = runner.invoke(main, ["refine", str(scene_dir)])
    assert res.exit_code == 0, res.output
    res = runner.invoke(main, ["refine", str(scene_dir)])  # again: starts from the unrefined video
    assert res.exit_code == 0, res.output
    scene = load_scene(scene_dir)
    view = scene.view("train00")
    assert view.video == "videos/train00_refined.mp4"
    assert view.provenance["unrefined"] == "videos/train00_synth.mp4"
    assert view.provenance["refine"]["method"] == "temporal"
    assert (scene_dir / "videos" / "train00_synth.mp4").exists()
    data = json.loads((scene_dir / "scene.json").read_text())
    assert data["views"][0]["video"] == "videos/train02.mp4"


def test_learned_backends_without_weights_fail_in_one_line(tmp_path):
    scene_dir = tiny_scene(tmp_path / "scene", frames=2)
    runner = CliRunner()
    res = runner.invoke(main, ["synth", str(scene_dir), "--method", "zero123", "--weights", str(tmp_path / "none")])
    assert res.exit_code == 2 and "Zero123 weights folder not found" in res.output
    (tmp_path / "empty").mkdir()
    runner.invoke(main, ["synth", str(scene_dir)])
    res = runner.invoke(main, ["refine", str(scene_dir), "--method", "cogvideox", "--weights", str(tmp_path / "empty")])
    assert res.exit_code == 2 and "missing: model_index.json" in res.output and "transformer/" in res.output


def test_registries_import_nothing_heavy():
    import subprocess
    import sys

    code = ("import sys, fluidnexus.gen.synthesizer, fluidnexus.gen.refiner, fluidnexus.gen.weights, "
            "fluidnexus.metrics, fluidnexus_cli.synth, fluidnexus_cli.refine; "
            "print(sorted(m for m in ('torch', 'diffusers', 'transformers') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
