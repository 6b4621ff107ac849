"""SPH smoothing kernels (Mueller et al. 2003) used by the PBF gas and the field queries.

All kernels take the support radius ``h`` in metres and return values in SI units: the Poly6 kernel
``W`` is a number density kernel [1/m^3], its gradients are [1/m^4]. Particles have unit mass, so
``rho = sum_j W(|x - p_j|)`` is a number density [1/m^3].
"""

import math

import numpy as np
import taichi as ti
from scipy.spatial import cKDTree

TINY = 1e-20  # guards sqrt(0) and 0/0 in differentiated code without changing any finite value


def poly6_coef(h: float) -> float:
    """Poly6 normalisation 315 / (64 pi h^9) [1/m^9]."""
    return 315.0 / (64.0 * math.pi * h**9)


def spiky_coef(h: float) -> float:
    """Spiky gradient magnitude factor -45 / (pi h^6) [1/m^6]."""
    return -45.0 / (math.pi * h**6)


# Written branch-free, without reassigned locals: inside a differentiated neighbour loop every reassigned
# local becomes an autodiff stack of bounded depth (taichi-notes), so these are single expressions.
@ti.func
def poly6(r2, h, coef):
    """Poly6 W(r) = coef (h^2 - r^2)^3 for r < h, else 0 (Mueller 2003, Eq. 20); ``r2`` = |r|^2."""
    d = ti.max(h * h - r2, 0.0)
    return coef * d * d * d


@ti.func
def spiky_grad(r, h, coef):
    """Spiky gradient -45 / (pi h^6) (h - |r|)^2 r / |r| for |r| < h, else 0 (Mueller 2003, Eq. 21).

    ``r`` = x_i - x_j (3-vector); the result is grad_{x_i} W(x_i - x_j) (zero at r = 0).
    """
    rl = ti.sqrt(ti.max(r.norm_sqr(), TINY))
    d = ti.max(h - rl, 0.0)
    return (coef * d * d / rl) * r


@ti.func
def poly6_grad(r, h, coef):
    """grad_r of Poly6 W(|r|^2) = -6 coef (h^2 - |r|^2)^2 r (zero beyond h)."""
    d = ti.max(h * h - r.norm_sqr(), 0.0)
    return (-6.0 * coef * d * d) * r


@ti.func
def spiky_hessian_vec(r, v, h, coef):
    """Hessian-vector product (d spiky_grad / d r) v = a v + b (r_hat . v) r_hat, l = |r|,

    a = coef (h - l)^2 / l, b = coef (-2 (h - l) - (h - l)^2 / l).

    Zero beyond h, and zero at r = 0 (where the spiky gradient is defined as zero).
    """
    r2 = r.norm_sqr()
    l = ti.sqrt(ti.max(r2, TINY))
    d = ti.max(h - l, 0.0)
    a = coef * d * d / l
    b = coef * (-2.0 * d - d * d / l)
    rh = r / l
    out = a * v + b * rh.dot(v) * rh
    if r2 <= 0.0:
        out = ti.Vector([0.0, 0.0, 0.0])
    return out


@ti.func
def ipow(a, n: ti.template()):
    """a ** n for a compile-time integer n >= 0, as a product (no loop, no reassigned local)."""
    if ti.static(n == 0):
        return 1.0
    else:
        return a * ipow(a, n - 1)


def lattice_density(spacing: float, h: float) -> float:
    """Poly6 number density [1/m^3] of an interior particle of an infinite cubic lattice (self term included).

    Used to pick the rest density relative to the initial lattice (docs/simulator.md).
    """
    m = int(math.ceil(h / spacing))
    ax = np.arange(-m, m + 1) * spacing
    r2 = (ax[:, None, None] ** 2 + ax[None, :, None] ** 2 + ax[None, None, :] ** 2).ravel()
    r2 = r2[r2 < h * h]
    return float(np.sum(poly6_coef(h) * (h * h - r2) ** 3))


def point_density(points: np.ndarray, particles: np.ndarray, h: float) -> np.ndarray:
    """Poly6 number density [M] [1/m^3] of ``particles`` [N, 3] at ``points`` [M, 3] (numpy; between steps)."""
    out = np.zeros(len(points))
    if len(points) and len(particles):
        pairs = cKDTree(points).sparse_distance_matrix(cKDTree(particles), h, output_type="ndarray")
        np.add.at(out, pairs["i"], poly6_coef(h) * (h * h - pairs["v"] ** 2) ** 3)
    return out
