"""Per-frame reconstruction state: the physical particles (p, u) and the visual Gaussians (x, c, s, o, r).

A run folder stores one ``frames/NNNNNN.npz`` per frame (see docs/run-format.md). Arrays are float32 numpy,
world metres and seconds, quaternions (w, x, y, z) as in docs/conventions.md.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic import atomic_file
from .errors import InputError

FIELDS = {
    "physical_positions": 3, "physical_velocities": 3,
    "visual_positions": 3, "visual_scales": 3, "visual_rotations": 4, "visual_opacities": None,
}


@dataclass(frozen=True, eq=False)
class FrameState:
    """The reconstructed smoke at one frame.

    Attributes:
        frame: frame index into the scene's videos.
        physical_positions: [N, 3] PBF particle positions p, metres.
        physical_velocities: [N, 3] PBF particle velocities u, m/s.
        visual_positions: [M, 3] Gaussian centres x, metres.
        visual_colors: [M, C] Gaussian colours c in [0, 1] (C = 1 gray, 3 RGB).
        visual_scales: [M, 3] Gaussian standard deviations s along their axes, metres.
        visual_rotations: [M, 4] unit quaternions r (w, x, y, z), body to world.
        visual_opacities: [M] opacities o in [0, 1].
        physical_ages: [N] seconds since each physical particle left the source (for a decaying buoyancy);
            None reads as zeros.
    """

    frame: int
    physical_positions: np.ndarray
    physical_velocities: np.ndarray
    visual_positions: np.ndarray
    visual_colors: np.ndarray
    visual_scales: np.ndarray
    visual_rotations: np.ndarray
    visual_opacities: np.ndarray
    physical_ages: np.ndarray | None = None

    @property
    def num_physical(self) -> int:
        return int(self.physical_positions.shape[0])

    @property
    def num_visual(self) -> int:
        return int(self.visual_positions.shape[0])

    @property
    def channels(self) -> int:
        return int(self.visual_colors.shape[1])

    def arrays(self) -> dict[str, np.ndarray]:
        out = {name: getattr(self, name) for name in (*FIELDS, "visual_colors")}
        out["physical_ages"] = self.ages()
        return out

    def ages(self) -> np.ndarray:
        """[N] particle ages in seconds (zeros when not recorded)."""
        if self.physical_ages is None:
            return np.zeros(self.num_physical, np.float32)
        return self.physical_ages


def frame_path(run_dir: str | Path, frame: int) -> Path:
    return Path(run_dir) / "frames" / f"{frame:06d}.npz"


def save_frame(path: str | Path, state: FrameState) -> None:
    """Write a frame state atomically (float32 arrays)."""
    validate(state, path)
    with atomic_file(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, frame=np.int64(state.frame),
                     **{k: np.asarray(v, dtype=np.float32) for k, v in state.arrays().items()})


def load_frame(path: str | Path) -> FrameState:
    """Read a frame state; a missing, corrupt or inconsistent file raises :class:`InputError`."""
    path = Path(path)
    if not path.exists():
        raise InputError(path, None, "file not found")
    try:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
    except Exception as err:  # zipfile/pickle/value errors all mean the same thing to a user
        raise InputError(path, None, f"not a readable frame state ({err})") from None
    missing = [k for k in ("frame", *FIELDS, "visual_colors") if k not in arrays]
    if missing:
        raise InputError(path, missing[0], "missing")
    state = FrameState(int(arrays.pop("frame")), **arrays)
    validate(state, path)
    return state


def validate(state: FrameState, path=None) -> None:
    """Check shapes agree and every value is finite."""
    n, m = state.num_physical, state.num_visual
    for name, width in FIELDS.items():
        arr = np.asarray(getattr(state, name))
        rows = n if name.startswith("physical") else m
        expected = (rows,) if width is None else (rows, width)
        if arr.shape != expected:
            raise InputError(path, name, f"expected shape {expected}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(path, name, "contains non-finite values")
    colors = np.asarray(state.visual_colors)
    if colors.ndim != 2 or colors.shape[0] != m or colors.shape[1] not in (1, 3):
        raise InputError(path, "visual_colors", f"expected shape ({m}, 1 or 3), got {colors.shape}")
    if not np.all(np.isfinite(colors)):
        raise InputError(path, "visual_colors", "contains non-finite values")
    ages = state.ages()
    if np.shape(ages) != (n,) or not np.all(np.isfinite(ages)):
        raise InputError(path, "physical_ages", f"expected {n} finite ages, got shape {np.shape(ages)}")
