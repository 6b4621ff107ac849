"""diagnose on footage over a backdrop and around obstacles: it sees the smoke's opacity
over each view's plate, leaves out views without a plate, and its plume flows around the scene's obstacles."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.diagnose.footage import run_layer
from fluidnexus.diagnose.plume import PlumeParams, PlumeSetup, PlumeSimulator
from fluidnexus.diagnose.run import load_observed
from fluidnexus.images import LUMA
from fluidnexus.scenery.static_layer import StaticLayer, save_static
from fluidnexus.scenery.world import Obstacles
from fluidnexus.video import read_video, write_frames

from .eulerian_plume import Grid, PlumeEffects, simulate, write_scene

SMOKE = np.array([0.12, 0.10, 0.09], np.float32)  # dark, absorbing smoke (PINF's kind) over a bright backdrop


def backdrop(width: int, height: int, phase: float) -> np.ndarray:
    """[H, W, 3] a bright textured wall: stripes and a gradient, each channel its own."""
    y, x = np.mgrid[0:height, 0:width] / np.array([height, width])[:, None, None]
    base = 0.72 + 0.12 * np.sin(11 * x + 7 * y + phase) + 0.06 * np.sign(np.sin(23 * y + phase))
    return np.clip(np.stack([base, 0.95 * base + 0.03, 0.9 * base + 0.05], -1), 0, 1).astype(np.float32)


def over_backdrop(black: Path, out: Path, held_out: str, wall=backdrop) -> Path:
    """The generator's scene ``black`` (gray opacity-like frames) as absorbing smoke over a wall (``wall(width,
    height, phase)``: a textured one), each input view with its plate given to ``fluidnexus background``;
    ``held_out`` becomes a ground-truth view (no plate)."""
    scene = json.loads((black / "scene.json").read_text())
    plates = []
    for i, view in enumerate(scene["views"]):
        a = read_video(black / view["video"], gray=True)
        plate = wall(a.shape[2], a.shape[1], phase=i)
        write_frames(out / view["video"], (plate * (1 - a) + SMOKE * a).astype(np.float32))
        if view["name"] != held_out:
            path = out / "plates" / f"{view['name']}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(path), cv2.cvtColor(np.rint(plate * 65535).astype(np.uint16), cv2.COLOR_RGB2BGR))
            plates += ["--plate", f"{view['name']}={path}"]
    truth = next(v for v in scene["views"] if v["name"] == held_out)
    scene["views"].remove(truth)
    scene["ground_truth"] = [{k: truth[k] for k in ("name", "camera", "video")}]
    (out / "scene.json").write_text(json.dumps(scene))
    result = CliRunner().invoke(main, ["background", str(out), *plates])
    assert result.exit_code == 0, result.output
    return out


def test_diagnose_sees_the_smoke_over_a_backdrop(template, tmp_path):
    """The images diagnose fits are the same smoke as on black, up to a gain, to within 10 % (measured 6.7 %: the
    smoke colour is the densest smoke's over all views, moved out to the brightest samples, and the smoke is not
    opaque here (peak opacity 0.8), so the opacity
    comes out scaled by a factor that follows the wall's brightness, and smoke fainter than the noise floor reads
    as none); the held-out view, which has no plate, is left out. (An image error of 0.0056 against diagnose's
    validation errors of 0.1-0.9.)"""
    black = write_scene(template, tmp_path / "black", simulate(12, PlumeEffects()))
    over = over_backdrop(black, tmp_path / "over", held_out="train03")
    ref, seen = load_observed(black, 0, 12, 40), load_observed(over, 0, 12, 40)
    assert "train03" not in seen.names and len(seen.names) == len(ref.names) - 1
    keep = [ref.names.index(n) for n in seen.names]
    truth, images = ref.images[keep], seen.images
    gain = (truth * images).sum() / (images * images).sum()
    error = np.linalg.norm(gain * images - truth) / np.linalg.norm(truth)
    assert error < 0.10, error
    # the raw frames would not do: the wall shows as smoke
    raw = np.stack([read_video(over / "videos" / n, gray=True)[..., 0] for n in seen.names if n != "train03"])
    assert raw.mean() > 5 * truth.mean()


def test_held_out_view_over_a_runs_static_layer(template, tmp_path, ti_engine):
    """Given a reconstruction's static layer, a view without a plate is seen over the layer rendered from its
    camera instead of being left out: over a plain wall that the layer holds (its background colour, no Gaussians
    in front), the held-out view's images are its smoke on black up to a gain, within the plated views' 10 % (measured
    3.2 %, over a gray layer 3.3 %; a plated view 3.5 %)."""
    wall = np.array([0.85, 0.83, 0.80], np.float32)
    black = write_scene(template, tmp_path / "black", simulate(12, PlumeEffects()))
    over = over_backdrop(black, tmp_path / "over", "train03", lambda w, h, phase: np.broadcast_to(wall, (h, w, 3)))
    empty = np.zeros((0, 3), np.float32)
    save_static(tmp_path / "run", StaticLayer(empty, empty, np.zeros((0, 4), np.float32), np.zeros(0, np.float32),
                                              empty, wall))
    assert run_layer(tmp_path) is None and run_layer(None) is None  # no run, or a run without a layer
    # a gray run (recon's default over a backdrop) has a gray layer: the view's frames are then read as gray too
    save_static(tmp_path / "gray", StaticLayer(empty, empty, np.zeros((0, 4), np.float32), np.zeros(0, np.float32),
                                               np.zeros((0, 1), np.float32), np.array([wall @ LUMA], np.float32)))
    ref = load_observed(black, 0, 12, 40)
    for run in ("run", "gray"):
        seen = load_observed(over, 0, 12, 40, run_layer(tmp_path / run))
        assert sorted(seen.names) == sorted(ref.names)
        for name in ("train03", "train01"):
            truth, images = ref.images[ref.names.index(name)], seen.images[seen.names.index(name)]
            gain = (truth * images).sum() / (images * images).sum()
            assert np.linalg.norm(gain * images - truth) / np.linalg.norm(truth) < 0.10, (run, name)
    # a layer that does not hold the wall (black beyond it) shows the wall as smoke in that view
    save_static(tmp_path / "dark", StaticLayer(empty, empty, np.zeros((0, 4), np.float32), np.zeros(0, np.float32),
                                               empty, np.zeros(3, np.float32)))
    dark = load_observed(over, 0, 12, 40, run_layer(tmp_path / "dark"))
    wrong = dark.images[dark.names.index("train03")]
    assert wrong.mean() > 5 * ref.images[ref.names.index("train03")].mean()


def test_plume_flows_around_the_scenes_obstacles(template, tmp_path, ti_engine):
    """A ball declared in scene.json right above the source: no smoke particle of either structure enters it, and
    the ball changes the rollout."""
    grid = Grid()
    scene_dir = write_scene(template, tmp_path / "scene", simulate(4, PlumeEffects()))
    ball = {"kind": "sphere", "center": [grid.source[0], grid.source[1] + 0.12, grid.source[2]], "radius": 0.05}
    data = json.loads((scene_dir / "scene.json").read_text())
    data["obstacles"] = [ball]
    (scene_dir / "scene.json").write_text(json.dumps(data))
    hi = tuple(np.asarray(grid.lo) + np.asarray(grid.shape) * grid.dx)
    for params in (PlumeParams(alpha=-1.0, k=1.0, layers=30.0), PlumeParams(structure="ambient_air", alpha=-0.3,
                                                                              c=0.3, inflow=0.6)):
        paths = []
        for obstacles in (Obstacles(str(scene_dir)), None):
            setup = PlumeSetup(grid.source, grid.source_radius, 0.02, grid.fps, 16, grid.lo, hi, np.zeros((0, 3)),
                               np.zeros((0, 3)), obstacles=obstacles)
            paths.append([p for p, _ in PlumeSimulator(setup).frames(params)])
        inside = [np.linalg.norm(p - ball["center"], axis=1) < 0.98 * ball["radius"] for p in paths[0]]
        assert not any(i.any() for i in inside), (params.structure, [int(i.sum()) for i in inside])
        free = [np.linalg.norm(p - ball["center"], axis=1) < 0.98 * ball["radius"] for p in paths[1]]
        assert sum(int(f.sum()) for f in free) > 0, params.structure  # without it, smoke passes there


def test_obstacles_of_a_run_are_the_runs(template, tmp_path, ti_engine):
    """Given a run folder, the bodies are the run's (scenery.world.run_scenery: its scene's declared ones, and those
    recon found in its static layer when it has one): here a run without a static layer keeps the declared ball."""
    from fluidnexus.runs import RUN_FORMAT

    scene_dir = write_scene(template, tmp_path / "scene", simulate(2, PlumeEffects()))
    data = json.loads((scene_dir / "scene.json").read_text())
    data["obstacles"] = [{"kind": "sphere", "center": [0.33, 0.1, -0.25], "radius": 0.04}]
    (scene_dir / "scene.json").write_text(json.dumps(data))
    run = tmp_path / "run"
    (run / "frames").mkdir(parents=True)
    (run / "frames" / "000000.npz").write_bytes(b"")
    (run / "run.json").write_text(json.dumps({"format": RUN_FORMAT, "kind": "recon", "scene": str(scene_dir)}))
    (run / "config.json").write_text("{}")
    body = Obstacles(str(scene_dir), str(run)).body()
    assert body.center == (0.33, 0.1, -0.25) and body.radius == 0.04
    assert Obstacles(str(scene_dir)).body().center == body.center


def test_a_scene_without_a_source_gets_the_foot_of_its_smoke(template, tmp_path):
    """A scene that declares no source (a PINF import): the simulated plume's source is the foot of the earliest
    smoke the views' hull holds, near the generator's inflow disk, not ScalarFlow's inflow."""
    from fluidnexus.diagnose.run import DEFAULT_SOURCE, plume_source
    from fluidnexus.scene import load_scene

    grid = Grid()
    scene_dir = write_scene(template, tmp_path / "scene", simulate(12, PlumeEffects()))
    data = json.loads((scene_dir / "scene.json").read_text())
    del data["source"]
    (scene_dir / "scene.json").write_text(json.dumps(data))
    observed = load_observed(scene_dir, 0, 12, 40)
    (center, radius), how = plume_source(load_scene(scene_dir), observed, 0.02, 1.0)
    assert how.startswith("found"), how
    error = np.linalg.norm(np.subtract(center, grid.source))  # measured 1.5 cm (one 2 cm lattice layer above)
    assert error < 0.02 and error < np.linalg.norm(np.subtract(center, DEFAULT_SOURCE[0])) / 2, (center, error)
    assert abs(radius - grid.source_radius) < 0.4 * grid.source_radius, radius  # measured 0.058 for 0.05
