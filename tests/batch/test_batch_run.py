"""`fluidnexus batch` on a local Ray instance: the results table, isolation of a failing scene, skip and resume."""
from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fluidnexus.batch.results import MAIN_METRIC, flatten_metrics

from .conftest import BATCH_OPTIONS, TINY_RECON, invoke, sample_scenes, write_manifest


def table(out: Path) -> dict[str, dict]:
    with open(out / "results.csv", newline="") as f:
        return {row["scene"]: row for row in csv.DictReader(f)}


def test_results_table_holds_each_scenes_eval_numbers(sample_batch):
    out, result = sample_batch
    rows = table(out)
    assert rows["single-view"]["status"] == rows["four-view"]["status"] == "ok", result.output
    for name in ("single-view", "four-view"):
        scores = flatten_metrics(json.loads((out / "scenes" / name / "eval.json").read_text()))
        assert MAIN_METRIC in scores and scores[MAIN_METRIC] is not None
        for metric, value in scores.items():
            cell = rows[name][metric]
            assert (cell == "") if value is None else float(cell) == value, (name, metric)
        for step in ("scene", "recon", "eval"):
            assert float(rows[name][f"seconds.{step}"]) > 0
    mean = np.mean([json.loads((out / "scenes" / n / "eval.json").read_text())["novel_view"]["psnr"]
                    for n in ("single-view", "four-view")])
    assert f"| {MAIN_METRIC} | {mean:.4f}".rstrip("0") in (out / "results.md").read_text()
    assert (out / "results.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    record = json.loads((out / "batch.json").read_text())
    assert [s["name"] for s in record["manifest"]["scenes"]] == ["single-view", "four-view", "broken"]
    assert record["versions"]["ray"] and record["cluster"]["address"] == "local"
    assert record["cluster"]["resources"]["CPU"] == os.cpu_count()


def test_a_scene_with_a_truncated_video_fails_alone(sample_batch):
    out, result = sample_batch
    assert result.exit_code == 1, result.output
    row = table(out)["broken"]
    assert row["status"] == "failed" and "truncated" in row["error"] and "\n" not in row["error"]
    assert "failed: broken" in result.output
    assert table(out)["four-view"]["status"] == "ok"


def test_a_rerun_skips_finished_steps(sample_batch):
    out, _ = sample_batch
    markers = {p: p.read_bytes() for p in (out / "scenes").glob("*/steps/*.json")}
    result = invoke("batch", out.parent / "batch.toml", "--out", out, "--resume", *BATCH_OPTIONS)
    assert result.exit_code == 1  # the broken scene fails again; the others are not redone
    assert "single-view: scene, recon, eval complete from an earlier batch, skipped" in result.output
    assert {p: p.read_bytes() for p in (out / "scenes").glob("*/steps/*.json")} == markers


@pytest.mark.slow
def test_killed_batch_resumes_to_the_same_checkpoints(sample_batch, tmp_path):
    """Kill the driver (and with it Ray) once the recon has checkpointed frame 0; re-run: bit-identical frames."""
    done, _ = sample_batch
    manifest = write_manifest(tmp_path, f'[defaults]\nsteps = ["recon", "eval"]\n{TINY_RECON}\n'
                              + sample_scenes("single-view"))
    out = tmp_path / "out"
    frames = out / "scenes" / "single-view" / "run" / "frames"
    cmd = [sys.executable, "-m", "cli", "batch", str(manifest), "--out", str(out), *BATCH_OPTIONS]
    driver = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.time() + 900
        while not (frames / "000000.npz").exists() and driver.poll() is None and time.time() < deadline:
            time.sleep(0.5)
        assert driver.poll() is None and (frames / "000000.npz").exists(), "the recon never checkpointed frame 0"
    finally:
        os.killpg(driver.pid, signal.SIGKILL)  # the driver and the Ray processes it started
        driver.wait()
    assert not (frames / "000001.npz").exists()
    scene_marker = (out / "scenes" / "single-view" / "steps" / "scene.json").read_bytes()
    result = invoke("batch", manifest, "--out", out, "--resume", *BATCH_OPTIONS)
    assert result.exit_code == 0, result.output
    assert "single-view: scene complete from an earlier batch, skipped" in result.output
    assert (out / "scenes" / "single-view" / "steps" / "scene.json").read_bytes() == scene_marker
    assert "resuming after frame 0" in (out / "scenes" / "single-view" / "run" / "logs" / "recon.log").read_text()
    for t in range(2):
        a = np.load(done / "scenes" / "single-view" / "run" / "frames" / f"{t:06d}.npz")
        b = np.load(frames / f"{t:06d}.npz")
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=f"frame {t} {key}")
    assert table(out)["single-view"][MAIN_METRIC] == table(done)["single-view"][MAIN_METRIC]
