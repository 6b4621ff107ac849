"""``fluidnexus view`` on the command line: bad input is one line and exit code 2; a good run is served on
127.0.0.1 (the page answers) until Ctrl-C."""
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from clirun import assert_clean_failure, invoke
from fluidnexus.state import FrameState

from handmade_run import write_run
from handmade_scene import ring_camera, write_scene
from view.ports import free_port

ROOT = Path(__file__).resolve().parents[2]


def tiny_state(frame: int) -> FrameState:
    n = 8
    p = np.random.default_rng(frame).normal(size=(n, 3)).astype(np.float32) * 0.1 + np.float32([0, 0.5, 0])
    return FrameState(frame, p, np.zeros((n, 3), np.float32), p, np.full((n, 1), 0.5, np.float32),
                      np.full((n, 3), 0.02, np.float32), np.tile([1.0, 0, 0, 0], (n, 1)).astype(np.float32),
                      np.full(n, 0.5, np.float32))


@pytest.fixture
def tiny_run(tmp_path):
    scene = write_scene(tmp_path / "scene", [("front", "input", ring_camera(0), None)])
    return write_run(tmp_path / "run", scene, [tiny_state(t) for t in range(3)], h=0.1, dt=1 / 25)


def test_a_folder_that_is_not_a_run_is_refused(tmp_path):
    assert_clean_failure(invoke("view", tmp_path), "run.json", "not a fluidnexus run folder")
    assert_clean_failure(invoke("view", tmp_path / "missing"), "run.json")


def test_a_port_in_use_is_refused(tiny_run):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert_clean_failure(invoke("view", tiny_run, "--port", port), "--port", str(port), "in use")


def test_bad_port_and_host_are_refused(tiny_run):
    assert_clean_failure(invoke("view", tiny_run, "--port", 70000), "--port", "1..65535")
    assert_clean_failure(invoke("view", tiny_run, "--host", "no-such-host.invalid", "--port", 8181), "--host")


def test_missing_viser_names_the_extra(tiny_run, monkeypatch):
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser raises ImportError
    port = free_port()
    assert_clean_failure(invoke("view", tiny_run, "--port", port), "viser", "pip install 'fluidnexus[view]'")


def _interruptible():
    """SIGINT at its default in the viewer, as a shell starts it: a test worker may ignore SIGINT, a child inherits
    that, and Python then never raises KeyboardInterrupt (the full suite timed out here three times on 2026-11-26)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_serves_on_localhost_until_interrupted(tiny_run):
    pytest.importorskip("viser", reason="viser is not installed (pip install 'fluidnexus[view]')")
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "fluidnexus_cli", "view", str(tiny_run), "--port", str(port)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_interruptible)
    try:
        deadline, said = time.monotonic() + 60, ""
        while "viewer at" not in said and time.monotonic() < deadline and proc.poll() is None:
            said += proc.stderr.readline()
        assert f"viewer at http://127.0.0.1:{port} (this machine only" in said, said
        page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10).read().decode()
        assert "<html" in page.lower()
        proc.send_signal(signal.SIGINT)
        _, rest = proc.communicate(timeout=60)
        assert proc.returncode == 0, rest[-2000:]
    finally:
        if proc.poll() is None:
            proc.kill()
