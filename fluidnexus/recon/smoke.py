"""The reconstructed smoke at one frame, in memory: physical particles (p, u, age) and visual Gaussians.

Tensors are torch, in the running engine precision (``fluidnexus.engine.real``); conversions to and from the
on-disk :class:`fluidnexus.state.FrameState` are exact in float32.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..state import FrameState


@dataclass
class Smoke:
    """Physical particles p [N, 3] m, u [N, 3] m/s, age [N] s; visual x [M, 3] m, color [M, C], scale [M, 3] m,
    rotation [M, 4] (w, x, y, z), opacity [M]."""

    frame: int
    p: torch.Tensor
    u: torch.Tensor
    age: torch.Tensor
    x: torch.Tensor
    color: torch.Tensor
    scale: torch.Tensor
    rotation: torch.Tensor
    opacity: torch.Tensor

    def to_state(self) -> FrameState:
        def a(t):
            return t.detach().cpu().numpy().astype(np.float32)

        return FrameState(self.frame, a(self.p), a(self.u), a(self.x), a(self.color), a(self.scale),
                          a(self.rotation), a(self.opacity), a(self.age))

    @classmethod
    def from_state(cls, state: FrameState, dtype: torch.dtype) -> "Smoke":
        def t(a):
            return torch.as_tensor(np.asarray(a), dtype=dtype).clone()

        return cls(state.frame, t(state.physical_positions), t(state.physical_velocities), t(state.ages()),
                   t(state.visual_positions), t(state.visual_colors), t(state.visual_scales),
                   t(state.visual_rotations), t(state.visual_opacities))

    def add_visual(self, positions: torch.Tensor, color, scale: float, opacity: float) -> None:
        """Append isotropic Gaussians at ``positions`` [K, 3] with one appearance (``color`` a float or [C])."""
        k, dtype = positions.shape[0], self.x.dtype
        self.x = torch.cat([self.x, positions.to(dtype)])
        rgb = torch.as_tensor(color, dtype=dtype).expand(k, self.color.shape[1])
        self.color = torch.cat([self.color, rgb])
        self.scale = torch.cat([self.scale, torch.full((k, 3), scale, dtype=dtype)])
        rot = torch.zeros((k, 4), dtype=dtype)
        rot[:, 0] = 1.0
        self.rotation = torch.cat([self.rotation, rot])
        self.opacity = torch.cat([self.opacity, torch.full((k,), opacity, dtype=dtype)])

    def add_physical(self, positions: torch.Tensor, velocity=None) -> None:
        """Append physical particles with age 0, at rest or moving at ``velocity`` (3,) m/s."""
        k, dtype = positions.shape[0], self.p.dtype
        self.p = torch.cat([self.p, positions.to(dtype)])
        u = torch.zeros((k, 3), dtype=dtype)
        if velocity is not None:
            u[:] = torch.as_tensor(velocity, dtype=dtype)
        self.u = torch.cat([self.u, u])
        self.age = torch.cat([self.age, torch.zeros(k, dtype=dtype)])

    def keep_physical(self, mask: torch.Tensor) -> int:
        removed = int((~mask).sum())
        self.p, self.u, self.age = self.p[mask], self.u[mask], self.age[mask]
        return removed
