"""Raw-array export: one uncompressed ``.npz`` per frame with the whole state and, optionally, gridded fields.

Keys (float32 unless noted; world metres, seconds, +y up, quaternions (w, x, y, z), see docs/conventions.md):

- ``frame`` (int64): the frame index.
- ``physical_positions`` [N, 3], ``physical_velocities`` [N, 3] (m/s): the PBF particles.
- ``visual_positions`` [M, 3], ``visual_colors`` [M, C] in [0, 1], ``visual_scales`` [M, 3] (standard
  deviations), ``visual_rotations`` [M, 4], ``visual_opacities`` [M]: the Gaussians, exactly as reconstructed.
- When a grid is given: ``grid_origin`` [3], ``grid_spacing`` [3] (float64, metres) and ``grid_<name>`` per
  field, shaped ``[nz, ny, nx]`` or ``[nz, ny, nx, 3]`` on the same nodes as the ``.vti`` export (node ``(i, j, k)`` at
  ``origin + (i dx, j dy, k dz)``).

Per-frame files because particle and Gaussian counts may change from frame to frame.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_file
from ..errors import InputError
from ..state import FrameState, validate
from .vti import check_grid


def write_frame_npz(path: str | Path, state: FrameState, origin=None, spacing=None,
                    fields: dict[str, np.ndarray] | None = None) -> None:
    """Write one frame's arrays (atomically).

    Args:
        path: the ``.npz`` file to write; its folder is created.
        state: the frame state.
        origin, spacing: (x, y, z) of the first grid node and the node spacing, metres; given with ``fields``.
        fields: optional name -> [nz, ny, nx] or [nz, ny, nx, 3] grid arrays, e.g. ``density``, ``velocity``.
    """
    validate(state, path)
    arrays = {"frame": np.int64(state.frame),
              **{k: np.asarray(v, dtype=np.float32) for k, v in state.arrays().items()}}
    if fields:
        fields = {name: np.asarray(arr) for name, arr in fields.items()}
        check_grid(origin, spacing, fields)
        arrays["grid_origin"] = np.asarray(origin, dtype=np.float64)
        arrays["grid_spacing"] = np.asarray(spacing, dtype=np.float64)
        arrays.update({f"grid_{name}": arr.astype(np.float32) for name, arr in fields.items()})
    with atomic_file(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)


def read_frame_npz(path: str | Path) -> dict[str, np.ndarray]:
    """Read every array of a file written by :func:`write_frame_npz`; a bad file raises :class:`InputError`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "file not found")
    try:
        with np.load(path) as data:
            return {k: data[k] for k in data.files}
    except Exception as err:  # zipfile/pickle/value errors all mean the same thing to a user
        raise InputError(path, None, f"not a readable .npz file ({err})") from None
