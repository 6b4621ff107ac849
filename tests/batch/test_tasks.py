"""The pieces of a batch step that need no Ray: shared-storage check, completion markers, scene copies, metrics."""
from __future__ import annotations

import pytest

from fluidnexus.atomic import write_json
from fluidnexus.batch.results import flatten_metrics
from fluidnexus.batch.steps import Layout
from fluidnexus.batch.tasks import PROBE, check_shared_storage, completed, copy_scene
from fluidnexus.errors import InputError
from fluidnexus.scene import load_scene

from .conftest import ok


def test_a_node_that_cannot_see_the_batch_folder_says_so(tmp_path):
    (tmp_path / PROBE).write_text("token-of-this-driver")
    check_shared_storage(tmp_path, "token-of-this-driver")
    for folder, token in ((tmp_path, "token-of-another-driver"), (tmp_path / "elsewhere", "token-of-this-driver")):
        with pytest.raises(InputError) as err:
            check_shared_storage(folder, token)
        assert "cannot see the batch folder" in str(err.value) and "shared storage" in str(err.value)


def test_a_step_is_complete_only_with_its_marker_and_the_same_options(tmp_path):
    layout = Layout(tmp_path)
    assert completed(layout, "recon", ["--frames", "0:2"]) is None
    write_json(layout.marker("recon"), {"step": "recon", "options": ["--frames", "0:2"], "seconds": 3.0})
    assert completed(layout, "recon", ["--frames", "0:2"])["seconds"] == 3.0
    assert completed(layout, "recon", ["--frames", "0:3"]) is None
    layout.marker("recon").write_text("{half")  # not a marker the batch wrote
    assert completed(layout, "recon", ["--frames", "0:2"]) is None


def test_a_copied_scene_links_its_footage_and_leaves_the_source_alone(tmp_path):
    src = tmp_path / "scene"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--out", src)
    dest = tmp_path / "copy"
    copy_scene(src, dest)
    assert [(v.name, v.role, v.video) for v in load_scene(dest).views] == [(v.name, v.role, v.video) for v in
                                                                        load_scene(src).views]
    assert (dest / "videos" / "train00.mp4").is_symlink() and not (dest / "scene.json").is_symlink()
    (dest / "scene.json").write_text("{}")
    assert load_scene(src).views  # the source's scene.json is its own file


def test_metrics_are_every_number_eval_wrote():
    scores = {"frames": [0, 2], "resolution": {"width": 34, "height": 60},
              "novel_view": {"psnr": 30.5, "ssim": 0.9, "lpips": None, "per_view": {"train02": {"psnr": 30.5}}},
              "divergence": {"mean_abs": 0.1, "grid": [32, 16, 16], "unit": "1/s"}}
    assert flatten_metrics(scores) == {"novel_view.psnr": 30.5, "novel_view.ssim": 0.9, "novel_view.lpips": None,
                                       "novel_view.per_view.train02.psnr": 30.5, "divergence.mean_abs": 0.1}
