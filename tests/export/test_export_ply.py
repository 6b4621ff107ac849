import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from fluidnexus.errors import InputError
from fluidnexus.export.ply import OPACITY_EPS, PROPERTIES, SH_C0, read_gaussians_ply, write_gaussians_ply
from fluidnexus.state import FrameState


def random_state(rng, m=300, channels=3, frame=7):
    q = rng.normal(size=(m, 4))
    return FrameState(
        frame=frame,
        physical_positions=rng.normal(size=(5, 3)).astype(np.float32),
        physical_velocities=rng.normal(size=(5, 3)).astype(np.float32),
        visual_positions=rng.normal(size=(m, 3)).astype(np.float32),
        visual_colors=rng.random((m, channels)).astype(np.float32),
        visual_scales=np.exp(rng.uniform(-7, 0, size=(m, 3))).astype(np.float32),
        visual_rotations=(q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32),
        visual_opacities=rng.uniform(0.01, 0.99, size=m).astype(np.float32),
    )


def quat_to_matrix(q):
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


@pytest.mark.parametrize("channels", [3, 1])
def test_round_trip_gives_identical_gaussians(tmp_path, channels):
    state = random_state(np.random.default_rng(0), channels=channels)
    write_gaussians_ply(tmp_path / "f.ply", state)
    back = read_gaussians_ply(tmp_path / "f.ply")
    assert all(v.dtype == np.float32 for v in back.values())
    np.testing.assert_array_equal(back["visual_positions"], state.visual_positions)
    np.testing.assert_array_equal(back["visual_rotations"], state.visual_rotations)
    assert back["visual_colors"].shape == state.visual_colors.shape
    # float32 round-off of the affine SH map, the log and the logit (each a few 1e-8)
    np.testing.assert_allclose(back["visual_colors"], state.visual_colors, rtol=0, atol=2e-7)
    np.testing.assert_allclose(back["visual_scales"], state.visual_scales, rtol=5e-7, atol=0)
    np.testing.assert_allclose(back["visual_opacities"], state.visual_opacities, rtol=0, atol=2e-7)
    FrameState(state.frame, state.physical_positions, state.physical_velocities, **back)  # usable as a state


def test_file_has_the_reference_3dgs_layout(tmp_path):
    state = random_state(np.random.default_rng(1), m=20)
    write_gaussians_ply(tmp_path / "f.ply", state)
    ply = PlyData.read(str(tmp_path / "f.ply"))
    assert not ply.text and ply.byte_order == "<"
    vertex = ply["vertex"].data
    assert vertex.dtype.names == PROPERTIES and len(PROPERTIES) == 62
    assert all(vertex.dtype[n] == np.dtype("<f4") for n in PROPERTIES)
    for n in ("nx", "ny", "nz", *(f"f_rest_{i}" for i in range(45))):
        assert np.all(vertex[n] == 0)
    c, o, s = (np.float64(a) for a in (state.visual_colors, state.visual_opacities, state.visual_scales))
    for i in range(3):
        np.testing.assert_allclose(vertex[f"f_dc_{i}"], (c[:, i] - 0.5) / SH_C0, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(vertex[f"scale_{i}"], np.log(s[:, i]), rtol=1e-6)
    np.testing.assert_allclose(vertex["opacity"], np.log(o / (1 - o)), rtol=1e-6, atol=1e-6)
    header = "\n".join(ply.comments)
    assert "+y down" in header and "logit" in header and "fluidnexus frame 7" in header


def test_gray_is_replicated_to_rgb(tmp_path):
    state = random_state(np.random.default_rng(2), m=10, channels=1)
    write_gaussians_ply(tmp_path / "f.ply", state)
    vertex = PlyData.read(str(tmp_path / "f.ply"))["vertex"].data
    np.testing.assert_array_equal(vertex["f_dc_0"], vertex["f_dc_1"])
    np.testing.assert_array_equal(vertex["f_dc_0"], vertex["f_dc_2"])


def test_file_is_the_world_rotated_half_a_turn_about_x(tmp_path):
    state = random_state(np.random.default_rng(3), m=50)
    write_gaussians_ply(tmp_path / "f.ply", state)
    v = PlyData.read(str(tmp_path / "f.ply"))["vertex"].data
    flip = np.diag([1.0, -1.0, -1.0])  # proper rotation: det = +1
    xyz = np.stack([v["x"], v["y"], v["z"]], 1)
    np.testing.assert_array_equal(xyz, state.visual_positions @ flip)
    q_file = np.stack([v[f"rot_{k}"] for k in range(4)], 1).astype(np.float64)
    R_world = quat_to_matrix(state.visual_rotations.astype(np.float64))
    np.testing.assert_allclose(quat_to_matrix(q_file), flip @ R_world, atol=1e-6)
    # the covariance R S^2 R^T of each Gaussian is the world covariance seen in the flipped frame
    S2 = np.exp(2 * np.stack([v[f"scale_{k}"] for k in range(3)], 1).astype(np.float64))
    cov_file = np.einsum("nij,nj,nkj->nik", quat_to_matrix(q_file), S2, quat_to_matrix(q_file))
    s2 = state.visual_scales.astype(np.float64) ** 2
    cov_world = np.einsum("nij,nj,nkj->nik", R_world, s2, R_world)
    np.testing.assert_allclose(cov_file, flip @ cov_world @ flip, rtol=1e-5, atol=1e-12)


def test_opacity_zero_and_one_are_clamped_to_finite_logits(tmp_path):
    state = random_state(np.random.default_rng(4), m=4)
    state.visual_opacities[:] = [0.0, 1.0, 0.5, 1e-9]
    write_gaussians_ply(tmp_path / "f.ply", state)
    logits = PlyData.read(str(tmp_path / "f.ply"))["vertex"].data["opacity"]
    limit = np.log((1 - OPACITY_EPS) / OPACITY_EPS)
    np.testing.assert_allclose(logits, [-limit, limit, 0.0, -limit], rtol=1e-6)
    back = read_gaussians_ply(tmp_path / "f.ply")["visual_opacities"]
    np.testing.assert_allclose(back, [OPACITY_EPS, 1 - OPACITY_EPS, 0.5, OPACITY_EPS], rtol=1e-5)


def test_non_positive_scale_is_rejected(tmp_path):
    state = random_state(np.random.default_rng(5), m=4)
    state.visual_scales[2, 1] = 0.0
    with pytest.raises(InputError, match="visual_scales.*> 0"):
        write_gaussians_ply(tmp_path / "f.ply", state)
    assert not (tmp_path / "f.ply").exists()


def test_reads_a_foreign_degree_3_file_and_ignores_view_dependence(tmp_path):
    names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", *(f"f_rest_{i}" for i in range(45)), "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    v = np.zeros(2, dtype=[(n, "<f4") for n in names])
    v["x"], v["y"], v["z"] = [1, 2], [3, 4], [5, 6]
    v["f_dc_0"], v["f_dc_1"], v["f_dc_2"] = [0, 1], [2, 3], [-1, 0]
    for i in range(45):
        v[f"f_rest_{i}"] = 0.3
    v["opacity"] = [0.0, 2.0]
    v["rot_0"] = 1.0
    PlyData([PlyElement.describe(v, "vertex")]).write(str(tmp_path / "foreign.ply"))
    back = read_gaussians_ply(tmp_path / "foreign.ply")
    np.testing.assert_array_equal(back["visual_positions"], [[1, -3, -5], [2, -4, -6]])
    np.testing.assert_allclose(back["visual_colors"], 0.5 + SH_C0 * np.array([[0, 2, -1], [1, 3, 0]]), rtol=1e-6)
    np.testing.assert_allclose(back["visual_opacities"], [0.5, 1 / (1 + np.exp(-2.0))], rtol=1e-6)
    np.testing.assert_array_equal(back["visual_scales"], np.ones((2, 3)))
    # identity in the viewer frame is the half turn about x in the world frame
    np.testing.assert_array_equal(back["visual_rotations"], [[0, -1, 0, 0]] * 2)


def test_bad_files_raise_input_errors_naming_the_problem(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_gaussians_ply(tmp_path / "missing.ply")
    (tmp_path / "junk.ply").write_bytes(b"not a ply at all")
    with pytest.raises(InputError, match="not a readable PLY"):
        read_gaussians_ply(tmp_path / "junk.ply")
    v = np.zeros(3, dtype=[(n, "<f4") for n in PROPERTIES if n != "rot_3"])
    PlyData([PlyElement.describe(v, "vertex")]).write(str(tmp_path / "short.ply"))
    with pytest.raises(InputError, match=r"vertex\.rot_3: missing property"):
        read_gaussians_ply(tmp_path / "short.ply")
    PlyData([PlyElement.describe(v, "face")]).write(str(tmp_path / "noverts.ply"))
    with pytest.raises(InputError, match="vertex: missing element"):
        read_gaussians_ply(tmp_path / "noverts.ply")
