import subprocess
import sys

import pytest

from fluidnexus.atomic import atomic_dir, atomic_file


def test_import_is_light():
    """`import fluidnexus` (and the scene/camera/video modules) pulls in no engine or generative packages."""
    code = ("import sys, fluidnexus, fluidnexus.scene, fluidnexus.camera, fluidnexus.video, fluidnexus.gen; "
            "print(sorted(m for m in ('taichi', 'torch', 'diffusers', 'transformers') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_atomic_file_leaves_nothing_on_failure(tmp_path):
    dest = tmp_path / "out.json"
    dest.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_file(dest) as tmp:
            tmp.write_text("half")
            raise RuntimeError("disk full")
    assert dest.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]
    with atomic_file(dest) as tmp:
        tmp.write_text("new")
    assert dest.read_text() == "new" and oct(dest.stat().st_mode & 0o777) != oct(0o600)


def test_atomic_dir_replaces_only_when_complete(tmp_path):
    dest = tmp_path / "scene"
    dest.mkdir()
    (dest / "a").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_dir(dest) as tmp:
            (tmp / "b").write_text("half")
            raise RuntimeError
    assert [p.name for p in dest.iterdir()] == ["a"]
    with atomic_dir(dest) as tmp:
        (tmp / "b").write_text("new")
    assert [p.name for p in dest.iterdir()] == ["b"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene"]


def test_cpu_engine_keeps_torch_to_one_thread():
    """On the CPU the engine owns the cores: starting it leaves torch one intra-op thread (engine/runtime.py)."""
    code = ("import torch; torch.set_num_threads(2); from fluidnexus import engine; engine.init('cpu'); "
            "print(torch.get_num_threads())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "1"
