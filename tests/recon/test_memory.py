"""The memory estimate (fluidnexus/memory.py, docs/scale.md): refusal before anything is allocated or written,
and the estimate against the measured peak resident memory of real runs."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fluidnexus import memory
from fluidnexus.errors import InputError
from fluidnexus.recon.config import config_for_scene
from fluidnexus.recon.memory import recon_estimate
from fluidnexus.recon.setup import default_setup
from fluidnexus.scene import load_scene

from .conftest import TINY, invoke, ok

ROOT = Path(__file__).resolve().parents[2]
# The estimate may be off by this factor either way against the measured peak (measured: peak / estimate
# 1.05-1.19 on ScalarFlow runs, 1.09 on Sphere; BENCHMARKS.md).
FACTOR = 1.5


def _one_error_line(result, needle: str) -> str:
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip() and not line.startswith("[Taichi]")]
    assert len(lines) == 1 and needle in lines[0], result.output
    return lines[0]


def test_limit_parsing():
    assert memory.parse_limit("2G") == 2 * 2**30
    assert memory.parse_limit("1500M") == 1500 * 2**20
    assert memory.parse_limit("auto") == int(memory.DEFAULT_FRACTION * memory.available_bytes())
    for bad in ("lots", "-1G", "1X"):
        with pytest.raises(InputError, match="--max-memory"):
            memory.parse_limit(bad)
    with pytest.raises(InputError, match="smallest run"):
        memory.parse_limit("100M")


def test_recon_refuses_before_writing(four_view_scene, tmp_path):
    out = tmp_path / "run"
    line = _one_error_line(invoke("recon", four_view_scene, "--out", out, "--max-memory", "600M",
                                  "--visual-spacing", "0.001", "--arch", "cpu"), "--visual-spacing")
    assert "visual hull" in line and "GiB" in line
    assert not out.exists()
    _one_error_line(invoke("recon", four_view_scene, "--out", out, "--max-memory", "100M", "--arch", "cpu"),
                    "--max-memory")
    assert not out.exists()


def test_synth_refuses_before_writing(tmp_path):
    scene = tmp_path / "s"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "single-view", "--out", scene)
    before = (scene / "scene.json").read_text()
    _one_error_line(invoke("synth", scene, "--max-memory", "500M"), "--resolution")
    assert (scene / "scene.json").read_text() == before
    assert not list((scene / "videos").glob("*_synth.mp4"))


def test_estimate_grows_with_the_settings(four_view_scene):
    scene = load_scene(four_view_scene)
    small = default_setup(scene, config_for_scene(scene, {"resolution": 0.25}))
    big = default_setup(scene, config_for_scene(scene, {"resolution": 0.5, "visual_spacing": 0.003}))
    a = recon_estimate(scene, small, (0, 120), 1000)
    b = recon_estimate(scene, big, (0, 120), 1000)
    assert b.parts["video cache"] == pytest.approx(4 * a.parts["video cache"], rel=0.02)  # pixel rounding
    assert b.parts["visual hull"] > a.parts["visual hull"] and b.total > a.total


# The peak is the process's own high-water mark (VmHWM). Not getrusage's ru_maxrss: on Linux that keeps the
# high-water mark of the process it was forked from (here the test session, gigabytes by then) across exec.
PEAK = """
import json, sys
from fluidnexus_cli.main import main
try:
    main(sys.argv[1:], standalone_mode=False)
finally:
    hwm = next(line for line in open("/proc/self/status") if line.startswith("VmHWM:"))
    print(json.dumps({"peak": int(hwm.split()[1]) * 1024}), file=sys.stderr)
"""


def _measured(args) -> tuple[int, str]:
    proc = subprocess.run([sys.executable, "-c", PEAK, *map(str, args)], cwd=ROOT, capture_output=True, text=True,
                          timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    peak = json.loads(proc.stderr.strip().splitlines()[-1])["peak"]
    return peak, proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("protocol, settings", [
    ("four-view", TINY),
    ("single-view", ["--frames", "0:4", "--resolution", "0.5", *TINY[4:]]),
])
def test_estimate_within_a_factor_of_the_measured_peak(protocol, settings, tmp_path):
    scene = tmp_path / "s"
    ok("calibrate", "--sample", "scalarflow", "--protocol", protocol, "--out", scene)
    peak, log = _measured(["recon", scene, "--out", tmp_path / "run", *settings])
    line = next(x for x in log.splitlines() if "recon needs about" in x)  # the check after the hull
    logged = _parse_size(line.split("needs about ")[1].split(" (")[0])
    assert 1 / FACTOR <= peak / logged <= FACTOR, (peak / 2**20, logged / 2**20, line)


def _parse_size(text: str) -> float:
    value, unit = text.split()
    return float(value) * {"MiB": 2**20, "GiB": 2**30}[unit]
