"""A frame that never moves: the static case of a lift plan ("1", "0", "11", "0000"…).

With every b_k equal, the eccentric never turns (DESIGN.md §7: it turns in pick k iff
b_k ≠ b_{k−1}): the frame rests at the top (b = 1) or bottom (b = 0) of its stroke for the whole
repeat, the rigid mechanism stands still (ω = α = 0) and the periodic steady state of the damped
equations of :mod:`jaxdobby.dobby` is their static equilibrium, reached without dynamics:

    F(q) = 0,  F the generalised forces of :func:`jaxdobby.dobby.equations_at` at q̇ = 0

(the arm's elastic stiffness and geometric stiffness, its weight, the ring link, and through
link 11 the downstream chain's weight and the warp force, ±F_w at the extremes for the
restoring law), solved by Newton's method with the forward-mode Jacobian. The deviation of the
heald frame is then the constant static deflection G(q_eq) − G(0) [m] at that dwell position:
its min = max = the deflection, its peak-to-peak, every dwell vibration, the velocity and
acceleration deviations and the rigid acceleration are exactly zero; the link forces are the
static ones. :func:`static_cycle` returns the series over the repeat on the collocation path's
output grid, so the run's metrics, per-pick metrics, stress and report are computed from it
by the same code as for a moving frame.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from ..dobby import DobbyModel, equations_at, rigid_state
from ..outputs import flexible_outputs
from ..steady_state import ShootingResult

NEWTON_ITERATIONS = 12
"""Newton steps on F(q) = 0 (the equations are nearly linear in q: measured on the default
machine, the step falls below 1e-14 of q after 3)."""


def static_equilibrium(model: DobbyModel, t=0.0, tolerance=1e-10) -> ShootingResult:
    """The static equilibrium (q_eq, 0) of ``model`` at time ``t`` [s] of a dwell.

    Returns a :class:`~jaxdobby.steady_state.ShootingResult` (the run's record of its steady
    state): ``state`` (q_eq, 0) (2k,), ``residual`` the last Newton step relative to
    ‖q_eq‖∞, ``iterations`` :data:`NEWTON_ITERATIONS`, ``converged`` residual ≤ tolerance.
    Differentiable in every float parameter (through the fixed Newton iterations).
    """
    k = model.n_modes
    rigid = rigid_state(model, jnp.asarray(t, dtype=float))
    rest = jnp.zeros(k)

    def force(q):
        return equations_at(model, rigid, q, rest)[1]

    def newton(_, carry):
        q, _ = carry
        step = jnp.linalg.solve(jax.jacfwd(force)(q), force(q))
        return q - step, step

    q, step = jax.lax.fori_loop(0, NEWTON_ITERATIONS, newton, (rest, rest))
    residual = jnp.max(jnp.abs(step)) / (jnp.max(jnp.abs(q)) + jnp.finfo(q.dtype).tiny)
    return ShootingResult(state=jnp.concatenate([q, rest]), residual=residual,
                          iterations=jnp.asarray(NEWTON_ITERATIONS),
                          converged=residual <= tolerance)


def static_cycle(model: DobbyModel, samples: int, tolerance=1e-10
                 ) -> tuple[ShootingResult, dict[str, Array], Array]:
    """(equilibrium, flexible outputs, times) of a frame that never moves over the repeat:
    ``samples`` uniform times over [0, T] (T = ``model.period``), the outputs of
    :func:`jaxdobby.outputs.flexible_outputs` at (q_eq, 0) at each (constant in time)."""
    k = model.n_modes
    eq = static_equilibrium(model, 0.0, tolerance)
    ts = jnp.linspace(0.0, model.period, samples)

    def at(t):
        return flexible_outputs(model, rigid_state(model, t), eq.state[:k], eq.state[k:])

    return eq, jax.vmap(at)(ts), ts
