"""The generated scene family (benchmarks/scenes, issue 30) checked on its smallest scenes (seconds each):
determinism, the PINF import, the truth against the footage, the renderer's occlusion, the solver's mass and
obstacles, and the file's unit and up axis."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from benchmarks.scenes import DEVELOPMENT_SEEDS, HELD_OUT_SEEDS, HeldOutError, check_seeds, draw, generate
from benchmarks.scenes.geometry import PinholeCamera, surfaces
from benchmarks.scenes.raymarch import render
from benchmarks.scenes.smoke_solver import Grid, Inflow, simulate
from benchmarks.scenes.spec import Backdrop, Body
from clirun import ok
from fluidnexus.calibrate.pinf import read_pinf
from fluidnexus.scene import load_ground_truth, load_scene
from fluidnexus.video import read_video

# tiny scenes drawn from seeds outside both halves (tests are not a place to look at development or held-out scenes)
SEEDS = (901, 902, 903, 904)  # 904: a moving held-out camera


def frames_of(folder, name):
    return read_video(folder / f"{name}.mp4")


def test_same_seed_same_scene_and_other_seeds_differ(tmp_path):
    a, b, c = (generate(s, tmp_path / n, "tiny") for s, n in ((901, "a"), (901, "b"), (902, "c")))
    assert a.read_text() == b.read_text()
    assert (a.parent / "truth.json").read_text() == (b.parent / "truth.json").read_text()
    for name in ("train00", "test00"):
        assert np.array_equal(frames_of(a.parent, name), frames_of(b.parent, name))
    assert a.read_text() != c.read_text()


def test_every_choice_is_drawn_across_seeds():
    """The distribution, not one scene: over 60 seeds every kind of source, backdrop, layout, elevation, unit and up
    axis appears, sources are not all at the box's centre, and some held-out cameras move."""
    specs = [draw(s, "tiny") for s in range(1000, 1060)]
    seen = {key: {f(s) for s in specs} for key, f in {
        "source": lambda s: s.source.kind, "backdrop": lambda s: s.backdrop.kind, "layout": lambda s: s.rig.layout,
        "elevation": lambda s: s.rig.elevation, "unit": lambda s: s.unit, "up": lambda s: s.up,
        "moving": lambda s: s.rig.moving, "burst": lambda s: s.source.window[1] is not None,
        "obstacle": lambda s: tuple(sorted(b.kind for b in s.obstacles)) != (),
        "smoke": lambda s: s.smoke.mode}.items()}
    assert seen["source"] == {"plume", "jet", "puff"}
    assert seen["backdrop"] == {"black", "white", "wall", "set"}
    assert seen["layout"] == {"arc", "ring"} and seen["elevation"] == {"level", "elevated", "low"}
    assert seen["unit"] == {"mm", "cm", "m"} and seen["up"] == {"Y", "Z"}
    assert seen["moving"] == seen["burst"] == seen["obstacle"] == {True, False}
    assert seen["smoke"] == {"glowing", "absorbing"}
    off_centre = [np.abs((np.asarray(s.source.center) - np.asarray(s.lo)) / (np.asarray(s.hi) - np.asarray(s.lo))
                         - 0.5)[[0, 2]].max() for s in specs]
    assert np.percentile(off_centre, 75) > 0.1
    lengths = [s.length for s in specs]
    assert min(lengths) < 0.4 and max(lengths) > 1.5  # scenes from decimetres to metres


def test_splits_are_disjoint_and_held_out_seeds_are_refused():
    assert not set(DEVELOPMENT_SEEDS) & set(HELD_OUT_SEEDS)
    check_seeds(DEVELOPMENT_SEEDS, held_out=False)
    with pytest.raises(HeldOutError):
        check_seeds([DEVELOPMENT_SEEDS[0], HELD_OUT_SEEDS[0]], held_out=False)
    check_seeds(HELD_OUT_SEEDS, held_out=True)


def test_scene_imports_as_a_pinf_capture(tmp_path):
    """Through the CLI as a user runs it: five cameras, the drawn frame count, metres and +y up, and a moving
    held-out camera with one pose per frame."""
    seed = next(s for s in range(900, 1000) if draw(s, "tiny").rig.moving)
    info = generate(seed, tmp_path / "cap", "tiny")
    truth = json.loads((info.parent / "truth.json").read_text())
    cap = read_pinf(info, truth["file"]["metres_per_unit"])
    assert sorted(cap.recordings) == ["test00", "train00", "train01", "train02", "train03"]
    assert cap.frame_count == truth["frames"] and cap.fps == truth["fps"]
    poses = cap.recordings["test00"].poses
    assert poses is not None and len(poses) == truth["frames"]
    assert not np.allclose(poses[0], poses[-1])
    proto = truth["protocols"]["four-view"]
    ok("calibrate", "--from-pinf", info, "--input", proto["input"], "--ground-truth", proto["ground_truth"],
       *truth["calibrate_args"], "--out", tmp_path / "scene")
    scene = load_scene(tmp_path / "scene")
    assert len(scene.views) == 4 and scene.frame_count == truth["frames"]
    assert np.allclose(scene.volume.min, truth["volume"]["min"]) and np.allclose(scene.volume.max,
                                                                                  truth["volume"]["max"])
    gt = load_ground_truth(tmp_path / "scene")
    assert len(gt) == 1 and gt[0].poses is not None and len(gt[0].poses) == truth["frames"]


@pytest.mark.parametrize("seed", SEEDS)
def test_true_source_projects_onto_smoke_in_every_camera(tmp_path, seed):
    """truth.json's source, projected through the imported cameras (the file's unit and up axis undone by the
    importer), lands on smoke: in a frame after the source switched on, the pixels around it differ from the clean
    plate, in every camera that sees the source (not hidden behind a body of the set)."""
    info = generate(seed, tmp_path / "cap", "tiny")
    truth = json.loads((info.parent / "truth.json").read_text())
    spec = draw(seed, "tiny")
    cap = read_pinf(info, truth["file"]["metres_per_unit"])
    start = truth["source"]["window"][0]
    t = min(start + 2, truth["frames"] - 1)
    center = np.asarray(truth["source"]["center"])
    checked = 0
    for name, rec in cap.recordings.items():
        cam = rec.camera if rec.poses is None else replace(rec.camera, w2c=rec.poses[t])
        uv, depth = cam.project(center[None])
        eye = cam.center
        ray = (center - eye) / np.linalg.norm(center - eye)
        t_body, _ = surfaces(eye, ray[None], spec.bodies, Backdrop("black"))
        if t_body[0] < np.linalg.norm(center - eye):
            continue  # a body of the scene stands in front of the source in this view
        video = frames_of(info.parent, name)
        i, j = (int(v) for v in uv[0])
        assert depth[0] > 0 and 0 <= i < cam.width and 0 <= j < cam.height, (name, uv)
        patch = lambda f: f[max(j - 1, 0):j + 2, max(i - 1, 0):i + 2]  # noqa: E731
        change = np.abs(patch(video[t]) - patch(video[0])).max()
        assert change > 0.05, (name, change)
        checked += 1
    assert checked >= 3


def test_box_in_front_hides_smoke_and_smoke_hides_box_behind():
    """The renderer's depth test: a box between the camera and a smoke blob shows the box's colour exactly where
    the blob would be; a box behind the blob is covered by it."""
    grid = Grid((-0.5, -0.5, -0.5), 0.05, (20, 20, 20))
    c = grid.centres()
    density = np.exp(-np.sum(c**2, -1) / 0.02)[None].astype(np.float32)
    cam = PinholeCamera.look_at(32, 32, 40.0, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    back = Backdrop("black")
    smoke = render(cam, density, grid, 5.0, (1.0, 1.0, 1.0), (), back)[0]
    assert smoke[16, 16].min() > 0.5
    front = Body("box", (0.0, 0.0, 1.2), half=(0.15, 0.15, 0.05), color=(0.2, 0.4, 0.9))
    hidden = render(cam, density, grid, 5.0, (1.0, 1.0, 1.0), (front,), back)[0]
    _, bare = surfaces(*cam.rays(), (front,), back)
    assert np.allclose(hidden[16, 16], bare.reshape(32, 32, 3)[16, 16], atol=1e-6)
    assert hidden[16, 16, 2] > hidden[16, 16, 0]  # blue box, not white smoke
    behind = Body("box", (0.0, 0.0, -0.8), half=(0.15, 0.15, 0.05), color=(0.2, 0.4, 0.9))
    covered = render(cam, density, grid, 5.0, (1.0, 1.0, 1.0), (behind,), back)[0]
    assert covered[16, 16].min() > 0.5 and abs(covered[16, 16, 0] - covered[16, 16, 2]) < 0.3


def test_solver_books_mass_and_keeps_smoke_out_of_solids():
    """A plume under a ball a little off its axis: the smoke in the box is what was emitted minus what left through
    the walls (the rescale that makes it so stays within 6 % of 1 in the median step, measured 1.034: the
    advection's own loss), no smoke is ever inside the ball, and smoke gets past it (above its top: 7.5 % of it
    at frame 39)."""
    grid = Grid((0.0, 0.0, 0.0), 0.05, (16, 24, 16))
    ball = Body("sphere", (0.45, 0.4, 0.4), radius=0.12)
    inflow = Inflow((0.4, 0.1, 0.4), 0.08, (0.0, 1.0, 0.0), 0.3, (0, None), 2.0)
    flow = simulate(grid, inflow, 40, 25.0, (ball,), vorticity=0.1, seed=1)
    assert flow.solid.sum() > 40
    assert np.all(flow.density[:, flow.solid] == 0)
    assert flow.density[-1].sum() == pytest.approx(flow.emitted - flow.outflow, rel=1e-5)
    assert abs(np.median(flow.mass_factors) - 1.0) < 0.06
    above = (grid.centres()[..., 1] > 0.4 + 0.12 + grid.dx)
    assert flow.density[-1][above].sum() > 0.03 * flow.density[-1].sum()


def test_units_and_up_axes_import_to_the_same_metric_scene(tmp_path):
    """The same scene written y-up in metres, z-up in millimetres and y-up in centimetres: imported with its unit,
    every camera, the volume and the footage are the same (scene.json is metres, +y up)."""
    seed = SEEDS[0]
    variants = {"m_y": dict(unit="m", up="Y"), "mm_z": dict(unit="mm", up="Z"), "cm_y": dict(unit="cm", up="Y")}
    scenes = {}
    for key, over in variants.items():
        info = generate(seed, tmp_path / key, "tiny", **over)
        truth = json.loads((info.parent / "truth.json").read_text())
        assert truth["file"]["unit"] == over["unit"] and truth["file"]["up"] == over["up"]
        ok("calibrate", "--from-pinf", info, "--input", "train00,train01,train02,train03", "--ground-truth",
           "test00", *truth["calibrate_args"], "--out", tmp_path / f"S_{key}")
        scenes[key] = (load_scene(tmp_path / f"S_{key}"), load_ground_truth(tmp_path / f"S_{key}"))
    raw = json.loads(generate(seed, tmp_path / "raw", "tiny", unit="mm", up="Z").read_text())
    assert raw["rot"] == "Z"
    ref, ref_gt = scenes["m_y"]
    for key, (scene, gt) in scenes.items():
        assert np.allclose(scene.volume.min, ref.volume.min, atol=1e-9)
        assert np.allclose(scene.volume.max, ref.volume.max, atol=1e-9)
        for v, r in zip(scene.views + tuple(gt), ref.views + tuple(ref_gt)):
            assert v.name == r.name
            assert np.allclose(v.camera.w2c, r.camera.w2c, atol=1e-9), (key, v.name)
            assert np.allclose(v.camera.K, r.camera.K)
        assert np.array_equal(read_video(scene.root / scene.views[0].video),
                              read_video(ref.root / ref.views[0].video))


def test_table_refuses_held_out_seeds_without_the_flag(tmp_path):
    """bench_scene_family.py stops before generating anything when asked for a held-out seed without --held-out."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    for extra in (["--split", "held-out"], ["--seeds", f"{DEVELOPMENT_SEEDS[0]},{HELD_OUT_SEEDS[0]}"]):
        proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_scene_family.py"), "--work",
                               str(tmp_path / "w"), *extra], capture_output=True, text=True, cwd=root)
        assert proc.returncode != 0 and "held out" in proc.stderr, proc.stderr
        assert not (tmp_path / "w").exists()


def test_table_compares_the_halves_on_the_backdrops_they_share():
    """by_backdrop weights each backdrop kind the halves share by its count in the development half: a held-out
    half that drew more of an easy kind scores the same as a development half whose like scenes score the same."""
    from benchmarks.bench_scene_family import backdrop_table, by_backdrop

    def row(seed, split, kind, psnr):
        return {"seed": seed, "split": split, "protocol": "four-view", "scene": {"backdrop": kind},
                "nvs": {"psnr": psnr}}

    rows = [row(1, "development", "black", 30.0), row(2, "development", "white", 20.0),
            row(3, "development", "set", 10.0),
            row(7301, "held-out", "black", 30.0), row(7302, "held-out", "black", 30.0),
            row(7303, "held-out", "black", 30.0), row(7304, "held-out", "white", 20.0),
            {"seed": 7305, "split": "held-out", "protocol": "four-view", "error": "refused"}]
    summary = by_backdrop(rows)
    s = summary["four-view"]
    assert s["shared_kinds"] == ["black", "white"]
    assert s["matched_nvs_psnr"] == {"development": 25.0, "held-out": 25.0}
    assert s["kinds"]["set"]["held-out"] == {"scenes": 0, "nvs_psnr": None}
    assert s["kinds"]["black"]["held-out"] == {"scenes": 3, "nvs_psnr": 30.0}
    assert "| shared kinds (black, white), the development half's mix | 25.00 | 25.00 |" in backdrop_table(summary)
