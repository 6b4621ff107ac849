"""`fluidnexus recon`: run folder, checkpoints, resume, bad input."""
import json

import numpy as np
import pytest

from fluidnexus.recon import run as run_module
from fluidnexus.recon.config import ReconConfig
from fluidnexus.state import load_frame

from .conftest import TINY, invoke, ok


def test_run_folder_layout(tiny_run):
    for name in ("run.json", "config.json", "summary.json", "logs/recon.log", "frames/000000.npz",
                 "frames/000002.npz"):
        assert (tiny_run / name).exists(), name
    info = json.loads((tiny_run / "run.json").read_text())
    assert info["format"] == "fluidnexus-run/1" and info["frames"] == [0, 3]
    config = json.loads((tiny_run / "config.json").read_text())
    cfg = ReconConfig.from_dict(config["recon"])
    assert cfg.dynamics_iters == 2 and cfg.resolution == 0.25 and cfg.frames == (0, 3)
    assert [t["kind"] for t in config["model"]["terms"]] == ["buoyancy", "drag"]
    summary = json.loads((tiny_run / "summary.json").read_text())
    assert summary["frames"] == [0, 3] and summary["particles"]["visual"] > 100
    assert {"render", "backward", "simulation"} <= set(summary["timing_s"])
    log = (tiny_run / "logs" / "recon.log").read_text()
    assert "frame 2 losses: image=" in log


def test_states_are_consistent_over_frames(tiny_run):
    states = [load_frame(tiny_run / "frames" / f"{t:06d}.npz") for t in range(3)]
    assert [s.frame for s in states] == [0, 1, 2]
    # visual rows keep their identity: every later frame has at least as many Gaussians
    assert states[0].num_visual <= states[1].num_visual <= states[2].num_visual
    # the smoke source was found in the footage: ScalarFlow's inflow is near (0.34, 0.0, -0.225)
    summary = json.loads((tiny_run / "summary.json").read_text())
    np.testing.assert_allclose(summary["source"]["center"], [0.34, 0.0, -0.23], atol=0.02)
    # x_t is x_{t-1} advected by the frame's velocity field: particles near the source rise
    s1, s2 = states[1], states[2]
    moved = s2.visual_positions[: s1.num_visual] - s1.visual_positions
    assert np.isfinite(moved).all() and np.abs(moved).max() > 0


def test_resume_after_interruption_is_bit_identical(four_view_scene, tiny_run, tmp_path, monkeypatch):
    out = tmp_path / "interrupted"
    real_save = run_module._save

    def save_then_die(folder, smoke, t):
        saved = real_save(folder, smoke, t)
        if t == 1:
            raise KeyboardInterrupt  # killed right after frame 1 was written
        return saved

    monkeypatch.setattr(run_module, "_save", save_then_die)
    result = invoke("recon", four_view_scene, "--out", out, *TINY)
    assert result.exit_code != 0 and not (out / "frames" / "000002.npz").exists()
    monkeypatch.setattr(run_module, "_save", real_save)
    ok("recon", four_view_scene, "--out", out, "--resume", *TINY)
    for t in range(3):
        a = np.load(tiny_run / "frames" / f"{t:06d}.npz")
        b = np.load(out / "frames" / f"{t:06d}.npz")
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=f"frame {t} {key}")


def test_resume_with_other_settings_is_refused(four_view_scene, tiny_run):
    result = invoke("recon", four_view_scene, "--out", tiny_run, "--resume", *TINY[:-2], "--lambda-sim", "0.5",
                    "--seed", "3", "--arch", "cpu")
    assert result.exit_code == 2
    assert "recon.lambda_sim" in result.output and "recon.seed" in result.output


@pytest.mark.parametrize("args, needle", [
    (["--frames", "100:130"], "outside the videos' 120 frames"),
    (["--frames", "5:6"], "at least 2 frames"),
    (["--resolution", "-1"], "--resolution"),
    (["--dynamics-iters", "-3"], "--dynamics-iters"),
])
def test_bad_settings(four_view_scene, tmp_path, args, needle):
    result = invoke("recon", four_view_scene, "--out", tmp_path / "r", *args)
    assert result.exit_code == 2 and needle in result.output, result.output
    assert "Traceback" not in result.output


def test_scene_without_usable_view(tmp_path):
    ok("calibrate", "--sample", "scalarflow", "--protocol", "single-view", "--out", tmp_path / "s")
    scene = json.loads((tmp_path / "s" / "scene.json").read_text())
    scene["views"] = [v for v in scene["views"] if v["role"] == "novel"]
    (tmp_path / "s" / "scene.json").write_text(json.dumps(scene))
    result = invoke("recon", tmp_path / "s", "--out", tmp_path / "r", *TINY)
    assert result.exit_code == 2 and "no usable view" in result.output


def test_existing_run_is_not_overwritten(four_view_scene, tiny_run):
    result = invoke("recon", four_view_scene, "--out", tiny_run, *TINY)
    assert result.exit_code == 2 and "--resume" in result.output


def test_full_disk_keeps_the_last_frame(four_view_scene, tmp_path, monkeypatch):
    import errno

    import fluidnexus.recon.run as rr

    real = rr.save_frame

    def fail_at_two(path, state):
        if state.frame == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path, state)

    monkeypatch.setattr(rr, "save_frame", fail_at_two)
    result = invoke("recon", four_view_scene, "--out", tmp_path / "r", *TINY)
    assert result.exit_code == 1 and "No space left on device" in result.output
    assert (tmp_path / "r" / "frames" / "000001.npz").exists()
    assert not list((tmp_path / "r" / "frames").glob("*.part*"))


def test_divergence_stops_with_a_clear_message(four_view_scene, tmp_path):
    result = invoke("recon", four_view_scene, "--out", tmp_path / "r", *TINY, "--max-loss", "1e-9")
    assert result.exit_code == 1 and "diverged" in result.output
