"""Loss terms of the reconstruction (FluidNexus Eq. 4-7 and the supplement), plain torch.

Every function takes torch tensors and returns a scalar tensor; gradients flow through torch autograd and,
where the inputs came from the engine, through its ``ti.ad`` bridges.
"""
from __future__ import annotations

import torch


def simulation_loss(p: torch.Tensor, p_sim: torch.Tensor, unit: float) -> torch.Tensor:
    """L_sim = mean |p_t - p_sim|^2 measured in ``unit`` metres (the release's 1 cm at ScalarFlow's scale,
    ``ReconConfig.loss_unit``), FluidNexus Eq. 3."""
    return (((p - p_sim) / unit) ** 2).sum(dim=1).mean()


def density_loss(rho: torch.Tensor, rest_density: float) -> torch.Tensor:
    """mean (rho / rho0 - 1)^2: the incompressibility term of FluidNexus Eq. 4 (mean as in the release)."""
    if rho.numel() == 0:
        return rho.sum()
    return ((rho / rest_density - 1.0) ** 2).mean()


def spacing_loss(x: torch.Tensor, pairs: torch.Tensor, sigma: float, unit: float) -> torch.Tensor:
    """sum over visual pairs of max(0, sigma - |x_i - x_j|)^2 (FluidNexus Eq. 4, third term).

    Args:
        x: [M, 3] visual positions (m). pairs: [P, 2] index pairs i < j closer than ``sigma`` at build time.
        sigma: the minimum distance (m). The paper writes the squared distance; we compare distances so that
            sigma is a length. Measured in ``unit`` metres (release units at ScalarFlow's scale,
            ``ReconConfig.loss_unit``) as the release's weight assumes.
    """
    if pairs.numel() == 0:
        return x.sum() * 0.0
    d = (x[pairs[:, 0]] - x[pairs[:, 1]]).norm(dim=1)
    return ((torch.clamp(sigma - d, min=0.0) / unit) ** 2).sum()


def temporal_loss(current: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
    """mean |a_t - a_{t-1}|^2 of one visual attribute over the particles both frames have (supp. L_reg)."""
    m = previous.shape[0]
    if m == 0:
        return current.sum() * 0.0
    return ((current[:m] - previous) ** 2).sum(dim=-1).mean() if current.dim() > 1 else \
        ((current[:m] - previous) ** 2).mean()


def anisotropy_loss(scales: torch.Tensor, cap: float) -> torch.Tensor:
    """mean max(0, max(s) / min(s) - cap): keeps Gaussians from growing needle-thin (PhysGaussian, supp.)."""
    if scales.numel() == 0:
        return scales.sum()
    ratio = scales.max(dim=1).values / scales.min(dim=1).values.clamp_min(1e-12)
    return torch.clamp(ratio - cap, min=0.0).mean()
