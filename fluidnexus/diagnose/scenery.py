"""The bodies diagnose's simulated plume flows around (issue 16, part 4, for diagnose).

The scene's declared obstacles (scene.json ``obstacles``) and, when diagnose is given a reconstruction of the scene,
the obstacles recon found in its static layer too (``recon.scenery.run_scenery``: declared ones win where both are).
:class:`Obstacles` holds the folders, not the engine bodies (a carved body is a Taichi field), so that every worker
process of ``--jobs`` (parallel.py) builds the same bodies: the finder is deterministic.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Obstacles:
    """Where the bodies come from: ``scene_dir``'s declared obstacles, or with ``run_dir`` that run's declared and
    found ones."""

    scene_dir: str
    run_dir: str | None = None

    def body(self):
        """The engine body of every obstacle (``engine.obstacle``), or None; needs the engine started."""
        from fluidnexus.recon.scenery import declared_scenery, run_scenery
        from fluidnexus.runs import open_run
        from fluidnexus.scene import load_scene

        if self.run_dir is not None:
            return run_scenery(open_run(self.run_dir)).obstacle
        return declared_scenery(load_scene(self.scene_dir)).obstacle


def scene_obstacles(scene_dir: Path, run_dir: Path | None = None) -> tuple[Obstacles | None, object | None]:
    """(the source of the bodies, or None when there are none; the bodies themselves, for this process)."""
    source = Obstacles(str(scene_dir), None if run_dir is None else str(run_dir))
    body = source.body()
    return (source, body) if body is not None else (None, None)
