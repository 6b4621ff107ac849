"""A set of 3D Gaussians as the renderer reads them (five tensors), and the union of two sets.

The renderer takes the smoke as separate tensors and a second, static set (backdrop, floor, obstacles) as one
:class:`Gaussians`; both are depth sorted together (``splat.render``).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class Gaussians:
    """N Gaussians: means [N, 3] (world metres), scales [N, 3] (standard deviations along the body axes, metres,
    not log), quats [N, 4] ((w, x, y, z) body to world, any non-zero norm), opacities [N] (peak, in [0, 1]),
    colors [N, C].

    Whether a tensor is optimised is torch's business: one that requires grad gets its gradient from a render,
    one that does not stays frozen.
    """

    means: torch.Tensor
    scales: torch.Tensor
    quats: torch.Tensor
    opacities: torch.Tensor
    colors: torch.Tensor

    def tensors(self) -> tuple[torch.Tensor, ...]:
        return self.means, self.scales, self.quats, self.opacities, self.colors

    def __len__(self) -> int:
        return self.means.shape[0]

    def check(self, what: str = "") -> None:
        """Raise ValueError naming the first tensor of the wrong shape, or a zero quaternion."""
        n = self.means.shape[0] if self.means.dim() >= 1 else -1
        prefix = f"{what}." if what else ""
        if self.colors.dim() != 2 or self.colors.shape[0] != n or self.colors.shape[1] < 1:
            raise ValueError(f"{prefix}colors must be [N, C] with N = {n}, got {tuple(self.colors.shape)}")
        for name, t, shape in (("means", self.means, (n, 3)), ("scales", self.scales, (n, 3)),
                               ("quats", self.quats, (n, 4)), ("opacities", self.opacities, (n,))):
            if tuple(t.shape) != shape:
                raise ValueError(f"{prefix}{name} must have shape {shape}, got {tuple(t.shape)}")
        if n and bool((self.quats.detach() == 0).all(dim=1).any()):
            raise ValueError(f"{prefix}quats contains a zero quaternion")

    def to(self, dtype: torch.dtype, device) -> Gaussians:
        """The same set in ``dtype`` on ``device`` (differentiable, as ``Tensor.to``)."""
        return Gaussians(*(t.to(device=device, dtype=dtype) for t in self.tensors()))

    def union(self, other: Gaussians) -> Gaussians:
        """This set followed by ``other``, in that order (differentiable; both in one dtype and device)."""
        return Gaussians(*(torch.cat([a, b]) for a, b in zip(self.tensors(), other.tensors())))
