"""External terms of the PBF gas step: each a frozen dataclass with its parameters and its kernels.

A term adds an acceleration [m/s^2] into the step's force accumulator before prediction
(FluidNexus Eq. S1: u_hat = u + dt alpha g + dt f). Every term is evaluated at the start-of-step state
(p_{t-1}, u_{t-1}). Differentiable parameters are listed in ``params`` (a float or a 3-vector each); they
live in one flat parameter field ``theta`` so that ``ti.ad`` gradients reach them. To add a term, write a
dataclass here with ``kind``, ``params``, ``needs_neighbors``, ``workspace`` and ``launch`` and decorate it
with :func:`register_term`; nothing else changes.
"""

from dataclasses import dataclass
from typing import ClassVar

import taichi as ti

from .sph import TINY, poly6, spiky_grad

TERMS: dict[str, type] = {}


def register_term(cls):
    """Class decorator: make a term available to :class:`fluidnexus.engine.model.ModelConfig` by ``kind``."""
    TERMS[cls.kind] = cls
    return cls


@ti.func
def _vec(theta: ti.template(), off):
    return ti.Vector([theta[off], theta[off + 1], theta[off + 2]])


# Neighbour loops take the ``fast`` flag (launched through ``ctx.record_pairs``) and read p[i], u[i] inside the
# inner loop on purpose; pbf.py explains both.


# ---------------------------------------------------------------- buoyancy
@ti.kernel
def add_buoyancy(n: int, off: int, gx: float, gy: float, gz: float, age: ti.template(), smoke: ti.template(),
                 theta: ti.template(), force: ti.template()):
    # FluidNexus Eq. S1 buoyancy alpha g, optionally decaying with particle age: alpha exp(-decay age) g, on smoke
    # only (smoke weight 1; 0 on the air particles of the ambient-air structure, engine/ambient.py)
    for i in range(n):
        a = theta[off] * ti.exp(-theta[off + 1] * age[i]) * smoke[i]
        force[i] += a * ti.Vector([gx, gy, gz])


@register_term
@dataclass(frozen=True)
class Buoyancy:
    """Buoyancy alpha exp(-decay age) g (FluidNexus Eq. S1; decay = 0 is the paper's constant term), times each
    particle's smoke weight (1 for every particle of the paper's gas, 0 for ambient air).

    Attributes:
        alpha: buoyancy coefficient (dimensionless, < 0 rises). The release's ScalarFlow -3 (FluidNexus sets -6)
            multiplies g = 9.8 in its x100 space, i.e. 9.8 cm/s^2; with g in m/s^2 the same acceleration is
            alpha = -0.03 (-0.06): 0.29 m/s^2 upward.
        decay: decay rate of buoyancy with particle age [1/s]; 0 disables the decay.
        gravity: g [m/s^2] (not fitted).
    """

    alpha: float = -0.03
    decay: float = 0.0
    gravity: tuple = (0.0, -9.8, 0.0)
    kind: ClassVar[str] = "buoyancy"
    params: ClassVar[tuple] = ("alpha", "decay")
    needs_neighbors: ClassVar[bool] = False
    workspace: ClassVar[tuple] = ()

    def launch(self, ctx, off: int) -> None:
        ctx.record(add_buoyancy, ctx.n, off, *self.gravity, ctx.age, ctx.smoke, ctx.theta, ctx.force)


# ---------------------------------------------------------------- drag
@ti.kernel
def add_drag(n: int, off: int, rho0: float, u: ti.template(), rho: ti.template(), theta: ti.template(),
             force: ti.template()):
    # FluidNexus Eq. S4: f_i = -k (v_i - v_env) max(0, 1 - rho_i / rho0)
    for i in range(n):
        w = ti.max(0.0, 1.0 - rho[i] / rho0)
        force[i] += -theta[off] * w * (u[i] - _vec(theta, off + 1))


@register_term
@dataclass(frozen=True)
class Drag:
    """Density-weighted drag towards the ambient air velocity (FluidNexus Eq. S4).

    Attributes:
        k: drag coefficient [1/s]; 3 in the paper.
        v_env: ambient air velocity v_env [m/s]; (0, 0, 0) is still air.
    """

    k: float = 3.0
    v_env: tuple = (0.0, 0.0, 0.0)
    kind: ClassVar[str] = "drag"
    params: ClassVar[tuple] = ("k", "v_env")
    needs_neighbors: ClassVar[bool] = True
    workspace: ClassVar[tuple] = ()

    def launch(self, ctx, off: int) -> None:
        ctx.record(add_drag, ctx.n, off, ctx.rho0, ctx.u, ctx.rho, ctx.theta, ctx.force)


# ---------------------------------------------------------------- wind
WIND_PROFILES = ("constant", "ramp", "exp")


@ti.kernel
def add_wind(n: int, off: int, profile: ti.template(), y0: float, height: float, p: ti.template(),
             theta: ti.template(), force: ti.template()):
    # wind acceleration a * phi(y); paper supp. "exponentially increasing" with height, release: a ramp in y
    for i in range(n):
        s = (p[i][1] - y0) / height
        phi = 1.0
        if ti.static(profile == 1):
            phi = ti.math.clamp(s, 0.0, 1.0)
        if ti.static(profile == 2):
            phi = ti.exp(s)
        force[i] += phi * _vec(theta, off)


@register_term
@dataclass(frozen=True)
class Wind:
    """Wind acceleration ``accel * phi(y)`` [m/s^2].

    Attributes:
        accel: full-strength wind acceleration [m/s^2].
        profile: "constant" (phi = 1), "ramp" (phi = clamp((y - y0) / height, 0, 1), the release's profile),
            or "exp" (phi = exp((y - y0) / height), the paper's exponential growth with height).
        y0: reference height [m].
        height: ramp length or e-folding height [m].
    """

    accel: tuple = (0.35, 0.0, 0.0)
    profile: str = "constant"
    y0: float = 0.0
    height: float = 0.01
    kind: ClassVar[str] = "wind"
    params: ClassVar[tuple] = ("accel",)
    needs_neighbors: ClassVar[bool] = False
    workspace: ClassVar[tuple] = ()

    def __post_init__(self):
        if self.profile not in WIND_PROFILES:
            raise ValueError(f"wind profile must be one of {WIND_PROFILES}, got {self.profile!r}")
        if self.height <= 0:
            raise ValueError(f"wind height must be > 0, got {self.height}")

    def launch(self, ctx, off: int) -> None:
        ctx.record(add_wind, ctx.n, off, WIND_PROFILES.index(self.profile), self.y0, self.height, ctx.p,
                   ctx.theta, ctx.force)


# ---------------------------------------------------------------- vorticity confinement
@ti.kernel
def accumulate_curl(fast: ti.template(), n: int, h: float, g_coef: float, p: ti.template(), u: ti.template(),
                    rho: ti.template(),
                    nbr: ti.template(), count: ti.template(), omega: ti.template()):
    # omega_i = sum_j (1 / rho_j) grad_i W_ij x (u_j - u_i)   (Macklin & Mueller 2013, Eq. 15, SPH volumes)
    for i in range(n):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            c = spiky_grad(p[i] - p[j], h, g_coef).cross(u[j] - u[i]) / rho[j]
            if ti.static(fast):
                acc += c
            else:
                omega[i] += c
        if ti.static(fast):
            omega[i] += acc


@ti.kernel
def accumulate_curl_gradient(fast: ti.template(), n: int, h: float, g_coef: float, p: ti.template(), rho: ti.template(),
                             nbr: ti.template(), count: ti.template(), omega: ti.template(), eta: ti.template()):
    # eta_i = grad |omega| at i = sum_j (1 / rho_j) (|omega_j| - |omega_i|) grad_i W_ij
    for i in range(n):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            da = ti.sqrt(omega[j].norm_sqr() + TINY) - ti.sqrt(omega[i].norm_sqr() + TINY)
            c = da / rho[j] * spiky_grad(p[i] - p[j], h, g_coef)
            if ti.static(fast):
                acc += c
            else:
                eta[i] += c
        if ti.static(fast):
            eta[i] += acc


@ti.kernel
def add_vorticity_force(n: int, off: int, omega: ti.template(), eta: ti.template(), theta: ti.template(),
                        force: ti.template()):
    # f_i = epsilon (N x omega_i), N = eta / |eta|   (Macklin & Mueller 2013, Eq. 16)
    for i in range(n):
        nrm = eta[i] / ti.sqrt(eta[i].norm_sqr() + TINY)
        force[i] += theta[off] * nrm.cross(omega[i])


@register_term
@dataclass(frozen=True)
class Vorticity:
    """Vorticity confinement (Macklin & Mueller 2013, section 6).

    Attributes:
        epsilon: confinement strength [m/s] (acceleration per unit vorticity).
    """

    epsilon: float = 0.01
    kind: ClassVar[str] = "vorticity"
    params: ClassVar[tuple] = ("epsilon",)
    needs_neighbors: ClassVar[bool] = True
    workspace: ClassVar[tuple] = (("omega", 3), ("eta", 3))

    def launch(self, ctx, off: int) -> None:
        ws = ctx.workspace
        ctx.record_pairs(accumulate_curl, ctx.n, ctx.h, ctx.g_coef, ctx.p, ctx.u, ctx.rho, ctx.nbr, ctx.count,
                         ws["omega"])
        ctx.record_pairs(accumulate_curl_gradient, ctx.n, ctx.h, ctx.g_coef, ctx.p, ctx.rho, ctx.nbr, ctx.count,
                         ws["omega"], ws["eta"])
        ctx.record(add_vorticity_force, ctx.n, off, ws["omega"], ws["eta"], ctx.theta, ctx.force)


# ---------------------------------------------------------------- XSPH viscosity
@ti.kernel
def accumulate_velocity_smoothing(fast: ti.template(), n: int, h: float, w_coef: float, p: ti.template(),
                                  u: ti.template(),
                                  rho: ti.template(), nbr: ti.template(), count: ti.template(),
                                  smooth: ti.template()):
    # sum_j (1 / rho_j) (u_j - u_i) W_ij   (Macklin & Mueller 2013, Eq. 17, SPH volumes)
    for i in range(n):
        acc = ti.Vector([0.0, 0.0, 0.0])
        for k in range(count[i]):
            j = nbr[i, k]
            c = poly6((p[i] - p[j]).norm_sqr(), h, w_coef) / rho[j] * (u[j] - u[i])
            if ti.static(fast):
                acc += c
            else:
                smooth[i] += c
        if ti.static(fast):
            smooth[i] += acc


@ti.kernel
def add_viscosity_force(n: int, off: int, dt: float, smooth: ti.template(), theta: ti.template(),
                        force: ti.template()):
    # XSPH u_i += c sum_j ..., applied as the acceleration (c / dt) sum_j ... in the prediction
    for i in range(n):
        force[i] += theta[off] / dt * smooth[i]


@register_term
@dataclass(frozen=True)
class Viscosity:
    """XSPH viscosity (Macklin & Mueller 2013, Eq. 17) as a velocity smoothing applied in the prediction.

    Attributes:
        c: smoothing fraction per step (dimensionless, 0..1).
    """

    c: float = 0.01
    kind: ClassVar[str] = "viscosity"
    params: ClassVar[tuple] = ("c",)
    needs_neighbors: ClassVar[bool] = True
    workspace: ClassVar[tuple] = (("smooth", 3),)

    def launch(self, ctx, off: int) -> None:
        ws = ctx.workspace
        ctx.record_pairs(accumulate_velocity_smoothing, ctx.n, ctx.h, ctx.w_coef, ctx.p, ctx.u, ctx.rho, ctx.nbr,
                         ctx.count, ws["smooth"])
        ctx.record(add_viscosity_force, ctx.n, off, ctx.dt, ws["smooth"], ctx.theta, ctx.force)
