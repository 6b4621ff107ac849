"""``fluidnexus view`` in a real browser: headless Chromium (WebGL on SwiftShader) opens the viewer of a tiny run,
looks through the run's input camera, and the screenshots must show the smoke where the frame's Gaussians project
and nowhere else; moving the time slider (from Python, as the page does) must move it.

Skipped, with the reason, where viser or Chromium is not installed."""
import time

import numpy as np
import pytest

from fluidnexus.state import FrameState

from handmade_run import write_run
from handmade_scene import ring_camera, write_scene
from view.ports import free_port

pytest.importorskip("viser", reason="viser is not installed (pip install 'fluidnexus[view]')")
from view.browser import Chromium, find_chromium  # noqa: E402 (needs websockets, which viser brings)

pytestmark = pytest.mark.skipif(find_chromium() is None,
                                reason="no Chromium to drive (Debian: apt-get install chromium; or set "
                                       "FLUIDNEXUS_CHROMIUM)")

WIDTH, HEIGHT = 1280, 640  # the page; the control panel floats over its right ~360 pixels
PANEL = 380
MARGIN = 40  # pixels round the projected blob left out of "elsewhere"
FRAMES = 4
SIGMA = 0.05  # spread of the smoke blob, m


def blob_center(frame: int) -> np.ndarray:
    return np.array([0.0, 0.28 + 0.15 * frame, 0.0])


def blob_state(frame: int) -> FrameState:
    """A round blob of gray Gaussians that rises 0.15 m per frame."""
    rng = np.random.default_rng(frame)
    n = 400
    pos = (rng.normal(size=(n, 3)) * SIGMA + blob_center(frame)).astype(np.float32)
    vel = np.tile([0.0, 0.15 * 25, 0.0], (n, 1)).astype(np.float32)
    return FrameState(frame, pos, vel, pos, np.full((n, 1), 0.95, np.float32), np.full((n, 3), 0.025, np.float32),
                      np.tile([1.0, 0, 0, 0], (n, 1)).astype(np.float32), np.full(n, 0.6, np.float32))


@pytest.fixture(scope="module")
def blob_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("view")
    scene = write_scene(tmp / "scene", [("front", "input", ring_camera(0), None),
                                        ("side", "novel", ring_camera(90), None)],
                        ground_truth=[("back", ring_camera(200), "videos/back.mp4")], frame_count=FRAMES)
    return write_run(tmp / "run", scene, [blob_state(t) for t in range(FRAMES)], h=0.1, dt=1 / 25)


def projected_box(frame: int, fov: float) -> tuple[slice, slice]:
    """Rows and columns of the page where the blob (3 sigma, plus the Gaussians' own size) of ``frame`` lands when
    seen through the ``front`` camera with vertical field of view ``fov`` on the whole page."""
    cam = ring_camera(0)
    xc = cam.R @ blob_center(frame) + cam.t
    f = 0.5 * HEIGHT / np.tan(0.5 * fov)
    u, v = 0.5 * WIDTH + f * xc[0] / xc[2], 0.5 * HEIGHT + f * xc[1] / xc[2]
    r = f * (3 * SIGMA + 0.05) / xc[2]
    return slice(int(v - r), int(v + r)), slice(int(u - r), int(u + r))


def brightness(shot: np.ndarray) -> np.ndarray:
    return shot.astype(np.float32).mean(axis=2)


def wait_for(condition, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value is not None and value is not False:
            return value
        time.sleep(0.25)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def settled(browser: Chromium, test, timeout: float = 60.0) -> np.ndarray:
    """A screenshot that passes ``test`` and equals the next one (the page finished drawing)."""
    last = [None]

    def check():
        shot = browser.screenshot()
        ready = last[0] is not None and test(shot) and np.abs(shot.astype(int) - last[0]).max() <= 2
        last[0] = shot.astype(int)
        return shot if ready else None

    return wait_for(check, timeout, "the page to draw")


def test_smoke_is_drawn_where_the_frame_projects_and_moves_with_the_slider(blob_run):
    from fluidnexus.viewer import open_viewer

    served = open_viewer([blob_run], port=free_port())
    try:
        with Chromium(WIDTH, HEIGHT) as browser:
            browser.open(served.url)
            wait_for(lambda: served.server.get_clients() or None, 60, "the page to connect")
            viewer = served.viewer
            viewer.look.value = "front"
            client = next(iter(served.server.get_clients().values()))
            fov = wait_for(lambda: client.camera.fov if abs(client.camera.fov - frustum_fov()) < 1e-3 else None, 30,
                           "the browser's camera to take the front camera's field of view")
            rows0, cols0 = projected_box(0, fov)
            rows3, cols3 = projected_box(3, fov)
            assert cols0.stop < WIDTH - PANEL and rows3.stop < rows0.start  # the two boxes are apart, left of the panel

            def smoke_in(rows, cols):
                return lambda shot: brightness(shot)[rows, cols].max() > 100

            with_smoke = settled(browser, smoke_in(rows0, cols0))
            viewer.smoke_on.value = False
            without = settled(browser, lambda shot: not smoke_in(rows0, cols0)(shot))
            diff = np.abs(brightness(with_smoke) - brightness(without))
            inside = np.zeros(diff.shape, bool)
            inside[rows0, cols0] = True
            near = np.zeros(diff.shape, bool)  # the blob's outliers, and what it hides (the source disk below it)
            near[rows0.start - MARGIN:rows0.stop + MARGIN, cols0.start - MARGIN:cols0.stop + MARGIN] = True
            elsewhere = ~near
            elsewhere[:, WIDTH - PANEL:] = False  # the panel's checkbox changed
            assert diff[inside].mean() > 8.0, diff[inside].mean()
            assert diff[elsewhere].mean() < 0.05 * diff[inside].mean(), (diff[elsewhere].mean(), diff[inside].mean())
            assert (diff[elsewhere] > 40).mean() < 1e-3
            ys, xs = np.nonzero(diff > 40)
            center = np.array([ys.mean(), xs.mean()])
            expected = np.array([0.5 * (rows0.start + rows0.stop), 0.5 * (cols0.start + cols0.stop)])
            assert np.abs(center - expected).max() < 12, (center, expected)

            viewer.smoke_on.value = True
            settled(browser, smoke_in(rows0, cols0))
            viewer.frame.value = 3
            assert viewer.shown == 3
            moved = settled(browser, smoke_in(rows3, cols3))
            b0, b3 = brightness(with_smoke), brightness(moved)
            assert b3[rows3, cols3].mean() > b0[rows3, cols3].mean() + 8
            assert b3[rows0, cols0].mean() < b0[rows0, cols0].mean() - 8
    finally:
        served.stop()


def frustum_fov() -> float:
    from fluidnexus.viewer.content import frustum_pose

    return frustum_pose(ring_camera(0)).fov
