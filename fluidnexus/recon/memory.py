"""A reconstruction's peak memory, estimated before anything is read or written (docs/scale.md; the arithmetic
per buffer is ``fluidnexus.memory``'s)."""
from __future__ import annotations

from ..memory import F32, Estimate, hull_bytes, image_bytes, physical_bytes, video_bytes, visual_bytes
from .hull import CHUNK_POINTS, hull_grid
from .setup import capacities, scene_source


def recon_estimate(scene, setup, frames: tuple[int, int], n_seeds: int) -> Estimate:
    """A reconstruction's peak: frame cache, hull, particle capacities over the run, render buffers, plates.

    ``n_seeds`` is the number of visual particles the first frame's hull seeds (0 before the hull is known).
    """
    cfg = setup.config
    views = scene.usable_views()
    cam = views[0].camera.scaled(cfg.resolution) if views else None
    est = Estimate("recon")
    if cam is not None:
        est.add("video cache", video_bytes(len(views), frames[1] - frames[0], cam.width, cam.height, cfg.channels),
                "--frames or --resolution")
        est.add("render buffers", image_bytes(cam.width, cam.height, cfg.channels, cfg.views_per_iter),
                "--resolution")
    if scene.backgrounds:  # plates held at the videos' size (and their run-size copies), static-layer Gaussians
        full = [v.camera for v in views if v.name in scene.backgrounds]
        est.add("plates", sum(c.width * c.height for c in full) * 4 * F32 + len(full) * 3 * image_bytes(
                cam.width, cam.height, cfg.channels, 1), "--resolution")
    if scene.volume is not None:
        voxels = 1
        for axis in hull_grid(scene.volume, cfg.visual_spacing):
            voxels *= len(axis)
        est.add("visual hull", hull_bytes(voxels, CHUNK_POINTS), "--visual-spacing")
    physical, visual = capacities(frames[1] - frames[0], setup, scene_source(scene, cfg.length_scale), n_seeds)
    est.add("physical particles", physical_bytes(physical, setup.solver.iterations),
            "--physical-spacing / --physical-emit-spacing or --frames")
    est.add("visual particles", visual_bytes(visual, cfg.channels), "--visual-spacing or --frames")
    return est
