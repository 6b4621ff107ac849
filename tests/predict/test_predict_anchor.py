"""Anchoring (predict/anchor.py): the known look at the start frame moves with the rollout's smoke."""
from __future__ import annotations

import numpy as np
import torch

from fluidnexus.camera import Camera
from fluidnexus.frames import render_state
from fluidnexus.metrics import psnr
from fluidnexus.predict.anchor import anchor_videos, carried
from fluidnexus.recon.smoke import Smoke

CAMERA = Camera.look_at(64, 48, 60.0, eye=(0.0, 0.0, 1.0), target=(0.0, 0.0, 0.0))


def blob(centres, color=0.5, scale=0.02, opacity=0.6) -> Smoke:
    """Gaussians at ``centres`` [M, 3] with one look (no physical particles)."""
    x = torch.as_tensor(np.asarray(centres, np.float64))
    m = x.shape[0]
    rot = torch.zeros((m, 4), dtype=torch.float64)
    rot[:, 0] = 1.0
    empty = torch.zeros((0, 3), dtype=torch.float64)
    return Smoke(0, empty, empty, torch.zeros(0, dtype=torch.float64), x,
                 torch.full((m, 1), color, dtype=torch.float64), torch.full((m, 3), scale, dtype=torch.float64), rot,
                 torch.full((m,), opacity, dtype=torch.float64))


def moved(smoke: Smoke, offsets, extra=None) -> Smoke:
    """``smoke`` with its Gaussians moved by ``offsets`` [M, 3] (and Gaussians ``extra`` appended)."""
    out = blob(smoke.x.numpy() + np.asarray(offsets), float(smoke.color[0, 0]), float(smoke.scale[0, 0]),
               float(smoke.opacity[0]))
    if extra is not None:
        out.add_visual(torch.as_tensor(np.asarray(extra, np.float64)), float(smoke.color[0, 0]),
                       float(smoke.scale[0, 0]), float(smoke.opacity[0]))
    return out


def test_flow_is_each_gaussians_projected_displacement(ti_engine):
    start = blob([[-0.15, 0.0, 0.0], [0.15, 0.0, 0.0]])
    offsets = np.array([[0.03, 0.02, 0.0], [-0.02, -0.04, 0.0]])
    now = moved(start, offsets, extra=[[0.0, 0.15, 0.0]])  # a Gaussian born after the start
    flow, alpha = carried(CAMERA, start, now)
    before, _ = CAMERA.project(start.x.numpy())
    after, _ = CAMERA.project(now.x.numpy())
    for k in range(2):  # at each old Gaussian's centre pixel: exactly its displacement back to the start
        u, v = np.floor(after[k]).astype(int)
        np.testing.assert_allclose(flow[v, u], before[k] - after[k], atol=1e-4)
        assert alpha[v, u] > 0.3
    u, v = np.floor(after[2]).astype(int)  # the newborn carries nothing
    np.testing.assert_array_equal(flow[v, u], [0.0, 0.0])
    assert alpha[v, u] == 0.0
    assert np.all(flow[0, 0] == 0.0) and alpha[0, 0] == 0.0  # empty background


def test_without_motion_the_anchored_video_is_the_known_frame(ti_engine):
    start = blob([[0.0, 0.0, 0.0], [0.05, 0.05, 0.0]])
    known = np.clip(render_state(start.to_state(), CAMERA) * 1.7 + 0.05, 0, 1)  # a look the render lacks
    rough = np.stack([render_state(start.to_state(), CAMERA)] * 3)[None]
    out = anchor_videos(rough, [start, start], start, [CAMERA], [known])
    assert out.shape == (1, 2) + known.shape
    np.testing.assert_allclose(out[0, 0], known, atol=1e-6)
    np.testing.assert_allclose(out[0, 1], known, atol=1e-6)
    kept = anchor_videos(rough, [start, start], start, [CAMERA], [None])  # a camera without footage
    np.testing.assert_array_equal(kept[0], rough[0, 1:])


def test_the_known_look_moves_with_the_smoke(ti_engine):
    rng = np.random.default_rng(0)
    start = blob(rng.normal(0.0, 0.03, (40, 3)), color=0.3)
    real = blob(start.x.numpy(), color=0.9)  # the footage's look: brighter than the reconstruction's
    shift = np.array([0.06, 0.04, 0.0])
    states = [moved(start, np.tile(shift * k / 3, (40, 1))) for k in (1, 2, 3)]
    truth = [render_state(moved(real, np.tile(shift * k / 3, (40, 1))).to_state(), CAMERA) for k in (1, 2, 3)]
    known = render_state(real.to_state(), CAMERA)
    rough = np.stack([render_state(s.to_state(), CAMERA) for s in [start] + states])[None]
    out = anchor_videos(rough, states, start, [CAMERA], [known])[0]
    for k in range(3):
        anchored, plain, still = psnr(out[k], truth[k]), psnr(rough[0, k + 1], truth[k]), psnr(known, truth[k])
        assert anchored > 40.0, (k, anchored)
        assert anchored > plain + 10.0 and anchored > still + 10.0, (k, anchored, plain, still)
