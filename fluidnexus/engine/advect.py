"""Visual-particle advection x_t = Adv(V_t, x_{t-1}) (FluidNexus Sec. 3.2 and supp. "advection operators")."""
import torch

from .bridge import velocity_at
from .query import FieldQuery

ORDERS = (1, 2)


def advect(x: torch.Tensor, p: torch.Tensor, u: torch.Tensor, dt: float, query: FieldQuery,
           order: int = 1) -> torch.Tensor:
    """Move points x [M, 3] through the particle velocity field V(.|u, p) for one step dt [s].

    order 1: forward Euler x + dt V(x) (the paper). order 2: explicit midpoint
    x + dt V(x + dt/2 V(x)) (second order in dt for a frozen field). Differentiable w.r.t. x, p and u.
    A point with no particle within h does not move.
    """
    if order not in ORDERS:
        raise ValueError(f"advection order must be one of {ORDERS}, got {order}")
    if order == 1:
        return x + dt * velocity_at(x, p, u, query)
    mid = x + 0.5 * dt * velocity_at(x, p, u, query)
    return x + dt * velocity_at(mid, p, u, query)
