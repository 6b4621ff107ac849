"""Rigid obstacles with one-way coupling (FluidNexus Sec. 4.2 and supp.; Macklin et al. 2014, Sec. 5).

After each constraint iteration of the PBF step (and after advection for visual particles) a point inside the
body is moved to the nearest point of its surface. Two bodies:

- :class:`SphereObstacle`: analytic, x <- c + r (x - c) / |x - c| when |x - c| < r.
- :class:`GridObstacle`: a signed-distance field sampled on a regular grid (negative inside), e.g. of a
  triangle mesh; a point with phi(x) < 0 moves by -phi(x) grad phi / |grad phi| (trilinear phi; repeated until
  it is outside, at most ``passes`` times: one or two where phi is a true distance). Where phi is flat inside the
  body (a ragged body carved from voxels), it steps instead toward the least deep of its six neighbours one cell
  away. Points outside the grid are outside the body.
- :class:`ObstacleGroup`: several bodies (a scene's declared obstacles plus an interaction's), one after another.

The projection is not differentiated: a simulator step with an obstacle has no backward (docs/prediction.md).
"""

import numpy as np
import taichi as ti
import torch

from . import tensors
from .runtime import real

GRID_PASSES = 12  # at most; a point stops once outside (1-2 passes where phi is a true distance)


@ti.kernel
def project_sphere(n: int, row: int, cx: float, cy: float, cz: float, r: float, x: ti.template()):
    # inside the ball |x - c| < r: move to the nearest surface point c + r (x - c) / |x - c|
    for i in range(n):
        c = ti.Vector([cx, cy, cz])
        d = x[row, i] - c
        dist = d.norm()
        if dist < r:
            if dist > 1e-12 * r:
                x[row, i] = c + d * (r / dist)
            else:  # at the centre every surface point is nearest: take the top one
                x[row, i] = c + ti.Vector([0.0, r, 0.0])


@ti.func
def _trilinear(phi: ti.template(), g, res):
    # value and gradient (in grid units) of the trilinear interpolant of phi at grid coordinate g
    i0 = ti.cast(ti.floor(g), ti.i32)
    i0 = ti.math.clamp(i0, 0, res - 2)
    f = g - ti.cast(i0, float)
    value = 0.0
    grad = ti.Vector([0.0, 0.0, 0.0])
    for a, b, c in ti.static(ti.ndrange(2, 2, 2)):
        v = phi[i0[0] + a, i0[1] + b, i0[2] + c]
        wx = f[0] if a else 1.0 - f[0]
        wy = f[1] if b else 1.0 - f[1]
        wz = f[2] if c else 1.0 - f[2]
        sx = 1.0 if a else -1.0
        sy = 1.0 if b else -1.0
        sz = 1.0 if c else -1.0
        value += v * wx * wy * wz
        grad += v * ti.Vector([sx * wy * wz, wx * sy * wz, wx * wy * sz])
    return value, grad


@ti.func
def _plateau_step(phi: ti.template(), g, res, top, value):
    # where phi is flat over a cell inside the body (a ragged voxel body: every corner one half-voxel deep), the
    # gradient names no surface; step (in grid units) along the axis whose neighbour one cell away is least deep,
    # to where phi, linear between here and there, reaches 0 (at most one cell); ``top`` is the last node's index
    best, step = value, ti.Vector([0.0, 0.0, 0.0])
    for k in ti.static(range(3)):
        for s in ti.static((1.0, -1.0)):
            e = ti.Vector([0.0, 0.0, 0.0])
            e[k] = s
            v, _ = _trilinear(phi, ti.math.clamp(g + e, 0.0, top), res)
            if v > best:
                best, step = v, e
    t = 1.0
    if best > 0.0:
        t = -value / (best - value)
    return step * t


@ti.kernel
def project_grid(n: int, row: int, passes: int, ox: float, oy: float, oz: float, spacing: float,
                 phi: ti.template(), x: ti.template()):
    # phi(x) < 0 (inside): x <- x - phi(x) grad phi / |grad phi|, the nearest surface point of a distance field
    res = ti.Vector([phi.shape[0], phi.shape[1], phi.shape[2]])
    origin = ti.Vector([ox, oy, oz])
    top = ti.cast(res - 1, float)
    for i in range(n):
        for _ in range(passes):
            g = (x[row, i] - origin) / spacing
            if not ((g >= 0).all() and (g <= top).all()):
                break
            value, grad = _trilinear(phi, g, res)
            if value >= 0.0:
                break
            norm = grad.norm()
            if norm > 1e-12:
                x[row, i] = x[row, i] - value * grad / norm
            else:
                x[row, i] = x[row, i] + spacing * _plateau_step(phi, g, res, top, value)


@ti.func
def _closest_on_triangle(p, a, b, c):
    # closest point of triangle abc to p by Voronoi regions (Ericson, Real-Time Collision Detection, 5.1.5)
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = ab.dot(ap), ac.dot(ap)
    d3, d4 = ab.dot(bp), ac.dot(bp)
    d5, d6 = ab.dot(cp), ac.dot(cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    q = a
    if d1 <= 0 and d2 <= 0:
        q = a
    elif d3 >= 0 and d4 <= d3:
        q = b
    elif d6 >= 0 and d5 <= d6:
        q = c
    elif vc <= 0 and d1 >= 0 and d3 <= 0:
        q = a + ab * (d1 / (d1 - d3))
    elif vb <= 0 and d2 >= 0 and d6 <= 0:
        q = a + ac * (d2 / (d2 - d6))
    elif va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        q = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    else:
        denom = va + vb + vc
        q = a + ab * (vb / denom) + ac * (vc / denom)
    return q


@ti.kernel
def signed_distance_kernel(nx: int, ny: int, nz: int, ox: float, oy: float, oz: float, spacing: float,
                           nf: int, tri: ti.types.ndarray(), phi: ti.types.ndarray()):
    # phi = +-min_f |p - closest_f(p)|, negative where the generalised winding number sum_f Omega_f / (4 pi) > 1/2
    # (solid angle of a triangle: Van Oosterom & Strackee 1983; winding number: Jacobson et al. 2013)
    for i, j, k in ti.ndrange(nx, ny, nz):
        p = ti.Vector([ox + spacing * i, oy + spacing * j, oz + spacing * k])
        best = 1e30
        wind = 0.0
        for f in range(nf):
            a = ti.Vector([tri[f, 0, 0], tri[f, 0, 1], tri[f, 0, 2]])
            b = ti.Vector([tri[f, 1, 0], tri[f, 1, 1], tri[f, 1, 2]])
            c = ti.Vector([tri[f, 2, 0], tri[f, 2, 1], tri[f, 2, 2]])
            best = ti.min(best, (p - _closest_on_triangle(p, a, b, c)).norm())
            ra, rb, rc = a - p, b - p, c - p
            la, lb, lc = ra.norm(), rb.norm(), rc.norm()
            det = ra.dot(rb.cross(rc))
            div = la * lb * lc + ra.dot(rb) * lc + rb.dot(rc) * la + rc.dot(ra) * lb
            wind += 2.0 * ti.atan2(det, div)
        phi[i, j, k] = -best if wind / (4.0 * 3.141592653589793) > 0.5 else best


def signed_distance_grid(triangles: np.ndarray, origin, spacing: float, res) -> np.ndarray:
    """Signed distance [nx, ny, nz] m (negative inside) of a closed, outward-oriented triangle mesh
    ``triangles`` [F, 3, 3] m at the nodes ``origin + spacing * (i, j, k)``."""
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    phi = np.zeros(tuple(int(r) for r in res), dtype=np.float64)
    signed_distance_kernel(*phi.shape, *(float(v) for v in origin), float(spacing), len(tri), tri, phi)
    return phi


class SphereObstacle:
    """A ball: centre (3,) m and radius r > 0 m."""

    def __init__(self, center, radius: float):
        if not radius > 0:
            raise ValueError(f"the ball's radius must be > 0, got {radius}")
        self.center = tuple(float(v) for v in center)
        self.radius = float(radius)

    def project(self, x, row: int, n: int) -> None:
        """Move the points x[row, :n] (a [rows, capacity] vector field) out of the ball."""
        project_sphere(n, row, *self.center, self.radius, x)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance [K] m of points [K, 3] (negative inside)."""
        return np.linalg.norm(points - np.asarray(self.center), axis=-1) - self.radius


class GridObstacle:
    """A body given by its signed distance phi [nx, ny, nz] m sampled at ``origin + spacing * index``."""

    def __init__(self, phi: np.ndarray, origin, spacing: float, passes: int = GRID_PASSES):
        phi = np.asarray(phi, dtype=np.float64)
        if phi.ndim != 3 or min(phi.shape) < 2:
            raise ValueError(f"phi must be a 3D grid with at least 2 nodes per axis, got {phi.shape}")
        if not spacing > 0:
            raise ValueError(f"grid spacing must be > 0, got {spacing}")
        self.phi_np, self.origin = phi, tuple(float(v) for v in origin)
        self.spacing, self.passes = float(spacing), passes
        self.phi = ti.field(real(), shape=phi.shape)
        self.phi.from_numpy(phi.astype(np.float64 if real() == ti.f64 else np.float32))

    def project(self, x, row: int, n: int) -> None:
        """Move the points x[row, :n] (a [rows, capacity] vector field) to the body's surface where inside."""
        project_grid(n, row, self.passes, *self.origin, self.spacing, self.phi, x)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Trilinear signed distance [K] m of points [K, 3]; +inf outside the grid."""
        g = (np.asarray(points, dtype=np.float64) - np.asarray(self.origin)) / self.spacing
        res = np.asarray(self.phi_np.shape)
        inside = np.all((g >= 0) & (g <= res - 1), axis=-1)
        i0 = np.clip(np.floor(g).astype(int), 0, res - 2)
        f = g - i0
        out = np.zeros(len(g))
        for a in (0, 1):
            for b in (0, 1):
                for c in (0, 1):
                    w = (f[:, 0] if a else 1 - f[:, 0]) * (f[:, 1] if b else 1 - f[:, 1]) * \
                        (f[:, 2] if c else 1 - f[:, 2])
                    out += w * self.phi_np[i0[:, 0] + a, i0[:, 1] + b, i0[:, 2] + c]
        return np.where(inside, out, np.inf)


class ObstacleGroup:
    """Several bodies at once: a point is projected out of each in turn (bodies that do not overlap leave it
    outside all of them)."""

    def __init__(self, bodies):
        self.bodies = tuple(bodies)

    def project(self, x, row: int, n: int) -> None:
        for body in self.bodies:
            body.project(x, row, n)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance [K] m to the nearest body (negative inside one)."""
        return np.min([b.distance(points) for b in self.bodies], axis=0)


class PointProjector:
    """Applies an obstacle to torch point sets (visual particles) through a scratch field."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        self.field = ti.Vector.field(3, real(), shape=(1, self.capacity))

    def __call__(self, obstacle, points: torch.Tensor) -> torch.Tensor:
        """Points [M, 3] m moved out of ``obstacle`` (a new tensor, same dtype)."""
        m = points.shape[0]
        if m == 0:
            return points.clone()
        if m > self.capacity:
            self.capacity = 2 * m
            self.field = ti.Vector.field(3, real(), shape=(1, self.capacity))
        tensors.load(self.field, tensors.as_tensor(points.detach(), 3), row=0)
        obstacle.project(self.field, 0, m)
        return tensors.store(self.field, m, row=0).to(points.dtype)
