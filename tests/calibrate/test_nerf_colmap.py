"""NeRF transforms.json and COLMAP sparse-model import."""
import json
import math

import numpy as np
from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.camera import Camera
from fluidnexus.scene import load_scene


def rig(n=3, width=16, height=12):
    cams = {}
    for i in range(n):
        a = math.radians(30 * (i - 1))
        cams[f"cam{i}"] = Camera.look_at(width, height, 18.0 + i, [math.sin(a), 0.4, math.cos(a)], [0, 0.3, 0])
    return cams


def test_from_nerf(tmp_path, make_video):
    cams = rig()
    frames = []
    for name, cam in cams.items():
        make_video(tmp_path / f"{name}.mp4", frames=5)
        nerf = cam.to_nerf()
        frames.append({"file_path": f"./{name}", "transform_matrix": nerf["transform_matrix"], "fl_x": nerf["fl_x"],
                       "fl_y": nerf["fl_y"], "cx": nerf["cx"], "cy": nerf["cy"]})
    (tmp_path / "transforms.json").write_text(json.dumps({"camera_angle_x": 0.7, "frames": frames}))
    result = CliRunner().invoke(main, ["calibrate", "--from-nerf", str(tmp_path / "transforms.json"),
                                       "--input", "cam0,cam2", "--novel", "cam1", "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    scene = load_scene(tmp_path / "s")
    assert scene.frame_count == 5 and scene.fps == 30
    assert [v.role for v in scene.views] == ["input", "input", "novel"]
    for v in scene.views:
        np.testing.assert_allclose(v.camera.K, cams[v.name].K, atol=1e-12)
        np.testing.assert_allclose(v.camera.w2c, cams[v.name].w2c, atol=1e-12)


def test_from_colmap(tmp_path, make_video):
    import pycolmap

    cams = rig()
    rec = pycolmap.Reconstruction()
    for i, (name, cam) in enumerate(cams.items(), start=1):
        pc_cam, pose = cam.to_pycolmap(camera_id=i)
        rec.add_camera_with_trivial_rig(pc_cam)
        image = pycolmap.Image(name=f"{name}.png", camera_id=i, image_id=i)
        rec.add_image_with_trivial_frame(image, pose)
    model = tmp_path / "project" / "sparse" / "0"
    model.mkdir(parents=True)
    rec.write_text(str(model))
    media = tmp_path / "project" / "images"
    media.mkdir()
    for name in cams:
        make_video(media / f"{name}.mp4", frames=3)
    result = CliRunner().invoke(main, ["calibrate", "--from-colmap", str(model), "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    scene = load_scene(tmp_path / "s")
    assert scene.view_names() == list(cams) and scene.frame_count == 3
    for v in scene.views:
        assert v.role == "input"
        np.testing.assert_allclose(v.camera.K, cams[v.name].K, atol=1e-9)
        np.testing.assert_allclose(v.camera.w2c, cams[v.name].w2c, atol=1e-9)


def test_from_nerf_in_centimetres(tmp_path, make_video):
    """A transforms.json written in centimetres, imported with --metres-per-unit 0.01, gives the metric rig."""
    cams = rig()
    frames = []
    for name, cam in cams.items():
        make_video(tmp_path / f"{name}.mp4", frames=3)
        c2w = np.array(cam.to_nerf()["transform_matrix"])
        c2w[:3, 3] *= 100.0
        frames.append({"file_path": f"./{name}", "transform_matrix": c2w.tolist(), "fl_x": float(cam.K[0, 0])})
    (tmp_path / "transforms.json").write_text(json.dumps({"frames": frames}))
    result = CliRunner().invoke(main, ["calibrate", "--from-nerf", str(tmp_path / "transforms.json"),
                                       "--metres-per-unit", "0.01", "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    scene = load_scene(tmp_path / "s")
    assert scene.source_frame.metres_per_unit == 0.01
    for v in scene.views:
        np.testing.assert_allclose(v.camera.w2c, cams[v.name].w2c, atol=1e-12)
