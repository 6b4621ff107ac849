"""Reading a run folder (written by ``recon``, ``predict`` or ``interact``; layout in docs/run-format.md)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .atomic import read_json
from .errors import InputError
from .scene import Scene, load_scene
from .state import FrameState, frame_path, load_frame

RUN_FORMAT = "fluidnexus-run/1"


@dataclass(frozen=True)
class Run:
    """A run folder: its settings and the frames it holds."""

    root: Path
    info: dict
    config: dict

    @property
    def scene_dir(self) -> Path:
        return Path(self.info["scene"])

    @property
    def frames(self) -> list[int]:
        """Frame indices with a saved state, in order."""
        return sorted(int(p.stem) for p in (self.root / "frames").glob("*.npz") if p.stem.isdigit())

    @property
    def resolution(self) -> float:
        return float(self.config["recon"]["resolution"])

    @property
    def channels(self) -> int:
        return int(self.config["recon"]["channels"])

    @property
    def length_scale(self) -> float:
        """The length-scale factor recon sized the run's lengths with (docs/scale.md)."""
        return float(self.config["recon"]["length_scale"])

    @property
    def dt(self) -> float:
        return float(self.config["solver"]["dt"])

    def state(self, frame: int) -> FrameState:
        return load_frame(frame_path(self.root, frame))

    def scene(self, check_videos: bool = True) -> Scene:
        return load_scene(self.scene_dir, check_videos=check_videos)


def open_run(path: str | Path) -> Run:
    """Open a run folder; it must hold at least one frame."""
    root = Path(path)
    info = read_json(root / "run.json", "file not found: not a fluidnexus run folder;")
    if info.get("format") != RUN_FORMAT:
        raise InputError(root / "run.json", "format", f"unknown format tag {info.get('format')!r}")
    run = Run(root, info, read_json(root / "config.json"))
    if not run.frames:
        raise InputError(root / "frames", None, "the run has no reconstructed frame yet")
    return run
