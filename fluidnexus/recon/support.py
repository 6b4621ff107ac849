"""Gas under the smoke: physical particles seeded where visual particles have none (``--physical-support``).

A visual particle moves with the gas's velocity field V (FluidNexus Eq. 2: the kernel-weighted mean velocity of
the physical particles within h of it); with no physical particle within h it has no velocity and stays where it
is (``engine.query``), while stage 2 can only change its look. The paper's gas starts at the source, which suits
smoke that does too (ScalarFlow). Footage whose smoke fills the view from the first frame (PINF's Sphere: the
inflow is below the images, the smoke already around the ball) leaves most Gaussians without gas: on Sphere 79 %
of them at frame 30, 87 % at frame 110, and the held-out views fell from 25-26 dB to 17.6 dB after frame 60.

Before each frame's stage 1, one physical particle at rest is seeded at the centre of every cell of the physical
lattice (``physical_spacing``) that holds a visual particle without support, outside the obstacles. Stage 1 then
fits their positions to the footage like every physical particle's, so the frame's velocity field moves those
Gaussians as the footage shows; seeded particles that end the frame isolated are removed with the others, and are
seeded again where still needed.
"""
from __future__ import annotations

import torch

from .. import engine
from .smoke import Smoke
from .workspace import Workspace

#: Room kept in the workspace beyond the seeded particles (the frame's emitter adds its own after them).
HEADROOM = 8192


def unsupported(x: torch.Tensor, p: torch.Tensor, ws: Workspace) -> torch.Tensor:
    """[M] bool: visual particles ``x`` [M, 3] with no physical particle of ``p`` [N, 3] within h."""
    if p.shape[0] == 0:
        return torch.ones(x.shape[0], dtype=torch.bool)
    with torch.no_grad():
        return engine.density_at(x.detach(), p.detach(), ws.advect_query) <= 0


def support(smoke: Smoke, ws: Workspace, spacing: float) -> int:
    """In place: physical particles at rest under the unsupported visual particles of ``smoke`` (module
    docstring), one per occupied cell of ``spacing``; returns how many were seeded."""
    if smoke.x.shape[0] == 0:
        return 0
    ws.reserve(smoke.p.shape[0] + HEADROOM)
    lonely = smoke.x.detach()[unsupported(smoke.x, smoke.p, ws)]
    if lonely.shape[0] == 0:
        return 0
    cells = torch.unique(torch.floor(lonely / spacing), dim=0)
    sites = ws.push_out((cells + 0.5) * spacing)
    ws.reserve(smoke.p.shape[0] + sites.shape[0] + HEADROOM)
    smoke.add_physical(sites)
    return int(sites.shape[0])
