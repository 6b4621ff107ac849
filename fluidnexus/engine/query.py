"""Fields of the particle gas at arbitrary points: velocity V(x) (FluidNexus Eq. 2), density rho(x), divergence.

Differentiable w.r.t. the query points, the particle positions and the particle velocities (a hand-written,
deterministic adjoint of the neighbour sums and ``ti.ad`` of the normalisation).
"""
import numpy as np
import taichi as ti
import torch

from . import tensors
from .neighbors import NeighborTable
from .runtime import real
from .sph import poly6, poly6_coef, poly6_grad


@ti.kernel
def accumulate_interpolation(nq: int, h: float, w_coef: float, q: ti.template(), p: ti.template(), u: ti.template(),
                             nbr: ti.template(), count: ti.template(), num: ti.template(), den: ti.template()):
    # num(x) = sum_j u_j W(x - p_j), den(x) = rho(x) = sum_j W(x - p_j)   (FluidNexus Eq. 2)
    for i in range(nq):
        acc_n, acc_d = ti.Vector([0.0, 0.0, 0.0]), 0.0
        for k in range(count[i]):
            j = nbr[i, k]
            w = poly6((q[i] - p[j]).norm_sqr(), h, w_coef)
            acc_n += w * u[j]
            acc_d += w
        num[i] += acc_n
        den[i] += acc_d


# Hand-written adjoint of accumulate_interpolation, as two gathers (no float atomics, so reruns are
# bit-identical): each query sums over its own neighbours, each particle over the queries that list it (the
# transposed table, in increasing query order). With c_ij = num_bar_i . u_j + den_bar_i and r = q_i - p_j:
# q_bar_i = sum_j c_ij grad W(r), p_bar_j = -sum_i c_ij grad W(r), u_bar_j = sum_i W(r) num_bar_i.
@ti.kernel
def query_adjoint(nq: int, h: float, w_coef: float, q: ti.template(), p: ti.template(), u: ti.template(),
                  nbr: ti.template(), count: ti.template(), num: ti.template(), den: ti.template()):
    for i in range(nq):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            acc += (num.grad[i].dot(u[j]) + den.grad[i]) * poly6_grad(q[i] - p[j], h, w_coef)
        q.grad[i] += acc


@ti.kernel
def source_adjoint(n_src: int, h: float, w_coef: float, q: ti.template(), p: ti.template(), u: ti.template(),
                   start: ti.types.ndarray(), queries: ti.types.ndarray(), num: ti.template(), den: ti.template()):
    for j in range(n_src):
        acc_p, acc_u = ti.Vector([0.0, 0.0, 0.0]), ti.Vector([0.0, 0.0, 0.0])
        for s in range(start[j], start[j + 1]):
            i = queries[s]
            r = q[i] - p[j]
            acc_p -= (num.grad[i].dot(u[j]) + den.grad[i]) * poly6_grad(r, h, w_coef)
            acc_u += poly6(r.norm_sqr(), h, w_coef) * num.grad[i]
        p.grad[j] += acc_p
        u.grad[j] += acc_u


@ti.kernel
def normalize_velocity(nq: int, num: ti.template(), den: ti.template(), vel: ti.template()):
    # V(x) = num / den; a point with no particle within h gets V = 0 (it does not move)
    for i in range(nq):
        if den[i] > 0.0:
            vel[i] = num[i] / den[i]


class FieldQuery:
    """Workspace to evaluate V(x) and rho(x) of up to ``source_capacity`` particles at ``query_capacity`` points.

    Args:
        source_capacity: most particles.
        query_capacity: most query points per call.
        h: kernel radius [m].
    """

    def __init__(self, source_capacity: int, query_capacity: int, h: float = 0.02, width: int = 48):
        self.h = float(h)
        f = real()
        self.source_capacity, self.query_capacity = int(source_capacity), int(query_capacity)
        vec = lambda c: ti.Vector.field(3, f, shape=c, needs_grad=True)  # noqa: E731
        self.q, self.vel, self.num = vec(self.query_capacity), vec(self.query_capacity), vec(self.query_capacity)
        self.p, self.u = vec(self.source_capacity), vec(self.source_capacity)
        self.den = ti.field(f, shape=self.query_capacity, needs_grad=True)
        self.table = NeighborTable(self.source_capacity, self.query_capacity, width=width)
        self.nq = self.np = 0
        self.token = None

    def forward(self, q, p, u=None) -> None:
        """Evaluate at query points q [M, 3] for particles p [N, 3] with velocities u [N, 3] (None: zeros)."""
        q, p = tensors.as_tensor(q, 3), tensors.as_tensor(p, 3)
        u = torch.zeros_like(p) if u is None else tensors.as_tensor(u, 3)
        if q.shape[0] > self.query_capacity or p.shape[0] > self.source_capacity:
            raise ValueError(f"query over capacity: {q.shape[0]}/{self.query_capacity} points, "
                             f"{p.shape[0]}/{self.source_capacity} particles")
        self.nq, self.np = q.shape[0], p.shape[0]
        for fld in (self.q, self.p, self.u):
            fld.fill(0)
        tensors.load(self.q, q)
        tensors.load(self.p, p)
        tensors.load(self.u, u)
        for fld in (self.num, self.den, self.vel):
            fld.fill(0)
        self.table.build(self.p, self.np, self.h, query=self.q, n_query=self.nq)
        self._args = (self.h, poly6_coef(self.h), self.q, self.p, self.u)
        accumulate_interpolation(self.nq, *self._args, self.table.nbr, self.table.count, self.num, self.den)
        normalize_velocity(self.nq, self.num, self.den, self.vel)
        self.token = object()

    def velocity(self) -> torch.Tensor:
        """V at the query points [M, 3] m/s."""
        return tensors.store(self.vel, self.nq)

    def density(self) -> torch.Tensor:
        """rho at the query points [M] 1/m^3."""
        return tensors.store(self.den, self.nq).reshape(-1)

    def backward(self, grad_vel=None, grad_den=None):
        """Gradients (dL/dq [M, 3], dL/dp [N, 3], dL/du [N, 3]) from dL/dV [M, 3] and dL/drho [M]."""
        for fld in (self.q, self.p, self.u, self.num, self.den, self.vel):
            fld.grad.fill(0)
        if grad_vel is not None:
            tensors.load(self.vel.grad, grad_vel)
        if grad_den is not None:
            tensors.load(self.den.grad, tensors.as_tensor(grad_den).reshape(-1, 1))
        normalize_velocity.grad(self.nq, self.num, self.den, self.vel)
        query_adjoint(self.nq, *self._args, self.table.nbr, self.table.count, self.num, self.den)
        start, queries = self.table.transpose(self.np)
        source_adjoint(self.np, *self._args, start, queries, self.num, self.den)
        return (tensors.store(self.q.grad, self.nq), tensors.store(self.p.grad, self.np),
                tensors.store(self.u.grad, self.np))


def grid_points(lo, hi, res) -> np.ndarray:
    """Node positions [rx * ry * rz, 3] of a regular grid with ``res`` nodes per axis from ``lo`` to ``hi`` [m]."""
    axes = [np.linspace(lo[d], hi[d], int(res[d])) for d in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def divergence_on_grid(query: FieldQuery, p, u, lo, hi, res, chunk: int | None = None):
    """Divergence of V (FluidNexus Eq. 2) on a regular grid, by central differences.

    Definition (the evaluation metric): V is sampled at the nodes of the grid with ``res`` = (rx, ry, rz)
    nodes from ``lo`` to ``hi`` (spacing d_a = (hi_a - lo_a) / (r_a - 1)); at every interior node
    div = sum_a (V_a[+1] - V_a[-1]) / (2 d_a). Nodes whose rho is 0 have V = 0 by definition.

    Returns:
        (div [rx-2, ry-2, rz-2] 1/s, rho [rx-2, ry-2, rz-2] 1/m^3 at the same nodes).
    """
    res = [int(r) for r in res]
    pts = grid_points(lo, hi, res)
    chunk = chunk or query.query_capacity
    vel = np.zeros_like(pts)
    rho = np.zeros(len(pts))
    for s in range(0, len(pts), chunk):
        query.forward(pts[s:s + chunk], p, u)
        vel[s:s + chunk] = query.velocity().numpy()
        rho[s:s + chunk] = query.density().numpy()
    vel, rho = vel.reshape(*res, 3), rho.reshape(res)
    spacing = [(hi[d] - lo[d]) / (res[d] - 1) for d in range(3)]
    inner = (slice(1, -1),) * 3
    div = np.zeros([r - 2 for r in res])
    for a in range(3):
        plus = [slice(1, -1)] * 3
        minus = [slice(1, -1)] * 3
        plus[a], minus[a] = slice(2, None), slice(None, -2)
        div += (vel[tuple(plus)][..., a] - vel[tuple(minus)][..., a]) / (2 * spacing[a])
    return div, rho[inner]


def mean_abs_divergence(query: FieldQuery, p, u, lo, hi, res) -> float:
    """The divergence metric: mean |div V| over the interior grid nodes where rho > 0 (inside the gas)."""
    div, rho = divergence_on_grid(query, p, u, lo, hi, res)
    inside = rho > 0
    return float(np.abs(div[inside]).mean()) if inside.any() else 0.0
