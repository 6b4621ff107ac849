"""A run folder written by hand from given frame states (for render, eval and export tests without a recon)."""
from __future__ import annotations

import json
from pathlib import Path

from fluidnexus.state import FrameState, frame_path, save_frame


def write_run(folder: Path, scene_dir: Path, states: list[FrameState], h: float, dt: float,
              resolution: float = 1.0, channels: int = 1) -> Path:
    """A ``recon`` run of ``scene_dir`` holding ``states`` (layout in docs/run-format.md)."""
    folder.mkdir(parents=True)
    frames = [s.frame for s in states]
    (folder / "run.json").write_text(json.dumps({"format": "fluidnexus-run/1", "kind": "recon",
                                                 "scene": str(Path(scene_dir).resolve()),
                                                 "frames": [min(frames), max(frames) + 1], "arch": "cpu"}))
    (folder / "config.json").write_text(json.dumps({"recon": {"resolution": resolution, "channels": channels},
                                                    "solver": {"h": h, "dt": dt}}))
    for state in states:
        save_frame(frame_path(folder, state.frame), state)
    return folder
