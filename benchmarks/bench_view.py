"""Benchmark of ``fluidnexus view``: time to the first frame drawn in a browser, and time per frame step.

Usage: python benchmarks/bench_view.py [--frames 120] [--visual 40000] [--physical 20000] [--work DIR]
       [--screenshot docs/viewer.png]

Makes the embedded ScalarFlow scene (``calibrate --sample scalarflow --protocol four-view``: four input videos and a
held-out one, 120 frames of 270 x 480) and a synthetic run over it (``--frames`` frame states of ``--visual``
Gaussians and ``--physical`` particles rising through the volume, ScalarFlow-like counts), then:

1. starts ``python -m fluidnexus_cli view RUN`` as a user does and a headless Chromium (already running, as a
   user's browser is), which opens the page as soon as the command prints its address; it reports the seconds
   from the command's start to the printed address, to the page's connection, and to the first screenshot in which
   the smoke is drawn (gray-to-white pixels over ``--smoke-share``, 3 %, of the page's middle, where the volume
   is). WebGL runs on SwiftShader (software).
2. in-process: seconds per frame step (``frame.value = t``: read the state, build the splats, send them) over the
   first 20 frames.

With ``--screenshot`` it also writes the page at frame 60 once the cameras show their video frames (the README's
picture, docs/viewer.png).
"""
import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from fluidnexus.state import FrameState  # noqa: E402

from handmade_run import write_run  # noqa: E402
from view.browser import Chromium  # noqa: E402

WIDTH, HEIGHT = 1280, 720
PANEL_SHOWN = "!!document.body && document.body.innerText.includes('frame 0 (t')"  # the status line of the panel


def plume_states(volume_min, volume_max, frames: int, visual: int, physical: int, seed: int = 0):
    """A rising, widening plume: every particle keeps its row, moves up with a little swirl, and wraps to the
    source when it leaves the volume's top."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(volume_min), np.asarray(volume_max)
    foot = np.array([0.5 * (lo[0] + hi[0]), lo[1] + 0.02, 0.5 * (lo[2] + hi[2])])
    height = hi[1] - lo[1] - 0.05
    phase_v, phase_p = rng.random(visual), rng.random(physical)
    dirs_v, dirs_p = rng.normal(size=(visual, 2)), rng.normal(size=(physical, 2))
    scales = (rng.uniform(0.003, 0.009, size=(visual, 3))).astype(np.float32)
    q = rng.normal(size=(visual, 4))
    q = (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)
    colors = rng.uniform(0.6, 0.95, size=(visual, 1)).astype(np.float32)
    opacity = rng.uniform(0.05, 0.35, size=visual).astype(np.float32)

    def place(phase, dirs, t):
        s = (phase + 0.006 * t) % 1.0
        width = 0.012 + 0.06 * s
        swirl = 0.02 * np.sin(6.0 * s + 0.15 * t)
        x = foot[0] + width * dirs[:, 0] + swirl
        z = foot[2] + width * dirs[:, 1]
        return np.stack([x, foot[1] + height * s, z], 1).astype(np.float32)

    for t in range(frames):
        pv, pp = place(phase_v, dirs_v, t), place(phase_p, dirs_p, t)
        up = height * 0.006 * 30.0
        vel = np.tile([0.0, up, 0.0], (physical, 1)).astype(np.float32) + rng.normal(0, 0.02, (physical, 3)).astype(
            np.float32)
        yield FrameState(t, pp, vel, pv, colors, scales, q, opacity)


def smoke_drawn(shot: np.ndarray, share: float) -> bool:
    """Gray-to-white pixels (not the coloured frusta) over ``share`` of the page's middle."""
    h, w = shot.shape[:2]
    middle = shot[h // 4: 3 * h // 4, w // 3: 2 * w // 3].astype(np.float32)
    gray = (middle.max(axis=2) - middle.min(axis=2)) < 25
    return (gray & (middle.mean(axis=2) > 100)).mean() > share


def first_frame(run: Path, port: int, share: float) -> dict:
    with Chromium(WIDTH, HEIGHT) as browser:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        start = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "fluidnexus_cli", "view", str(run), "--port", str(port)],
                                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        try:
            said = ""
            while "viewer at" not in said:
                line = proc.stderr.readline()
                if not line and proc.poll() is not None:
                    raise RuntimeError(f"view stopped: {said}")
                said += line
            printed = time.perf_counter() - start
            browser.open(f"http://127.0.0.1:{port}/")
            connected = None
            while True:
                shot = browser.screenshot()
                if connected is None and browser.evaluate(PANEL_SHOWN):
                    connected = time.perf_counter() - start
                if connected is not None and smoke_drawn(shot, share):  # (a blank page is white too)
                    drawn = time.perf_counter() - start
                    break
                if time.perf_counter() - start > 180:
                    raise RuntimeError("no smoke drawn within 180 s")
                time.sleep(0.25)  # a screenshot costs the software renderer a frame
            return {"printed_address_s": printed, "page_shows_panel_s": connected, "smoke_drawn_s": drawn,
                    "log": said.strip().splitlines()[-1]}
        finally:
            proc.send_signal(signal.SIGINT)  # Ctrl-C
            proc.wait(20)


def picture(run: Path, port: int, path: Path, frame: int = 60, view_turn_deg: float = -125.0,
            view_distance: float = 1.5) -> None:
    """The page at ``frame`` once the cameras show their video frames, without the 'software WebGL' notice."""
    import cv2

    from fluidnexus.viewer import open_viewer

    served = open_viewer([run], port=port)
    try:
        with Chromium(WIDTH, HEIGHT) as browser:
            browser.open(served.url)
            while not served.server.get_clients():
                time.sleep(0.2)
            for thumbs in served.viewer.thumbnails:
                thumbs.join(120)
            served.viewer.frame.value = frame
            viewer, client = served.viewer, next(iter(served.server.get_clients().values()))
            center = 0.5 * (viewer.lo + viewer.hi)
            cams = np.array([m.camera.center for m in viewer.marks[0]])
            toward = cams.mean(0) - center
            toward = np.array([toward[0], 0.0, toward[2]]) / np.hypot(toward[0], toward[2])
            turn = np.radians(view_turn_deg)
            side = np.array([toward[2], 0.0, -toward[0]])
            eye = center + viewer.size * (view_distance * (np.cos(turn) * toward + np.sin(turn) * side) + [0, 1.2, 0])
            client.camera.position = tuple(eye)
            client.camera.look_at = tuple(0.5 * (center + cams.mean(0)))
            last = None
            while True:  # until two screenshots a second apart agree (the splats are sorted and drawn)
                time.sleep(1.0)
                browser.evaluate("document.querySelectorAll('.mantine-Notification-root, [role=alert]')"
                                 ".forEach(e => e.remove())")
                shot = browser.screenshot()
                if last is not None and np.abs(shot.astype(int) - last).max() <= 2:
                    break
                last = shot.astype(int)
            cv2.imwrite(str(path), shot[:, :, ::-1])
    finally:
        served.stop()


def frame_steps(run: Path, port: int, steps: int = 20) -> list[float]:
    from fluidnexus.viewer import open_viewer

    served = open_viewer([run], port=port)
    try:
        out = []
        for t in range(1, steps + 1):
            start = time.perf_counter()
            served.viewer.frame.value = t
            out.append(time.perf_counter() - start)
        return out
    finally:
        served.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--visual", type=int, default=40000)
    ap.add_argument("--physical", type=int, default=20000)
    ap.add_argument("--work", type=Path, default=None, help="folder for the scene and run (default: a temp folder)")
    ap.add_argument("--port", type=int, default=8093)
    ap.add_argument("--screenshot", type=Path, default=None)
    ap.add_argument("--smoke-share", type=float, default=0.03,
                    help="share of the page's middle the drawn smoke covers (a real run's thinner plume: 0.002)")
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench-view-"))
    scene, run = work / "scene", work / "run"
    if not (scene / "scene.json").is_file():
        subprocess.run([sys.executable, "-m", "fluidnexus_cli", "-q", "calibrate", "--sample", "scalarflow",
                        "--protocol", "four-view", "--out", str(scene)], cwd=ROOT, check=True)
    if not run.is_dir():
        import json

        volume = json.loads((scene / "scene.json").read_text())["volume"]
        t0 = time.perf_counter()
        write_run(run, scene, list(plume_states(volume["min"], volume["max"], args.frames, args.visual,
                                                args.physical)), h=0.02, dt=1 / 30)
        print(f"wrote {args.frames} frames of {args.visual} Gaussians / {args.physical} particles in "
              f"{time.perf_counter() - t0:.1f} s to {run}")
    result = first_frame(run, args.port, args.smoke_share)
    print(f"view {run.name}: address printed {result['printed_address_s']:.2f} s, panel shown "
          f"{result['page_shows_panel_s']:.2f} s, smoke drawn {result['smoke_drawn_s']:.2f} s after the command "
          f"started ({result['log']})")
    if args.screenshot is not None:
        picture(run, args.port + 2, args.screenshot)
        print(f"wrote {args.screenshot}")
    steps = frame_steps(run, args.port + 1)
    print(f"frame step (read, splats, send; in-process): median {1000 * np.median(steps):.0f} ms, "
          f"max {1000 * max(steps):.0f} ms over {len(steps)} steps")


if __name__ == "__main__":
    main()
