"""Tiny batch settings: two-frame reconstructions of the embedded sample at 1/8 resolution, one engine thread."""
from __future__ import annotations

from pathlib import Path

import pytest

from clirun import invoke, ok  # noqa: F401  (re-exported to the tests of this folder)

TINY_RECON = ('recon = { frames = "0:2", resolution = 0.125, init_iters = 2, dynamics_iters = 1, '
              'appearance_iters = 1, stabilization_steps = 1 }')
BATCH_OPTIONS = ["--cpus-per-scene", "1"]  # one engine thread per task: two scenes at a time, deterministic


def write_manifest(folder: Path, body: str, name: str = "batch.toml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(body)
    return path


def sample_scenes(*protocols: str) -> str:
    """[[scene]] entries of the sample, named after their protocol."""
    return "".join(f'\n[[scene]]\nname = "{p}"\nsample = "scalarflow"\nprotocol = "{p}"\n' for p in protocols)


@pytest.fixture(scope="session")
def sample_batch(tmp_path_factory):
    """One batch of three scenes: the sample's single-view and four-view protocols, and a scene folder whose
    input video is truncated; each reconstructs two frames and scores them. Returns (batch folder, result)."""
    pytest.importorskip("ray")
    root = tmp_path_factory.mktemp("batch")
    broken = root / "broken-scene"
    ok("calibrate", "--sample", "scalarflow", "--protocol", "four-view", "--out", broken)
    video = broken / "videos" / "train00.mp4"
    data = video.read_bytes()
    video.write_bytes(data[: len(data) // 3])  # cut off mid-stream, as a failed copy would
    manifest = write_manifest(root, f'[defaults]\nsteps = ["recon", "eval"]\n{TINY_RECON}\n'
                                    + sample_scenes("single-view", "four-view")
                                    + '\n[[scene]]\nname = "broken"\nscene = "broken-scene"\n')
    out = root / "out"
    result = invoke("batch", manifest, "--out", out, *BATCH_OPTIONS)
    return out, result
