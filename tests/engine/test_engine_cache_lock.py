"""A kernel-cache lock left by a killed process is cleared when the engine starts (runtime.clear_stale_lock)."""
import os

from fluidnexus.engine.runtime import STALE_LOCK_SECONDS, clear_stale_lock


def test_only_an_old_lock_is_removed(tmp_path):
    lock = tmp_path / "ticache.lock"
    assert not clear_stale_lock(tmp_path)  # none there
    lock.write_bytes(b"")
    assert not clear_stale_lock(tmp_path) and lock.exists()  # a process may be writing the cache now
    old = lock.stat().st_mtime - STALE_LOCK_SECONDS - 1
    os.utime(lock, (old, old))
    assert clear_stale_lock(tmp_path) and not lock.exists()
