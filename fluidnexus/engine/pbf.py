"""The differentiable Position-Based-Fluids gas step (FluidNexus Eq. S1-S4; Macklin & Mueller 2013).

One step, all in ``ti.ad``-differentiable kernels whose reverse goes on a small tape:

1. external terms at (p, u): force f (forces.py), density rho(p) for the drag;
2. prediction u_hat = u + dt f, x^0 = p + dt u_hat (Eq. S1 with alpha g inside f);
3. ``iterations`` density-constraint projections, iteration k reading x^k and writing x^{k+1} (its own row
   of an [iterations + 1, N] field so the tape can replay it), one launch each;
4. velocity u' = (x^K - p) / dt; p' = x^K.

The two neighbour tables (at p for the external terms, at x^0 for the solver) are built outside the tape by
non-differentiated kernels and reused by every iteration.
"""

from dataclasses import dataclass
from typing import Callable

import taichi as ti
import torch

from . import tensors
from .entrainment import entrain
from .model import ModelConfig, SolverConfig
from .neighbors import NeighborTable
from .runtime import real
from .sph import ipow, poly6, poly6_coef, poly6_grad, spiky_coef, spiky_grad, spiky_hessian_vec


@ti.kernel
def accumulate_density(n: int, h: float, w_coef: float, p: ti.template(), nbr: ti.template(), count: ti.template(),
                       rho: ti.template()):
    # rho_i += sum_{j != i} W(p_i - p_j)   (FluidNexus Eq. 2 density; the self term is pre-filled)
    for i in range(n):
        acc = 0.0
        for k in range(count[i]):
            acc += poly6((p[i] - p[nbr[i, k]]).norm_sqr(), h, w_coef)
        rho[i] += acc


@ti.kernel
def predict(n: int, dt: float, p: ti.template(), u: ti.template(), force: ti.template(), x: ti.template()):
    # FluidNexus Eq. S1: u_hat = u + dt (alpha g + f); p_hat = p + dt u_hat
    for i in range(n):
        x[0, i] = p[i] + dt * (u[i] + dt * force[i])


@ti.func
def _lambda(i, it, w0, rho0, eps, rho, gsum, gsq, lam, vol):
    # lambda_i = -C_i / (sum_k |grad_k C_i|^2 + eps), C_i = v_i rho_i / rho0 - 1 (two-sided; Macklin Eq. 11), with
    # v_i the particle's rest volume (1 = its own; entrainment grows it, engine/entrainment.py): it rests at
    # rho0 / v_i. grad_k C_i = v_i grad_k(rho_i) / rho0, so the stored lam is v_i lambda_i and the position update
    # below keeps its symmetric form. v_i = 1 gives the paper's constraint bit for bit.
    v = vol[i]
    c = v * (rho[it, i] + w0) / rho0 - 1.0
    lam[it, i] = -v * c / (v * v * (gsum[it, i].norm_sqr() + gsq[it, i]) / (rho0 * rho0) + eps)


@ti.kernel
def compute_lambda(n: int, it: int, w0: float, rho0: float, eps: float, rho: ti.template(), gsum: ti.template(),
                   gsq: ti.template(), lam: ti.template(), vol: ti.template()):
    for i in range(n):
        _lambda(i, it, w0, rho0, eps, rho, gsum, gsq, lam, vol)


@ti.func
def _apply(i, it, averaging: ti.template(), count, dp, x):
    # x^{k+1} = x^k + dp (divided by the neighbour count with constraint averaging)
    if ti.static(averaging):
        x[it + 1, i] = x[it, i] + dp[it, i] / ti.max(1.0, ti.cast(count[i], float))
    else:
        x[it + 1, i] = x[it, i] + dp[it, i]


@ti.kernel
def apply_delta(n: int, it: int, averaging: ti.template(), count: ti.template(), dp: ti.template(),
                x: ti.template()):
    for i in range(n):
        _apply(i, it, averaging, count, dp, x)


@ti.kernel
def project_constraint(n: int, it: int, h: float, w_coef: float, g_coef: float, w0: float, rho0: float, eps: float,
                       scorr_k: float, scorr_n: ti.template(), w_dq: float, averaging: ti.template(),
                       x: ti.template(), nbr: ti.template(), count: ti.template(), rho: ti.template(),
                       gsum: ti.template(), gsq: ti.template(), lam: ti.template(), dp: ti.template(),
                       vol: ti.template()):
    """One density-constraint projection x^it -> x^{it+1}, as four loops in one launch (launches cost more than
    these loops at a few thousand particles). Its reverse pass is four kernels: ``constraint_adjoint``,
    ``compute_lambda.grad``, ``delta_adjoint`` and ``apply_delta.grad``."""
    # rho_i, sum_j grad_i W_ij and sum_j |grad_i W_ij|^2 over the neighbours (Macklin & Mueller 2013, Eq. 8-9)
    for i in range(n):
        acc_w, acc_g, acc_q = 0.0, ti.Vector([0.0, 0.0, 0.0]), 0.0
        for k in range(count[i]):
            r = x[it, i] - x[it, nbr[i, k]]
            g = spiky_grad(r, h, g_coef)
            acc_w += poly6(r.norm_sqr(), h, w_coef)
            acc_g += g
            acc_q += g.norm_sqr()
        rho[it, i] = acc_w
        gsum[it, i] = acc_g
        gsq[it, i] = acc_q
    for i in range(n):
        _lambda(i, it, w0, rho0, eps, rho, gsum, gsq, lam, vol)
    # dp_i = (1/rho0) sum_j (lambda_i + lambda_j + s_corr) grad W_ij, s_corr = -K (W/W(dq))^n (Macklin Eq. 12-14)
    for i in range(n):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            r = x[it, i] - x[it, j]
            s = -scorr_k * ipow(poly6(r.norm_sqr(), h, w_coef) / w_dq, scorr_n)
            acc += (lam[it, i] + lam[it, j] + s) / rho0 * spiky_grad(r, h, g_coef)
        dp[it, i] = acc
    for i in range(n):
        _apply(i, it, averaging, count, dp, x)


# Hand-written adjoints of the three neighbour loops above (the density and the projection's first and third
# loops; automatic ones would need per-pair forms that scatter with atomics, about 10x slower). They use that the
# self table is symmetric (j in N(i) iff i in N(j)), so every particle gathers the adjoint of both pair orders
# (i, j) and (j, i) without atomics. Checked against torch autograd and finite differences
# (tests/engine/test_pbf_step.py).
@ti.kernel
def density_adjoint(n: int, h: float, w_coef: float, p: ti.template(), nbr: ti.template(), count: ti.template(),
                    rho: ti.template()):
    # rho_i = sum_j W(p_i - p_j)  =>  p_bar_i += sum_j (rho_bar_i + rho_bar_j) grad W(p_i - p_j)
    for i in range(n):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            acc += (rho.grad[i] + rho.grad[j]) * poly6_grad(p[i] - p[j], h, w_coef)
        p.grad[i] += acc


@ti.func
def _constraint_pair_adjoint(r, rho_bar, gsum_bar, gsq_bar, h, w_coef, g_coef):
    # d/dr of rho_bar W(r) + gsum_bar . g(r) + gsq_bar |g(r)|^2, g = spiky gradient
    g = spiky_grad(r, h, g_coef)
    return rho_bar * poly6_grad(r, h, w_coef) + spiky_hessian_vec(r, gsum_bar + 2.0 * gsq_bar * g, h, g_coef)


@ti.kernel
def constraint_adjoint(n: int, it: int, h: float, w_coef: float, g_coef: float, x: ti.template(),
                       nbr: ti.template(), count: ti.template(), rho: ti.template(), gsum: ti.template(),
                       gsq: ti.template()):
    for i in range(n):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            r = x[it, i] - x[it, j]
            acc += _constraint_pair_adjoint(r, rho.grad[it, i], gsum.grad[it, i], gsq.grad[it, i], h, w_coef, g_coef)
            acc -= _constraint_pair_adjoint(-r, rho.grad[it, j], gsum.grad[it, j], gsq.grad[it, j], h, w_coef,
                                            g_coef)
        x.grad[it, i] += acc


@ti.func
def _delta_pair_adjoint(r, m, dp_bar, h, w_coef, g_coef, rho0, scorr_k, scorr_n: ti.template(), w_dq):
    # d/dr of dp_bar . (m + s(r) / rho0) g(r), m = (lambda_i + lambda_j) / rho0 + s(r) / rho0 held fixed
    g = spiky_grad(r, h, g_coef)
    a = poly6(r.norm_sqr(), h, w_coef) / w_dq
    ds = (-scorr_k * scorr_n) * ipow(a, scorr_n - 1) / w_dq * poly6_grad(r, h, w_coef)
    return m * spiky_hessian_vec(r, dp_bar, h, g_coef) + dp_bar.dot(g) / rho0 * ds


@ti.kernel
def delta_adjoint(n: int, it: int, h: float, w_coef: float, g_coef: float, rho0: float, scorr_k: float,
                  scorr_n: ti.template(), w_dq: float, x: ti.template(), nbr: ti.template(), count: ti.template(),
                  lam: ti.template(), dp: ti.template()):
    for i in range(n):
        acc_x = ti.Vector([0.0, 0.0, 0.0])
        acc_l = 0.0
        for k in range(count[i]):
            j = nbr[i, k]
            r = x[it, i] - x[it, j]
            s = -scorr_k * ipow(poly6(r.norm_sqr(), h, w_coef) / w_dq, scorr_n)
            m = (lam[it, i] + lam[it, j] + s) / rho0
            acc_l += (dp.grad[it, i] - dp.grad[it, j]).dot(spiky_grad(r, h, g_coef)) / rho0
            acc_x += _delta_pair_adjoint(r, m, dp.grad[it, i], h, w_coef, g_coef, rho0, scorr_k, scorr_n, w_dq)
            acc_x -= _delta_pair_adjoint(-r, m, dp.grad[it, j], h, w_coef, g_coef, rho0, scorr_k, scorr_n, w_dq)
        x.grad[it, i] += acc_x
        lam.grad[it, i] += acc_l


@ti.kernel
def update_velocity(n: int, last: int, dt: float, p: ti.template(), x: ti.template(), u_out: ti.template()):
    # u_t = (p_t - p_{t-1}) / dt   (Macklin & Mueller 2013, Algorithm 1)
    for i in range(n):
        u_out[i] = (x[last, i] - p[i]) / dt


# The force terms' neighbour-loop kernels (forces.py) take ``fast`` (compile time). fast=True sums into locals and
# writes once per particle: the forward pass, about 2x faster than per-pair atomic adds. fast=False accumulates
# every pair straight into the global field, the only form whose ti.ad adjoint is correct (a local carried across
# a dynamic loop breaks it); the tape runs ``kernel.grad`` of that form. Both compute the same sums (tests compare
# both to torch). They read p[i] inside the inner loop on purpose: a local hoisted out of a dynamic inner loop gets
# wrong adjoints in Taichi 1.7.4 (checked against finite differences).


@dataclass(frozen=True)
class StepContext:
    """What a force term's ``launch`` sees: the fields and constants of the current step, and the two ways to
    launch a differentiated kernel (``record``: any kernel; ``record_pairs``: a neighbour-loop kernel that takes the
    leading ``fast`` flag)."""

    n: int
    dt: float
    h: float
    w_coef: float
    g_coef: float
    rho0: float
    p: object
    u: object
    age: object
    smoke: object
    rho: object
    force: object
    theta: object
    nbr: object
    count: object
    workspace: dict
    record: Callable
    record_pairs: Callable


class PBFSimulator:
    """Fields, tables and tape of one differentiable PBF step for up to ``capacity`` particles.

    Usage: :meth:`load` a state (p, u, age) and the model parameters, :meth:`forward`, read the result with
    :meth:`result`; for gradients, :meth:`backward` with the gradients of the outputs. Memory: about
    ``2 * capacity * (3 * (iterations + 1) + 9 * iterations + 14)`` reals (values and gradients), plus the two
    neighbour tables (``capacity * width`` int32 each); see docs/simulator.md.

    Args:
        capacity: most physical particles.
        solver: solver constants.
        model: external terms and their parameters.
        width: initial neighbour-table width (grows on demand).
    """

    def __init__(self, capacity: int, solver: SolverConfig = SolverConfig(), model: ModelConfig | None = None,
                 width: int = 48):
        self.capacity = int(capacity)
        self.solver = solver
        self.model = model if model is not None else ModelConfig.scalarflow()
        self.n = 0
        cap, its, f = self.capacity, max(solver.iterations, 1), real()
        vec = lambda *shape: ti.Vector.field(3, f, shape=shape, needs_grad=True)  # noqa: E731
        sca = lambda *shape: ti.field(f, shape=shape, needs_grad=True)  # noqa: E731
        self.p, self.u, self.u_out, self.force = vec(cap), vec(cap), vec(cap), vec(cap)
        self.rho_pre = sca(cap)
        self.age = ti.field(f, shape=cap)
        self.smoke = ti.field(f, shape=cap)
        self.volume = ti.field(f, shape=cap)
        self.x = vec(solver.iterations + 1, cap)
        self.rho, self.gsq, self.lam = sca(its, cap), sca(its, cap), sca(its, cap)
        self.gsum, self.dp = vec(its, cap), vec(its, cap)
        self.pre_table = NeighborTable(cap, width=width)
        self.solve_table = NeighborTable(cap, width=width)
        self._grad_fields = [self.p, self.u, self.u_out, self.force, self.rho_pre, self.x, self.rho, self.gsq,
                             self.lam, self.gsum, self.dp]
        self._workspaces: dict = {}
        self._thetas: dict = {}  # parameter count -> its field (set_model)
        self.set_model(self.model)
        self._tape: list = []
        self.token = None
        self.obstacle = None

    # ------------------------------------------------------------------ state
    def set_obstacle(self, obstacle) -> None:
        """A rigid body (``engine.obstacle``) the particles cannot enter, or None.

        With an obstacle every point inside the body moves to its surface after the prediction and after each
        constraint iteration (one-way coupling, FluidNexus Sec. 4.2); such a step has no :meth:`backward`.
        """
        self.obstacle = obstacle
        self.token = None

    def set_model(self, model: ModelConfig) -> None:
        """Use ``model`` (terms and parameter values) from the next step on. The particles' fields and tables stay,
        and one parameter field is kept per parameter count, so a model of other terms compiles only its terms'
        kernels once, and the kernels it shares with the models before it are not compiled again."""
        self.model = model
        self._offsets = model.offsets()
        size = max(1, len(model.param_names()))
        if size not in self._thetas:
            self._thetas[size] = ti.field(real(), shape=size, needs_grad=True)
        self.theta = self._thetas[size]
        self.load_theta(model.to_vector())
        for term in model.terms:
            for name, dims in term.workspace:
                key = (term.kind, name)
                if key not in self._workspaces:
                    self._workspaces[key] = ti.Vector.field(dims, real(), shape=self.capacity, needs_grad=True)

    def _active_workspaces(self) -> list:
        """The workspace fields of the model's terms (those of earlier models' terms stay, unused)."""
        return [self._workspaces[(t.kind, name)] for t in self.model.terms for name, _ in t.workspace]

    def load_theta(self, theta) -> None:
        """Set the model parameters from a vector [P] in the layout of ``model.param_names()``."""
        t = tensors.as_tensor(torch.as_tensor(theta).reshape(-1, 1))
        if t.shape[0] != len(self.model.param_names()):
            raise ValueError(f"theta has {t.shape[0]} entries, model expects {len(self.model.param_names())}")
        tensors.load(self.theta, t)

    def load(self, p, u, age=None, smoke=None, volume=None) -> None:
        """Set the start-of-step state: positions p [N, 3] m, velocities u [N, 3] m/s, ages [N] s (default 0),
        smoke weights [N] (default 1: every particle is smoke; 0 marks ambient air, which buoyancy skips), rest
        volumes [N] (default 1, a particle's own; the entrainment term grows them, engine/entrainment.py: a
        particle of volume v rests at rho0 / v, and buoyancy acts on its smoke concentration smoke / v)."""
        p, u = tensors.as_tensor(p, 3), tensors.as_tensor(u, 3)
        if p.shape != u.shape:
            raise ValueError(f"p {tuple(p.shape)} and u {tuple(u.shape)} differ")
        if p.shape[0] > self.capacity:
            raise ValueError(f"{p.shape[0]} particles exceed the capacity {self.capacity}")
        self.n = p.shape[0]
        tensors.load(self.p, p)
        tensors.load(self.u, u)
        columns = {}
        for name, values, default in (("age", age, 0.0), ("smoke", smoke, 1.0), ("volume", volume, 1.0)):
            values = torch.full((self.n,), default) if values is None else torch.as_tensor(values).reshape(-1)
            if values.shape[0] != self.n:
                raise ValueError(f"{values.shape[0]} {name} values for {self.n} particles")
            columns[name] = values
        if volume is not None:
            columns["smoke"] = columns["smoke"] / columns["volume"]
        for field, name in ((self.age, "age"), (self.smoke, "smoke"), (self.volume, "volume")):
            tensors.load(field, tensors.as_tensor(columns[name].reshape(-1, 1)))
        self.token = None

    # ------------------------------------------------------------------ step
    def _record(self, kernel, *args, adjoint=None) -> None:
        """Launch a differentiated kernel and put its reverse on the tape: ``adjoint`` (a hand-written reverse
        kernel taking the same arguments) or else ``kernel.grad``."""
        kernel(*args)
        self._tape.append((adjoint if adjoint is not None else kernel.grad, args))

    def _record_pairs(self, kernel, *args) -> None:
        """Launch a neighbour-loop kernel in its fast form and put the ``ti.ad`` reverse of its per-pair form on the
        tape (the comment above ``StepContext``)."""
        kernel(True, *args)
        self._tape.append((kernel.grad, (False,) + args))

    def forward(self) -> None:
        """Run one step on the loaded state, recording the reverse of its differentiated kernels for
        :meth:`backward`."""
        s, n = self.solver, self.n
        h, wc, gc = s.h, poly6_coef(s.h), spiky_coef(s.h)
        w0 = wc * h**6
        self._tape = []
        for f in [self.force] + self._active_workspaces():
            f.fill(0)
        self.rho_pre.fill(w0)
        if any(t.needs_neighbors for t in self.model.terms):
            self.pre_table.build(self.p, n, h)
            self._record(accumulate_density, n, h, wc, self.p, self.pre_table.nbr, self.pre_table.count,
                         self.rho_pre, adjoint=density_adjoint)
        for term, off in zip(self.model.terms, self._offsets):
            ctx = StepContext(n=n, dt=s.dt, h=h, w_coef=wc, g_coef=gc, rho0=s.rest_density, p=self.p, u=self.u,
                              age=self.age, smoke=self.smoke, rho=self.rho_pre, force=self.force, theta=self.theta,
                              nbr=self.pre_table.nbr, count=self.pre_table.count,
                              workspace={name: self._workspaces[(term.kind, name)] for name, _ in term.workspace},
                              record=self._record, record_pairs=self._record_pairs)
            term.launch(ctx, off)
        self._record(predict, n, s.dt, self.p, self.u, self.force, self.x)
        if self.obstacle is not None:
            self.obstacle.project(self.x, 0, n)
        if s.iterations:
            self.solve_table.build(self.x, n, h, src_row=0)
        nbr, cnt = self.solve_table.nbr, self.solve_table.count
        w_dq = wc * (h * h - (s.scorr_dq * h) ** 2) ** 3
        rho0, avg = s.rest_density, bool(s.averaging)
        for it in range(s.iterations):
            project_constraint(n, it, h, wc, gc, w0, rho0, s.eps, s.scorr_k, s.scorr_n, w_dq, avg, self.x, nbr, cnt,
                               self.rho, self.gsum, self.gsq, self.lam, self.dp, self.volume)
            self._tape += [
                (constraint_adjoint, (n, it, h, wc, gc, self.x, nbr, cnt, self.rho, self.gsum, self.gsq)),
                (compute_lambda.grad, (n, it, w0, rho0, s.eps, self.rho, self.gsum, self.gsq, self.lam,
                                       self.volume)),
                (delta_adjoint, (n, it, h, wc, gc, rho0, s.scorr_k, s.scorr_n, w_dq, self.x, nbr, cnt, self.lam,
                                 self.dp)),
                (apply_delta.grad, (n, it, avg, cnt, self.dp, self.x))]
            if self.obstacle is not None:  # one-way rigid coupling after each constraint iteration
                self.obstacle.project(self.x, it + 1, n)
        self._record(update_velocity, n, s.iterations, s.dt, self.p, self.x, self.u_out)
        self.token = object()

    def result(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(p_t [N, 3] m, u_t [N, 3] m/s) of the last :meth:`forward`."""
        return tensors.store(self.x, self.n, row=self.solver.iterations), tensors.store(self.u_out, self.n)

    def backward(self, grad_p, grad_u) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Reverse-mode ``ti.ad`` through the recorded step.

        Args:
            grad_p: dL/dp_t [N, 3]; grad_u: dL/du_t [N, 3] (either may be None for zero).

        Returns:
            (dL/dp_{t-1} [N, 3], dL/du_{t-1} [N, 3], dL/dtheta [P]).
        """
        if self.token is None:
            raise RuntimeError("backward() needs a forward() on the loaded state first")
        if self.obstacle is not None:
            raise RuntimeError("a step with an obstacle is not differentiated (set_obstacle(None) first)")
        for f in self._grad_fields + self._active_workspaces() + [self.theta]:
            f.grad.fill(0)
        zeros = torch.zeros((self.n, 3), dtype=tensors.torch_dtype())
        tensors.load(self.x.grad, zeros if grad_p is None else grad_p, row=self.solver.iterations)
        tensors.load(self.u_out.grad, zeros if grad_u is None else grad_u)
        for reverse, args in reversed(self._tape):
            reverse(*args)
        n_theta = len(self.model.param_names())
        return (tensors.store(self.p.grad, self.n), tensors.store(self.u.grad, self.n),
                tensors.store(self.theta.grad, n_theta).reshape(-1))


@ti.kernel
def _gather_state(n: int, pos: ti.template(), vel: ti.template(), age: ti.template(), smoke: ti.template(),
                  volume: ti.template(), p: ti.template(), u: ti.template(), age_out: ti.template(),
                  smoke_out: ti.template(), volume_out: ti.template()):
    for i in range(n):
        p[i] = pos[i]
        u[i] = vel[i]
        age_out[i] = age[i]
        smoke_out[i] = smoke[i] / volume[i]  # buoyancy acts on the concentration (PBFSimulator.load)
        volume_out[i] = volume[i]


@ti.kernel
def _scatter_state(n: int, last: int, dt: float, x: ti.template(), u_out: ti.template(), force: ti.template(),
                   pos: ti.template(), vel: ti.template(), frc: ti.template(), age: ti.template()):
    for i in range(n):
        pos[i] = x[last, i]
        vel[i] = u_out[i]
        frc[i] = force[i]
        age[i] += dt


def step_particles(sim: PBFSimulator, particles) -> None:
    """Advance a :class:`~fluidnexus.engine.particles.PhysicalParticles` set by one step in place (no tape use),
    then let the model's entrainment (if any) grow the particles' volumes and slow them (engine/entrainment.py)."""
    n = particles.n
    if n > sim.capacity:
        raise ValueError(f"{n} particles exceed the simulator capacity {sim.capacity}")
    f = particles.fields
    sim.n = n
    _gather_state(n, f["position"], f["velocity"], f["age"], f["smoke"], f["volume"], sim.p, sim.u, sim.age,
                  sim.smoke, sim.volume)
    sim.forward()
    _scatter_state(n, sim.solver.iterations, sim.solver.dt, sim.x, sim.u_out, sim.force, f["position"],
                   f["velocity"], f["force"], f["age"])
    if sim.model.entrainment is not None and n:
        u, volume = entrain(sim.model, particles.get("position"), particles.get("velocity"), particles.get("volume"),
                            sim.solver)
        particles.set("velocity", u)
        particles.set("volume", volume)
