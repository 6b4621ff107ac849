"""The peak memory of a prediction or interaction, estimated before anything is read or written (docs/scale.md;
the arithmetic per buffer is ``fluidnexus.memory``'s)."""
from __future__ import annotations

from ..memory import F32, Estimate, physical_bytes, visual_bytes
from .rollout import capacities


def future_estimate(command: str, start, frames: int, ctx, model, cameras, videos: bool) -> Estimate:
    """predict / interact: the rollout's workspace (with the gas in ambient air, its air: the region the smoke
    reaches, on the rest density's lattice), the ``frames`` states it keeps, and with ``videos`` the rough, known,
    anchored and refined video of every camera (float32, at the run's resolution)."""
    phys, smoke, vis = capacities(start, frames, ctx, model)
    channels = ctx.config.channels
    est = Estimate(command)
    if model.air is None:
        est.add("physical particles", physical_bytes(phys, ctx.solver.iterations), "--frames")
    else:
        est.add("smoke and air particles", physical_bytes(phys, ctx.solver.iterations),
                "--frames or the model's structure margin")
    est.add("visual particles", visual_bytes(vis, channels), "--frames")
    est.add("rollout states", frames * F32 * (7 * smoke + (11 + channels) * vis), "--frames")
    if videos:
        pixels = sum(cam.width * cam.height for cam in cameras)
        est.add("videos", 4 * (frames + 1) * pixels * channels * F32, "--frames or --no-refit")
    return est
