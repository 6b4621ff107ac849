"""Slow, obvious dense 3D Gaussian splatting in plain torch (test-only reference for fluidnexus.engine.splat).

Every pixel is composited against every Gaussian in depth order; torch autograd gives the gradients. It follows
the same rules as the Taichi renderer (Kerbl et al. 2023): Sigma = R S S^T R^T, EWA projection with the
Jacobian evaluated at x/z, y/z clamped to the image +- 15 %, a 0.3 px^2 dilation, alpha = min(0.99, o exp(power)),
contributions below 1/255 skipped, and compositing stopped before the transmittance falls below 1e-4.
The background is one colour [C] or one colour per pixel [H, W, C].
"""
import torch

DILATION = 0.3
ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.99
T_MIN = 1e-4
CLAMP_MARGIN = 0.15


def quat_to_rotation(quats: torch.Tensor) -> torch.Tensor:
    """[N, 4] (w, x, y, z), any norm -> [N, 3, 3] rotation matrices."""
    w, x, y, z = (quats / quats.norm(dim=1, keepdim=True)).unbind(1)
    return torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], dim=1).reshape(-1, 3, 3)


def project_reference(camera, means, scales, quats, near: float = 0.01):
    """EWA projection of [N] Gaussians.

    Returns:
        xy [N, 2] pixels, conic [N, 3] (a, b, c) of the inverse 2D covariance, depth [N] camera z,
        in_front [N] bool (z > near).
    """
    dt = means.dtype
    R = torch.as_tensor(camera.R, dtype=dt)
    t = torch.as_tensor(camera.t, dtype=dt)
    K = camera.K
    fx, fy, cx, cy, skew = (float(v) for v in (K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]))
    w, h = float(camera.width), float(camera.height)
    p = means @ R.T + t
    z = p[:, 2]
    in_front = z > near
    zs = torch.where(in_front, z, torch.ones_like(z))  # keep culled rows finite (their values are unused)
    m = R @ quat_to_rotation(quats) @ torch.diag_embed(scales)
    cov = m @ m.transpose(1, 2)
    tx = torch.clamp(p[:, 0] / zs, -(cx + CLAMP_MARGIN * w) / fx, (w - cx + CLAMP_MARGIN * w) / fx) * zs
    ty = torch.clamp(p[:, 1] / zs, -(cy + CLAMP_MARGIN * h) / fy, (h - cy + CLAMP_MARGIN * h) / fy) * zs
    zero = torch.zeros_like(zs)
    jac = torch.stack([
        torch.stack([fx / zs, skew / zs + zero, -(fx * tx + skew * ty) / zs ** 2], 1),
        torch.stack([zero, fy / zs, -fy * ty / zs ** 2], 1),
    ], 1)
    cov2 = jac @ cov @ jac.transpose(1, 2)
    a, b, c = cov2[:, 0, 0] + DILATION, cov2[:, 0, 1], cov2[:, 1, 1] + DILATION
    det = a * c - b * b
    conic = torch.stack([c / det, -b / det, a / det], 1)
    xy = torch.stack([(fx * p[:, 0] + skew * p[:, 1]) / zs + cx, fy * p[:, 1] / zs + cy], 1)
    return xy, conic, z, in_front


def render_reference(camera, means, scales, quats, opacities, colors, background, near: float = 0.01,
                     rows: tuple[int, int] | None = None):
    """Dense front-to-back compositing of every Gaussian at every pixel centre.

    Args:
        background: [C] one colour, or [H, W, C] one per pixel (the full image's, also with ``rows``).
        rows: render only image rows [r0, r1) (to bound memory on large images); default all.
    Returns:
        image [H, W, C], alpha [H, W], depth [H, W] (sum of alpha-weighted camera z); H = r1 - r0 with rows.
    """
    dt = means.dtype
    r0, r1 = rows if rows is not None else (0, camera.height)
    h, w = r1 - r0, camera.width
    xy, conic, z, in_front = project_reference(camera, means, scales, quats, near)
    order = torch.argsort(torch.where(in_front, z, torch.full_like(z, float("inf"))).detach(), stable=True)
    xy, conic, z, in_front = xy[order], conic[order], z[order], in_front[order]
    op, col = opacities[order], colors[order]
    py, px = torch.meshgrid(torch.arange(r0, r1, dtype=dt), torch.arange(w, dtype=dt), indexing="ij")
    pix = torch.stack([px.reshape(-1) + 0.5, py.reshape(-1) + 0.5], 1)  # [P, 2]
    d = pix[:, None, :] - xy[None, :, :]  # [P, N, 2]
    power = -0.5 * (conic[:, 0] * d[..., 0] ** 2 + conic[:, 2] * d[..., 1] ** 2) - conic[:, 1] * d[..., 0] * d[..., 1]
    alpha = torch.clamp(op * torch.exp(power), max=ALPHA_MAX)
    alpha = torch.where((alpha >= ALPHA_MIN) & in_front, alpha, torch.zeros_like(alpha))
    with torch.no_grad():
        keep = torch.cumprod(1 - alpha, dim=1) >= T_MIN  # early termination: drop the first that crosses
    alpha = alpha * keep
    trans = torch.cumprod(torch.cat([torch.ones_like(alpha[:, :1]), 1 - alpha], 1), dim=1)
    weight = alpha * trans[:, :-1]
    t_n = trans[:, -1]
    if background.dim() == 3:
        background = background[r0:r1].reshape(-1, background.shape[-1])
    image = weight @ col + t_n[:, None] * background
    depth = weight @ z
    return image.reshape(h, w, -1), (1 - t_n).reshape(h, w), depth.reshape(h, w)


def random_gaussians(n: int, channels: int, seed: int = 0, dtype=torch.float64, spread: float = 0.6,
                     scale=(0.05, 0.3), opacity=(0.2, 0.7)):
    """A small random scene around the world origin: means, scales, quats, opacities, colors (in that order)."""
    gen = torch.Generator().manual_seed(seed)

    def rand(*shape):
        return torch.rand(*shape, generator=gen, dtype=dtype)

    means = (rand(n, 3) * 2 - 1) * spread
    scales = scale[0] + (scale[1] - scale[0]) * rand(n, 3)
    quats = torch.randn(n, 4, generator=gen, dtype=dtype)
    opacities = opacity[0] + (opacity[1] - opacity[0]) * rand(n)
    colors = rand(n, channels)
    return means, scales, quats, opacities, colors
