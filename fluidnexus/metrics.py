"""Image metrics used across the project: PSNR, SSIM (numpy and differentiable torch), video flicker and the
photometric loss L1 + D-SSIM that recon and the static layer minimise.

Images follow docs/conventions.md: ``[..., H, W, C]`` floats in [0, 1]. Every function accepts a numpy array
or a torch tensor and answers in the same kind; torch inputs stay on their device and dtype, and the torch
path of :func:`ssim` is differentiable (the reconstruction loss uses ``0.2 (1 - SSIM)``, method-notes).

SSIM is the standard definition (Wang et al. 2004, Eq. 13): an 11x11 Gaussian window with sigma 1.5,
``C1 = (0.01 L)^2``, ``C2 = (0.03 L)^2`` with data range L = 1, statistics from "valid" windows only (no
padding), channels scored separately and averaged.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import torch

WINDOW = 11
SIGMA = 1.5
K1, K2 = 0.01, 0.03


def _is_torch(x) -> bool:
    return type(x).__module__.split(".")[0] == "torch"


def psnr(a, b, data_range: float = 1.0):
    """Peak signal-to-noise ratio in dB over the last three axes.

    Args:
        a, b: ``[..., H, W, C]`` images (numpy or torch, same shape).
        data_range: peak value L; PSNR = 10 log10(L^2 / MSE).
    Returns:
        ``[...]`` PSNR values (a float for a single image). Identical images give ``inf``.
    """
    if _is_torch(a):
        import torch

        mse = ((a - b) ** 2).mean(dim=(-3, -2, -1))
        return 10.0 * torch.log10(data_range ** 2 / mse)
    diff = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    mse = (diff ** 2).mean(axis=(-3, -2, -1))
    with np.errstate(divide="ignore"):
        out = 10.0 * np.log10(data_range ** 2 / mse)
    return float(out) if np.ndim(out) == 0 else out


def gaussian_window(size: int = WINDOW, sigma: float = SIGMA) -> np.ndarray:
    """[size] normalised 1D Gaussian; SSIM's window is its outer product with itself."""
    x = np.arange(size, dtype=np.float64) - (size - 1) / 2.0
    g = np.exp(-(x ** 2) / (2.0 * sigma ** 2))
    return g / g.sum()


def ssim(a, b, data_range: float = 1.0):
    """Mean structural similarity (Wang et al. 2004) over the last three axes.

    Args:
        a, b: ``[..., H, W, C]`` images with H, W >= 11 (numpy or torch, same shape).
        data_range: the dynamic range L of the values.
    Returns:
        ``[...]`` SSIM values in [-1, 1] (a float for a single numpy image); differentiable for torch inputs.
    """
    if a.shape != b.shape:
        raise ValueError(f"ssim: shapes differ: {tuple(a.shape)} vs {tuple(b.shape)}")
    if a.shape[-3] < WINDOW or a.shape[-2] < WINDOW:
        raise ValueError(f"ssim: images must be at least {WINDOW}x{WINDOW}, got {tuple(a.shape[-3:-1])}")
    if not _is_torch(a):
        a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    out = _ssim_map(a, b, data_range).mean(axis=(-3, -2, -1))
    return float(out) if not _is_torch(out) and np.ndim(out) == 0 else out


def _valid_blur(x):
    """Separable "valid" Gaussian blur (no padding) of ``[..., H, W, C]`` numpy or torch images, as weighted sums
    of shifted slices: on the CPU this is several times faster than ``torch.nn.functional.conv2d`` with a 1-channel
    11-tap kernel, forward and backward."""
    g = gaussian_window().tolist()
    n = x.shape[-3] - WINDOW + 1
    rows = sum(g[k] * x[..., k:k + n, :, :] for k in range(WINDOW))
    m = x.shape[-2] - WINDOW + 1
    return sum(g[k] * rows[..., k:k + m, :] for k in range(WINDOW))


def _ssim_map(a, b, data_range: float):
    """Wang et al. 2004 Eq. (13) from local Gaussian statistics (valid windows)."""
    c1, c2 = (K1 * data_range) ** 2, (K2 * data_range) ** 2
    mu_a, mu_b = _valid_blur(a), _valid_blur(b)
    var_a = _valid_blur(a * a) - mu_a * mu_a
    var_b = _valid_blur(b * b) - mu_b * mu_b
    cov = _valid_blur(a * b) - mu_a * mu_b
    return ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a ** 2 + mu_b ** 2 + c1) * (var_a + var_b + c2))


# ---- temporal flicker ---------------------------------------------------------------------------------
def optical_flow(prev: np.ndarray, nxt: np.ndarray) -> np.ndarray:
    """Dense Farneback flow from ``prev`` to ``nxt`` (OpenCV), for [H, W, C] frames in [0, 1].

    Returns:
        [H, W, 2] float32 pixel displacements (dx, dy): ``nxt(p + flow(p)) ~ prev(p)``.
    """
    import cv2

    def gray8(x):
        x = np.asarray(x, np.float32)
        x = x.mean(axis=-1) if x.ndim == 3 else x
        return np.round(np.clip(x, 0, 1) * 255).astype(np.uint8)

    return cv2.calcOpticalFlowFarneback(gray8(prev), gray8(nxt), None, pyr_scale=0.5, levels=3, winsize=15,
                                        iterations=3, poly_n=5, poly_sigma=1.2, flags=0)


def warp_by_flow(image: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """Sample ``image`` [H, W, C] at ``p + flow(p)`` (bilinear, edges replicated); returns [H, W, C]."""
    import cv2

    h, w = flow.shape[:2]
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    out = cv2.remap(np.asarray(image, np.float32), gx + flow[..., 0], gy + flow[..., 1], cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(image.shape)


def flicker(video: np.ndarray, flow_from: np.ndarray | None = None) -> float:
    """Mean absolute temporal difference after motion compensation.

    For each pair of consecutive frames, frame t+1 is warped back onto frame t with the optical flow from t to
    t+1, and ``|frame_t - warped_{t+1}|`` is averaged over pixels, channels and pairs. Motion that the flow
    explains costs nothing; frame-to-frame brightness noise (flicker) does.

    Args:
        video: [T, H, W, C] in [0, 1], T >= 2.
        flow_from: optional [T, H, W, C] video to compute the flow on (e.g. a clean reference, so two versions
            of one video are compared under the same motion); default ``video`` itself.
    Returns:
        The mean absolute compensated difference, in intensity units.
    """
    video = np.asarray(video, np.float32)
    if video.ndim != 4 or video.shape[0] < 2:
        raise ValueError(f"flicker: expected [T >= 2, H, W, C], got shape {video.shape}")
    ref = video if flow_from is None else np.asarray(flow_from, np.float32)
    total = 0.0
    for t in range(video.shape[0] - 1):
        flow = optical_flow(ref[t], ref[t + 1])
        total += float(np.abs(video[t] - warp_by_flow(video[t + 1], flow)).mean())
    return total / (video.shape[0] - 1)


def mean_psnr_db(pred: np.ndarray, truth: np.ndarray) -> float:
    """Mean over frames of the per-frame PSNR of two [T, H, W, C] videos (the project's video PSNR)."""
    values = psnr(pred, truth)
    return float(np.mean(np.minimum(values, 100.0)))


def mean_ssim(pred: np.ndarray, truth: np.ndarray) -> float:
    """Mean over frames of the per-frame SSIM of two [T, H, W, C] videos."""
    return float(np.mean([ssim(p, t) for p, t in zip(pred, truth)]))


def image_loss(pred: torch.Tensor, target: torch.Tensor, w_l1: float = 0.8, w_dssim: float = 0.2) -> torch.Tensor:
    """L_visual for one view: ``w_l1 * L1 + w_dssim * (1 - SSIM)`` on [H, W, C] images (3DGS, FluidNexus Eq. 5)."""
    loss = w_l1 * (pred - target).abs().mean()
    if w_dssim:
        loss = loss + w_dssim * (1.0 - ssim(pred, target))
    return loss
