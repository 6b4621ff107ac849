"""`render`, `eval` and `export` on a tiny reconstruction."""
import json

import numpy as np

from fluidnexus.export.npz import read_frame_npz
from fluidnexus.export.ply import read_gaussians_ply
from fluidnexus.export.vti import read_vti
from fluidnexus.state import load_frame
from fluidnexus.video import probe_video, read_video

from .conftest import invoke, ok


def test_eval_json_keys_and_values(tiny_run, tmp_path):
    result = ok("eval", tiny_run, "--json", tmp_path / "eval.json", "--arch", "cpu")
    scores = json.loads((tmp_path / "eval.json").read_text())
    assert set(scores) >= {"novel_view", "resimulation", "divergence", "frames", "resolution"}
    nv = scores["novel_view"]
    assert set(nv) >= {"psnr", "ssim", "lpips", "per_view"} and list(nv["per_view"]) == ["train02"]
    assert nv["lpips"] is None  # no weights given
    # a real reconstruction of a mostly black scene scores well above zero and below a perfect copy
    assert 18 < nv["psnr"] < 60 and 0.5 < nv["ssim"] <= 1
    assert abs(scores["resimulation"]["psnr"] - nv["psnr"]) < 1.0
    assert scores["divergence"]["mean_abs"] >= 0 and scores["frames"] == [0, 3]
    assert scores["resolution"]["width"] == 68 and scores["resolution"]["height"] == 120
    assert "novel views    PSNR" in result.output


def test_eval_psnr_matches_a_direct_computation(tiny_run, tmp_path, four_view_scene):
    """The reported PSNR equals one computed here from the rendered and the real frames."""
    ok("eval", tiny_run, "--json", tmp_path / "e.json", "--arch", "cpu")
    ok("render", tiny_run, "--out", tmp_path / "v", "--views", "train02", "--png", "--arch", "cpu")
    rendered = read_video(tmp_path / "v" / "train02", channels=1)  # PNG frames: exact 8-bit values
    real = read_video(four_view_scene / "ground_truth" / "train02.mp4", frames=slice(0, 3), size=(68, 120),
                      channels=1)
    mse = ((rendered - real) ** 2).reshape(3, -1).mean(1)
    expected = float(np.mean(10 * np.log10(1.0 / mse)))
    got = json.loads((tmp_path / "e.json").read_text())["novel_view"]["psnr"]
    assert abs(got - expected) < 0.2  # 8-bit rounding of the PNGs only


def test_render_compare_and_orbit(tiny_run, tmp_path):
    ok("render", tiny_run, "--out", tmp_path, "--compare", "--orbit", "5", "--arch", "cpu")
    info = probe_video(tmp_path / "train02_compare.mp4")
    assert info.frame_count == 3 and info.width == 68 * 2 + 4 and info.height == 120
    assert probe_video(tmp_path / "orbit.mp4").frame_count == 5


def test_render_backgrounds_and_the_alpha_matte(tiny_run, tmp_path):
    """--background black|plates|FILE and --alpha: on this black sample plates and black agree; an image puts
    the smoke over it; the matte is the smoke's own alpha (1 - T_N) as a gray video."""
    import cv2

    cv2.imwrite(str(tmp_path / "wall.png"), np.full((30, 20, 3), 200, np.uint8))
    for choice in ("black", "plates", str(tmp_path / "wall.png")):
        ok("render", tiny_run, "--out", tmp_path / "v", "--views", "train00", "--background", choice, "--alpha",
           "--arch", "cpu")
        video = read_video(tmp_path / "v" / "train00.mp4", channels=1)
        alpha = read_video(tmp_path / "v" / "train00_alpha.mp4", channels=1)
        if choice == "black":
            black = video
        elif choice == "plates":
            np.testing.assert_array_equal(video, black)
        else:  # I = C_smoke + (1 - alpha) B with B = 200/255, up to H.264 (three videos' codec errors)
            assert np.abs(video - (black + (1 - alpha) * 200 / 255)).mean() < 0.01
    assert alpha.max() > 0.1 and alpha.min() < 0.01
    (tmp_path / "broken.png").write_bytes(b"no image")
    result = invoke("render", tiny_run, "--out", tmp_path / "w", "--background", tmp_path / "broken.png",
                    "--arch", "cpu")
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1 and "broken.png" in lines[0] and "--background" in lines[0]
    assert not (tmp_path / "w").exists()


def test_render_unknown_view(tiny_run, tmp_path):
    result = invoke("render", tiny_run, "--out", tmp_path, "--views", "nope", "--arch", "cpu")
    assert result.exit_code == 2 and "unknown view 'nope'" in result.output


def test_export_ply_reads_back_identical(tiny_run, tmp_path):
    ok("export", tiny_run, "--format", "ply", "--out", tmp_path)
    state = load_frame(tiny_run / "frames" / "000002.npz")
    back = read_gaussians_ply(tmp_path / "000002.ply")
    np.testing.assert_array_equal(back["visual_positions"], state.visual_positions)
    np.testing.assert_array_equal(back["visual_rotations"], state.visual_rotations)
    np.testing.assert_allclose(back["visual_colors"], state.visual_colors, atol=1e-6)
    np.testing.assert_allclose(back["visual_scales"], state.visual_scales, rtol=1e-6)
    np.testing.assert_allclose(back["visual_opacities"], state.visual_opacities, atol=1e-6)


def test_export_vti_and_npz_fields(tiny_run, tmp_path):
    ok("export", tiny_run, "--format", "vti", "--out", tmp_path / "vti", "--voxel", "0.02", "--arch", "cpu")
    ok("export", tiny_run, "--format", "npz", "--out", tmp_path / "npz", "--voxel", "0.02", "--arch", "cpu")
    origin, spacing, arrays = read_vti(tmp_path / "vti" / "000001.vti")
    assert arrays["density"].ndim == 3 and arrays["velocity"].shape == arrays["density"].shape + (3,)
    assert arrays["density"].max() > 0  # the gas is inside the volume
    raw = read_frame_npz(tmp_path / "npz" / "000001.npz")
    np.testing.assert_allclose(raw["grid_density"], arrays["density"], rtol=1e-6)
    np.testing.assert_allclose(raw["grid_origin"], origin)
    state = load_frame(tiny_run / "frames" / "000001.npz")
    np.testing.assert_array_equal(raw["physical_positions"], state.physical_positions)
