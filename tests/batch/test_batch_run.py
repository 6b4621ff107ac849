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


def _stat(pid) -> list[str] | None:
    """Fields of /proc/PID/stat after the command name (state, ppid, ..., start time at [19])."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def descendants(pid: int) -> set[tuple[int, str]]:
    """(process id, start time) of every process below ``pid``; the start time tells a reused id apart."""
    stats = {int(p.name): _stat(p.name) for p in Path("/proc").iterdir() if p.name.isdigit()}
    stats = {p: f for p, f in stats.items() if f is not None}
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, f in stats.items() if int(f[1]) in frontier} - found
        found |= frontier
    return {(p, stats[p][19]) for p in found}


def alive(process: tuple[int, str]) -> bool:
    fields = _stat(process[0])
    return fields is not None and fields[19] == process[1] and fields[0] != "Z"


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


def cmdline(pid: int) -> str:
    try:
        return (Path("/proc") / str(pid) / "cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def wait_for(condition, driver, seconds: float = 900) -> set[tuple[int, str]]:
    """Poll until ``condition()``; return the driver's processes seen meanwhile (fails if the driver ended)."""
    seen, deadline = set(), time.time() + seconds
    while not condition() and driver.poll() is None and time.time() < deadline:
        seen |= descendants(driver.pid)
        time.sleep(0.3)
    assert driver.poll() is None and condition(), "the batch never got there"
    return seen | descendants(driver.pid)


@pytest.mark.slow
def test_killed_driver_and_worker_lose_no_finished_work(sample_batch, tmp_path):
    """Kill the driver (and with it Ray) once the recon has checkpointed frame 0; re-run and kill the resumed
    recon's worker: Ray retries it, the recon resumes again, and the frames are bit-identical to an uninterrupted
    batch's."""
    done, _ = sample_batch
    manifest = write_manifest(tmp_path, f'[defaults]\nsteps = ["recon", "eval"]\n{TINY_RECON}\n'
                              + sample_scenes("single-view"))
    out = tmp_path / "out"
    scene = out / "scenes" / "single-view"
    frames = scene / "run" / "frames"
    cmd = [sys.executable, "-m", "fluidnexus_cli", "batch", str(manifest), "--out", str(out), *BATCH_OPTIONS]
    driver = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    started = set()
    try:
        started = wait_for(lambda: (frames / "000000.npz").exists(), driver)
    finally:
        os.killpg(driver.pid, signal.SIGKILL)  # the driver and Ray's head processes (workers have their own group)
        driver.wait()
    deadline = time.time() + 60
    while any(alive(p) for p in started) and time.time() < deadline:
        time.sleep(0.5)
    left = [p for p in started if alive(p)]
    for pid, _ in left:  # only cleanup: the assertion below fails the test when the workers outlive Ray
        os.kill(pid, signal.SIGKILL)
    assert not left, "Ray workers kept running after the driver was killed"
    assert not (frames / "000001.npz").exists()
    scene_marker = (scene / "steps" / "scene.json").read_bytes()

    log = tmp_path / "rerun.log"
    with open(log, "w") as sink:
        driver = subprocess.Popen(cmd + ["--resume"], stdout=sink, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        recon_log = scene / "run" / "logs" / "recon.log"
        seen = wait_for(lambda: recon_log.exists() and "resuming after frame 0" in recon_log.read_text(), driver)
        workers = [p for p in seen if alive(p) and cmdline(p[0]).startswith("ray::run_step")]
        assert len(workers) == 1
        os.kill(workers[0][0], signal.SIGKILL)
        assert driver.wait(timeout=900) == 0, log.read_text()
    finally:
        if driver.poll() is None:
            os.killpg(driver.pid, signal.SIGKILL)
            driver.wait()
    text = log.read_text()
    assert "single-view: scene complete from an earlier batch, skipped" in text
    assert (scene / "steps" / "scene.json").read_bytes() == scene_marker
    assert recon_log.read_text().count("resuming after frame 0") == 2  # the re-run and Ray's retry of it
    for t in range(2):
        a = np.load(done / "scenes" / "single-view" / "run" / "frames" / f"{t:06d}.npz")
        b = np.load(frames / f"{t:06d}.npz")
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=f"frame {t} {key}")
    assert table(out)["single-view"][MAIN_METRIC] == table(done)["single-view"][MAIN_METRIC]
