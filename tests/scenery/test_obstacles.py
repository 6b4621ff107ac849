"""Obstacles and source records in scene.json, and ``calibrate --obstacle``: parsing, frames, bad input."""
import json
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from clirun import invoke, ok
from commands.test_bad_input import assert_clean_failure

from fluidnexus.scene import load_scene
from fluidnexus.scenery.obstacles import MeshBody, SphereBody, engine_obstacle
from fluidnexus.world_frame import SourceFrame

INSIDE = (0.34, 0.25, -0.25)  # a point in the sample's volume


@pytest.fixture(scope="module")
def sample_scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("obstacles") / "scene"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--link", "--out", out)
    return out


def _edit(scene_dir, tmp_path, **changes):
    """A copy of the sample scene's scene.json (videos linked) with top-level fields changed."""
    data = json.loads((scene_dir / "scene.json").read_text())
    data.update(changes)
    (tmp_path / "videos").symlink_to(scene_dir / "videos")
    (tmp_path / "scene.json").write_text(json.dumps(data))
    return tmp_path


def _ball_file(path, center=INSIDE, radius=0.04):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    mesh.apply_translation(center)
    mesh.export(path)
    return path


def test_calibrate_obstacle_sphere_and_mesh_are_written_in_scene_coordinates(sample_scene, tmp_path):
    mesh = _ball_file(tmp_path / "ball.stl", center=(0.3, 0.4, -0.2))
    out = tmp_path / "scene"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--link", "--out", out,
       "--obstacle", "sphere:" + ",".join(map(str, (*INSIDE, 0.05))), "--obstacle", f"mesh:{mesh}")
    scene = load_scene(out)
    assert scene.obstacles[0] == SphereBody(INSIDE, 0.05)
    assert isinstance(scene.obstacles[1], MeshBody) and (out / scene.obstacles[1].file).is_file()
    written = trimesh.load(out / scene.obstacles[1].file, force="mesh")
    np.testing.assert_allclose(written.bounds.mean(axis=0), [0.3, 0.4, -0.2], atol=1e-6)


def test_obstacle_options_are_converted_by_the_source_frame(tmp_path):
    from fluidnexus.scenery.obstacles import parse_option, place_obstacles

    frame = SourceFrame.for_import("Z", 0.1)  # a z-up file in decimetres
    mesh = _ball_file(tmp_path / "ball.ply", center=(1.0, 2.0, 3.0), radius=0.5)
    bodies = place_obstacles([parse_option("sphere:1,2,3,0.5"), parse_option(f"mesh:{mesh}")], tmp_path, frame)
    np.testing.assert_allclose(bodies[0].center, [0.1, 0.3, -0.2], atol=1e-12)  # (x, z, -y) / 10
    assert bodies[0].radius == pytest.approx(0.05)
    moved = trimesh.load(tmp_path / bodies[1].file, force="mesh")
    np.testing.assert_allclose(moved.bounds.mean(axis=0), [0.1, 0.3, -0.2], atol=1e-6)


def test_engine_bodies_keep_points_out_of_every_obstacle(sample_scene, tmp_path, ti_engine):
    mesh = _ball_file(tmp_path / "ball.ply", center=(0.3, 0.4, -0.2))
    body = engine_obstacle((SphereBody(INSIDE, 0.05), MeshBody("ball.ply")), tmp_path)
    pts = np.random.default_rng(0).uniform([0.25, 0.2, -0.3], [0.4, 0.45, -0.15], (2000, 3))
    assert (body.distance(pts) < 0).sum() > 50
    import torch

    from fluidnexus.engine.obstacle import PointProjector

    out = PointProjector(len(pts))(body, torch.as_tensor(pts)).numpy()
    assert body.distance(out).min() > -2e-3  # the mesh's grid distance is within a grid cell of the true one
    assert mesh.exists()


@pytest.mark.parametrize("obstacles, needles", [
    ([{"kind": "sphere", "center": list(INSIDE), "radius": 0}], ["obstacles[0].radius", "> 0"]),
    ([{"kind": "sphere", "center": list(INSIDE), "radius": -1}], ["obstacles[0].radius"]),
    ([{"kind": "sphere", "center": list(INSIDE), "radius": 0.05},
      {"kind": "sphere", "center": [5, 5, 5], "radius": 0.1}], ["obstacles[1]", "outside the scene volume"]),
    ([{"kind": "box"}], ["obstacles[0].kind"]),
    ([{"kind": "mesh", "file": "missing.obj"}], ["obstacles[0].file", "file not found"]),
])
def test_bad_obstacles_in_scene_json(sample_scene, tmp_path, obstacles, needles):
    scene = _edit(sample_scene, tmp_path, obstacles=obstacles)
    result = invoke("recon", scene, "--out", tmp_path / "run", "--arch", "cpu")
    assert_clean_failure(result, "scene.json", *needles)
    assert not (tmp_path / "run").exists()


def test_unreadable_mesh_in_scene_json(sample_scene, tmp_path):
    scene = _edit(sample_scene, tmp_path, obstacles=[{"kind": "mesh", "file": "junk.obj"}])
    (tmp_path / "junk.obj").write_text("this is not a mesh\n")
    result = invoke("recon", scene, "--out", tmp_path / "run", "--frames", "0:2", "--arch", "cpu")
    assert_clean_failure(result, "scene.json", "obstacles[0].file", "junk.obj")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("source, needles", [
    ({"center": list(INSIDE), "radius": 0.02, "direction": [0, 0, 0]}, ["source.direction", "zero length"]),
    ({"center": list(INSIDE), "radius": 0.02, "speed": -1}, ["source.speed"]),
    ({"center": list(INSIDE), "radius": 0.02, "window": [5, 2]}, ["source.window"]),
])
def test_bad_source_in_scene_json(sample_scene, tmp_path, source, needles):
    scene = _edit(sample_scene, tmp_path, source=source)
    result = invoke("recon", scene, "--out", tmp_path / "run", "--arch", "cpu")
    assert_clean_failure(result, "scene.json", *needles)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("option, needle", [
    ("sphere:1,2,3", "sphere:CX,CY,CZ,R"),
    ("sphere:0.34,0.25,-0.25,0", "radius must be > 0"),
    ("cube:1", "sphere:CX,CY,CZ,R or mesh:FILE"),
    ("sphere:5,5,5,0.1", "outside the scene volume"),
    ("mesh:/nonexistent/ball.obj", "file not found"),
])
def test_bad_obstacle_option(tmp_path, option, needle):
    result = invoke("calibrate", "--sample", "scalarflow", "--out", tmp_path / "s", "--obstacle", option)
    assert_clean_failure(result, "--obstacle", needle)
    assert not (tmp_path / "s").exists()


def test_unreadable_mesh_in_a_fresh_process(sample_scene, tmp_path):
    """The same refusal from the installed command in its own process, where the engine starts for the first time:
    nothing on stdout (Taichi announces its arch there when it starts), one error line on stderr."""
    scene = _edit(sample_scene, tmp_path, obstacles=[{"kind": "mesh", "file": "junk.obj"}])
    (tmp_path / "junk.obj").write_text("this is not a mesh\n")
    proc = subprocess.run([sys.executable, "-m", "fluidnexus_cli", "recon", str(scene), "--out", str(tmp_path / "run"),
                           "--frames", "0:2", "--arch", "cpu"], capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for needle in ("scene.json", "obstacles[0].file", "junk.obj"):
        assert needle in lines[0], (needle, lines[0])
    assert not (tmp_path / "run").exists()
