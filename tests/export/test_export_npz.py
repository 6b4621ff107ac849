import numpy as np
import pytest

from fluidnexus.errors import InputError
from fluidnexus.export.npz import read_frame_npz, write_frame_npz
from fluidnexus.state import FrameState


def state(rng, n=6, m=9):
    q = rng.normal(size=(m, 4))
    return FrameState(3, rng.normal(size=(n, 3)).astype(np.float32), rng.normal(size=(n, 3)).astype(np.float32),
                      rng.normal(size=(m, 3)).astype(np.float32), rng.random((m, 1)).astype(np.float32),
                      rng.random((m, 3)).astype(np.float32) + 0.01,
                      (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32),
                      rng.random(m).astype(np.float32))


def test_state_round_trips_exactly(tmp_path):
    s = state(np.random.default_rng(0))
    write_frame_npz(tmp_path / "f.npz", s)
    back = read_frame_npz(tmp_path / "f.npz")
    assert back["frame"] == 3 and back["frame"].dtype == np.int64
    assert set(back) == {"frame", *s.arrays()}
    for name, arr in s.arrays().items():
        np.testing.assert_array_equal(back[name], arr)


def test_grid_fields_are_stored_with_their_grid(tmp_path):
    rng = np.random.default_rng(1)
    density, velocity = rng.random((2, 3, 4)), rng.normal(size=(2, 3, 4, 3))
    write_frame_npz(tmp_path / "f.npz", state(rng), origin=(0.0, 0.1, -0.2), spacing=(0.1, 0.1, 0.2),
                    fields={"density": density, "velocity": velocity})
    back = read_frame_npz(tmp_path / "f.npz")
    np.testing.assert_array_equal(back["grid_origin"], [0.0, 0.1, -0.2])
    np.testing.assert_array_equal(back["grid_spacing"], [0.1, 0.1, 0.2])
    np.testing.assert_array_equal(back["grid_density"], density.astype(np.float32))
    np.testing.assert_array_equal(back["grid_velocity"], velocity.astype(np.float32))
    assert back["grid_velocity"].dtype == np.float32


def test_bad_input_is_rejected(tmp_path):
    s = state(np.random.default_rng(2))
    with pytest.raises(ValueError, match="has grid"):
        write_frame_npz(tmp_path / "f.npz", s, (0, 0, 0), (1, 1, 1),
                        {"density": np.zeros((2, 3, 4)), "velocity": np.zeros((2, 3, 5, 3))})
    with pytest.raises(ValueError, match="origin and spacing"):
        write_frame_npz(tmp_path / "f.npz", s, fields={"density": np.zeros((2, 3, 4))})
    assert not (tmp_path / "f.npz").exists()
    with pytest.raises(InputError, match="file not found"):
        read_frame_npz(tmp_path / "f.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(InputError, match="not a readable"):
        read_frame_npz(tmp_path / "junk.npz")
