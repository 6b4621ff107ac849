"""Carry the look of the last known frame into the rough future videos (docs/prediction.md, "Anchoring").

The paper extends a video with a conditional refiner v_cond that starts from S clean frames (FluidNexus Sec. 3.1,
"Long Video Generation"); for the future those are the last known frames, so the predicted smoke keeps the look
the camera saw. This is its non-learned counterpart. For each camera, the residual between the frame the
reconstruction was fitted to at the start frame T and the reconstruction's own render of T,

    R = known_T - render_T,

is split by the Gaussians' coverage c(a) = a / (a + COVER_ALPHA) of each pixel (a = alpha of the Gaussians
there): the covered part moves with them, the rest stays where it was seen. At a future frame t,

    anchored_t(p) = clip(render_t(p) + R(p + f_t(p)) c(a_t(p)) + R(p) (1 - c(a_T(p))), 0, 1),

with f_t the backward flow rendered from the visual particles' projected displacements (:func:`carried`) and a_t
the alpha of the Gaussians present at T. Without motion this is the known frame itself (the repeat-last-frame
forecast); where the rollout moves smoke, the real look moves with it; smoke the render lacks has no particle to
carry it and stays where it was seen. Particles born after T carry no residual.
"""
from __future__ import annotations

import numpy as np
import torch

from .. import engine
from ..camera import Camera
from ..metrics import warp_by_flow
from ..recon.observations import load_observations
from ..recon.smoke import Smoke

#: Alpha at which a pixel's residual counts as half carried by the Gaussians there (coverage a / (a + this)).
COVER_ALPHA = 0.01


def carried(camera: Camera, start: Smoke, state: Smoke) -> tuple[np.ndarray, np.ndarray]:
    """Where the smoke each pixel of ``state`` shows was at ``start``, and how much of it was there.

    Returns:
        flow [H, W, 2]: pixel displacements (du, dv) such that image_start(p + flow(p)) shows that smoke, the
            alpha-weighted mean displacement of the Gaussians the pixel composites over those present at ``start``
            (the first ``start.x.shape[0]`` rows: the rollout appends new ones and never removes any); 0 where
            there are none.
        alpha [H, W]: their summed compositing weight at the pixel (alpha of the Gaussians present at ``start``).
    """
    m = start.x.shape[0]
    before, _ = camera.project(start.x.numpy().astype(np.float64))
    now, _ = camera.project(state.x[:m].numpy().astype(np.float64))
    colors = torch.zeros((state.x.shape[0], 3), dtype=state.x.dtype)
    colors[:m, :2] = torch.as_tensor(before - now, dtype=state.x.dtype)
    colors[:m, 2] = 1.0
    with torch.no_grad():
        image, _, _ = engine.render(camera, state.x, state.scale, state.rotation, state.opacity, colors)
    image = image.numpy().astype(np.float64)
    alpha = image[..., 2]
    flow = np.where(alpha[..., None] > 0.0, image[..., :2] / np.maximum(alpha, 1e-12)[..., None], 0.0)
    return flow.astype(np.float32), alpha


def coverage(alpha: np.ndarray) -> np.ndarray:
    """[H, W, 1] share of a pixel's residual carried by Gaussians of compositing weight ``alpha`` [H, W]."""
    return (alpha / (alpha + COVER_ALPHA))[..., None].astype(np.float32)


def known_frames(scene, frame: int, names: list[str], resolution: float, channels: int) -> list[np.ndarray | None]:
    """Each named view's footage at ``frame`` (what the reconstruction was fitted to there: real input or
    synthesised novel video), at the run's resolution; None for a view without footage or a frame past the
    videos."""
    if not 0 <= frame < scene.frame_count:
        return [None] * len(names)
    obs = load_observations(scene, (frame, frame + 1), resolution, channels)
    found = dict(zip(obs.names, obs.frame(frame)))
    return [found.get(name) for name in names]


def anchor_videos(rough: np.ndarray, states: list[Smoke], start: Smoke, cameras: list[Camera],
                  known: list[np.ndarray | None]) -> np.ndarray:
    """The rough future videos with each camera's known look at the start frame carried along the rollout.

    Args:
        rough: [V, 1 + T, H, W, C] renders by ``cameras`` of ``start`` then of the T rollout frames (with the look
            the refiner will get, so that the residual removes exactly that look).
        states: the T rollout frames.
        start: the reconstructed state the rollout starts from (frame T0).
        cameras: [V] cameras.
        known: [V] the frame [H, W, C] each camera's footage shows at T0, or None for a camera without footage
            (its rough video is kept).
    Returns:
        [V, T, H, W, C] float32 in [0, 1].
    """
    out = np.array(rough[:, 1:], dtype=np.float32, copy=True)
    for v, (camera, frame) in enumerate(zip(cameras, known)):
        if frame is None:
            continue
        residual = np.asarray(frame, np.float32) - rough[v, 0]
        staying = residual * (1.0 - coverage(carried(camera, start, start)[1]))
        for k, state in enumerate(states):
            flow, alpha = carried(camera, start, state)
            out[v, k] = np.clip(out[v, k] + warp_by_flow(residual, flow) * coverage(alpha) + staying, 0.0, 1.0)
    return out
