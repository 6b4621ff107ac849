"""EWA projection of 3D Gaussians to image-space 2D Gaussians, culling and screen footprints.

3D Gaussian Splatting (Kerbl et al. 2023): a Gaussian with centre mu, scales s and unit quaternion q has the
world covariance Sigma = R S S^T R^T (Eq. 6). Its image is a 2D Gaussian with covariance
Sigma' = J W Sigma W^T J^T (Eq. 5; Zwicker et al. 2002, EWA splatting, Eq. 31) where W is the camera rotation and
J the Jacobian of the pinhole projection at the centre. A low-pass dilation of 0.3 px^2 is added to Sigma'
(Kerbl et al. reference code; Zwicker et al. 2002, Sec. 6) so that every splat covers at least about a pixel.

:func:`project_gaussians` is differentiated by Taichi's automatic adjoint (``project_gaussians.grad``); it runs
once per Gaussian and scatters nothing, so the automatic adjoint is as fast as a hand-written one.
"""

import numpy as np
import taichi as ti

DILATION = 0.3  # px^2 added to the 2D covariance (3DGS low-pass filter)
ALPHA_MIN = 1.0 / 255.0  # contributions below this are skipped (3DGS)
CLAMP_MARGIN = 0.15  # the Jacobian is evaluated with x/z, y/z clamped to the image +- 15% of its size (3DGS 1.3 x)
BOUND_SLACK = 1e-3  # in log units: footprints are this much larger than the exact alpha = 1/255 ellipse
DEFAULT_NEAR = 0.01  # metres


def pack_camera(camera, near: float) -> np.ndarray:
    """The camera as the 24 reals the kernels read.

    Layout: R (9, row-major), t (3), fx, fy, cx, cy, skew, near, lim_x_neg, lim_x_pos, lim_y_neg, lim_y_pos,
    width, height. The limits bound x/z and y/z where the projection Jacobian is evaluated.
    """
    K = camera.K
    fx, fy, cx, cy, skew = K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]
    w, h = float(camera.width), float(camera.height)
    lim = [(cx + CLAMP_MARGIN * w) / fx, (w - cx + CLAMP_MARGIN * w) / fx,
           (cy + CLAMP_MARGIN * h) / fy, (h - cy + CLAMP_MARGIN * h) / fy]
    return np.concatenate([camera.R.reshape(-1), camera.t, [fx, fy, cx, cy, skew, near], lim, [w, h]])


@ti.func
def quat_to_rotation(q):
    """Rotation matrix of the quaternion q = (w, x, y, z), normalised here (so q need not be unit)."""
    u = q / q.norm()
    w, x, y, z = u[0], u[1], u[2], u[3]
    return ti.Matrix([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ])


@ti.kernel
def project_gaussians(g: ti.template(), cam: ti.template(), n: ti.i32):
    """Write the projected centre ``g.xy`` (px), inverse 2D covariance ``g.conic`` and depth ``g.depth``.

    Gaussians at or in front of the near plane get only their depth; :func:`bound_footprints` culls them.
    """
    for i in range(n):
        rot = ti.Matrix([[cam[0], cam[1], cam[2]], [cam[3], cam[4], cam[5]], [cam[6], cam[7], cam[8]]])
        p = rot @ g.means[i] + ti.Vector([cam[9], cam[10], cam[11]])
        fx, fy, cx, cy, skew, near = cam[12], cam[13], cam[14], cam[15], cam[16], cam[17]
        z = p[2]
        g.depth[i] = z
        if z > near:
            # Kerbl et al. 2023, Eq. (6): Sigma = R S S^T R^T, here in camera axes.
            s = g.scales[i]
            m = rot @ quat_to_rotation(g.quats[i]) @ ti.Matrix([
                [s[0], 0.0, 0.0], [0.0, s[1], 0.0], [0.0, 0.0, s[2]]])
            cov = m @ m.transpose()
            # Zwicker et al. 2002, Eq. (29): Jacobian of (u, v) = (fx x/z + skew y/z + cx, fy y/z + cy),
            # evaluated with x/z, y/z clamped near the image (3DGS) so off-screen splats stay bounded.
            tx = ti.math.clamp(p[0] / z, -cam[18], cam[19]) * z
            ty = ti.math.clamp(p[1] / z, -cam[20], cam[21]) * z
            jac = ti.Matrix([[fx / z, skew / z, -(fx * tx + skew * ty) / (z * z)],
                             [0.0, fy / z, -fy * ty / (z * z)]])
            # Kerbl et al. 2023, Eq. (5) plus the 0.3 px^2 low-pass dilation.
            cov2 = jac @ cov @ jac.transpose()
            a = cov2[0, 0] + DILATION
            b = cov2[0, 1]
            c = cov2[1, 1] + DILATION
            det = a * c - b * b
            g.conic[i] = ti.Vector([c / det, -b / det, a / det])
            g.xy[i] = ti.Vector([(fx * p[0] + skew * p[1]) / z + cx, fy * p[1] / z + cy])


@ti.kernel
def bound_footprints(g: ti.template(), cam: ti.template(), n: ti.i32, rect: ti.types.ndarray(),
                     power_min: ti.types.ndarray(), key: ti.types.ndarray()):
    """Cull and bound each projected Gaussian (not differentiated).

    A Gaussian is kept when it lies beyond the near plane, its opacity can reach 1/255 and its footprint
    meets the image. The footprint is the ellipse where opacity * exp(power) >= 1/255, i.e.
    d^T Sigma'^-1 d <= 2 ln(255 opacity); its axis-aligned extent is sqrt(2 ln(255 opacity) Sigma'_kk).

    Args:
        rect: [n, 4] int32 out, first/last pixel column and row inside the image (empty when culled).
        power_min: [n] real out, the exponent below which the alpha test fails (minus a small slack).
        key: [n] real out, the depth sort key (camera z; +inf when culled).
    """
    for i in range(n):
        width, height = cam[22], cam[23]
        rect[i, 0], rect[i, 1], rect[i, 2], rect[i, 3] = 0, -1, 0, -1
        key[i] = ti.math.inf
        power_min[i] = 0.0
        op = g.opacities[i]
        if g.depth[i] > cam[17] and op * 255.0 > 1.0:
            con = g.conic[i]
            det = con[0] * con[2] - con[1] * con[1]
            log_level = ti.log(op * 255.0) + BOUND_SLACK
            rx = ti.sqrt(2.0 * log_level * con[2] / det)
            ry = ti.sqrt(2.0 * log_level * con[0] / det)
            x, y = g.xy[i][0], g.xy[i][1]
            # pixel centres sit at index + 0.5; clamp before the integer cast so huge splats cannot overflow.
            i0 = ti.cast(ti.ceil(ti.math.clamp(x - rx - 0.5, -1.0, width)), ti.i32)
            i1 = ti.cast(ti.floor(ti.math.clamp(x + rx - 0.5, -1.0, width)), ti.i32)
            j0 = ti.cast(ti.ceil(ti.math.clamp(y - ry - 0.5, -1.0, height)), ti.i32)
            j1 = ti.cast(ti.floor(ti.math.clamp(y + ry - 0.5, -1.0, height)), ti.i32)
            i0, j0 = ti.max(i0, 0), ti.max(j0, 0)
            i1 = ti.min(i1, ti.cast(width, ti.i32) - 1)
            j1 = ti.min(j1, ti.cast(height, ti.i32) - 1)
            if i0 <= i1 and j0 <= j1:
                rect[i, 0], rect[i, 1], rect[i, 2], rect[i, 3] = i0, i1, j0, j1
                key[i] = g.depth[i]
                power_min[i] = -log_level
