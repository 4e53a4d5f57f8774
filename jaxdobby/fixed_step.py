"""Fixed-step integration of one cycle with the rigid mechanism tabulated in advance.

Everything in the coupled equations that depends on time alone — the arm's angle and rates, the
ring link's direction, the link-11 force of rigid inverse dynamics (:class:`RigidState`) — is
evaluated once, vectorised over the half-step grid t = 0, Δt/2, Δt, …, T, and the classical
fourth-order Runge–Kutta method then marches the elastic state with ``lax.scan``, its stages
reading the table (stages sit at t, t + Δt/2, t + Δt). This is the fast path of
:func:`jaxdobby.simulate.simulate`; the adaptive Tsit5 solve is the reference it is tested against.

Step size: RK4 is stable for |ω|Δt < 2.78 on an undamped oscillator; at |ω|Δt = 1.5 for the
highest mode kept the elastic state agrees with the adaptive reference (rtol 1e-8) to ~1e-8 of
its amplitude, so :func:`steps_per_cycle` picks Δt = 1.5/ω_max.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from jax import Array

from .dobby import DobbyModel, RigidState, equations_at, rigid_state

STABILITY_MARGIN = 1.5
"""ω_max·Δt used to choose the step (RK4's stability limit on the imaginary axis is 2.83)."""


def steps_per_cycle(highest_frequency_hz: float, period: float, multiple: int = 100) -> int:
    """Number of RK4 steps per cycle for a highest natural frequency [Hz] and period [s].

    A concrete (Python) number: it sets the length of the scan, a static size.
    """
    n = period * 2.0 * math.pi * highest_frequency_hz / STABILITY_MARGIN
    return int(multiple * math.ceil(n / multiple))


def rigid_table(model: DobbyModel, n_steps: int) -> RigidState:
    """:class:`RigidState` on the half-step grid, leading axis 2·n_steps + 1."""
    t = jnp.linspace(0.0, model.period, 2 * n_steps + 1)
    return jax.vmap(lambda tt: rigid_state(model, tt))(t)


def _rhs(model: DobbyModel, rigid: RigidState, x: Array) -> Array:
    k = model.n_modes
    mass, force = equations_at(model, rigid, x[:k], x[k:])
    return jnp.concatenate([x[k:], jnp.linalg.solve(mass, force)])


def rk4_cycle(model: DobbyModel, table: RigidState, x0: Array, save=None):
    """March the state x = (q, q̇) over one cycle with RK4 on the tabulated rigid states.

    Args:
        model: the coupled model.
        table: :func:`rigid_table` of the same number of steps.
        x0: state at t = 0, shape (2k,).
        save: optional ``save(model, rigid, x) -> pytree`` evaluated at the end of every step.

    Returns:
        ``(x_end, saved)``: the state at t = T and the stacked ``save`` outputs (or None).
    """
    n = (table.time.shape[0] - 1) // 2
    dt = model.period / n
    start = jax.tree.map(lambda a: a[0:2 * n:2], table)
    middle = jax.tree.map(lambda a: a[1:2 * n:2], table)
    end = jax.tree.map(lambda a: a[2::2], table)

    def step(x, rigid):
        a, b, c = rigid
        k1 = _rhs(model, a, x)
        k2 = _rhs(model, b, x + 0.5 * dt * k1)
        k3 = _rhs(model, b, x + 0.5 * dt * k2)
        k4 = _rhs(model, c, x + dt * k3)
        x_next = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return x_next, (None if save is None else save(model, c, x_next))

    return jax.lax.scan(step, x0, (start, middle, end))
