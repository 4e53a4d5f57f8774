"""Periodic steady state by shooting on the period.

A loom runs for hours, so the results that matter are the periodic steady state of the forced,
damped equations: the initial state x₀ = (q, q̇) that the period map F (one heald-frame cycle of
integration) returns unchanged, F(x₀) = x₀. The equations are nearly linear in the elastic
coordinates, so Newton's method on F(x) − x with the monodromy matrix ∂F/∂x (forward-mode
autodiff through the solve: one solve carrying 2k tangents) converges in one or two iterations,
where waiting for the start-up transient of the ~110 Hz frame-on-arm mode at 2 % damping to die
out would take ten or more cycles (Nayfeh & Balachandran, *Applied Nonlinear Dynamics*, §7.3).

The converged state is returned through ``jax.lax.custom_root``, so derivatives of anything
computed from it follow the implicit-function theorem, dx₀/dp = (I − F_x)⁻¹ F_p, rather than
the Newton iterations.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array


class ShootingResult(eqx.Module):
    """The periodic state found by :func:`periodic_state`.

    Attributes:
        state: x₀ = concatenated (q, q̇) at the start of the cycle, shape (2k,).
        residual: max over the q and q̇ blocks of ‖F(x) − x‖∞/‖x‖∞ at the last Newton iterate
            [-] (the state returned has had one more correction).
        iterations: period maps evaluated (the first with the monodromy matrix).
        converged: residual ≤ tolerance.
    """

    state: Array
    residual: Array
    iterations: Array
    converged: Array


def relative_residual(x: Array, fx: Array) -> Array:
    """max(‖Δq‖/‖q‖, ‖Δq̇‖/‖q̇‖) of F(x) − x, blockwise infinity norms (the two blocks differ in
    scale by the frequencies); x (2k, lanes...) gives one residual per lane."""
    k = x.shape[0] // 2
    r = fx - x

    def block(sl):
        return (jnp.max(jnp.abs(r[sl]), axis=0)
                / (jnp.max(jnp.abs(fx[sl]), axis=0) + jnp.finfo(x.dtype).tiny))

    return jnp.maximum(block(slice(0, k)), block(slice(k, None)))


def _newton(period_map: Callable[[Array], Array], x0: Array, tolerance, max_iterations: int,
            linearised: Callable[[Array], tuple[Array, Array]] | None = None):
    """Newton–chord iterations: the monodromy matrix is computed once, at the starting guess
    (one solve carrying 2k tangents), and reused; each further iteration costs one plain
    solve. The equations are nearly linear in the elastic state, so the chord method converges
    about as fast as full Newton here (each iteration gains the ratio of the nonlinear part,
    ~1e-3) at a fraction of the cost. ``linearised(x0)`` may supply (F(x0), an approximate
    monodromy matrix) instead (the chord method only needs an approximation)."""
    n = x0.shape[0]
    eye = jnp.eye(n, dtype=x0.dtype)
    if linearised is None:
        # All 2k tangents ride through one solve as a batch (cheaper here than
        # jax.linearize, which stores the primal trace and replays it).
        values, columns = jax.vmap(lambda v: jax.jvp(period_map, (x0,), (v,)))(eye)
        fx, monodromy = values[0], columns.T
    else:
        fx, monodromy = linearised(x0)
    lu = jax.scipy.linalg.lu_factor(eye - monodromy)
    x1 = x0 + jax.scipy.linalg.lu_solve(lu, fx - x0)

    def step(carry):
        i, x, _ = carry
        fx = period_map(x)
        return i + 1, x + jax.scipy.linalg.lu_solve(lu, fx - x), relative_residual(x, fx)

    def keep_going(carry):
        i, _, residual = carry
        return (i < max_iterations) & (residual > tolerance)

    return jax.lax.while_loop(keep_going, step, (1, x1, relative_residual(x0, fx)))


def periodic_state(period_map: Callable[[Array], Array], x0: Array, *, tolerance=1e-9,
                   max_iterations: int = 8,
                   linearised: Callable[[Array], tuple[Array, Array]] | None = None
                   ) -> ShootingResult:
    """Solve F(x) = x by the Newton–chord method with the monodromy matrix at ``x0``.

    Args:
        period_map: x ↦ F(x), the state after one period; must support forward-mode autodiff
            (for a diffrax solve: ``adjoint=diffrax.ForwardMode()``).
        x0: starting guess (e.g. zeros: the mechanism at rest in its rigid motion).
        tolerance: relative residual (see :func:`relative_residual`) to stop at.
        max_iterations: Newton iterations at most (static).
        linearised: optional x ↦ (F(x), Φ̃) with Φ̃ an approximation of the monodromy matrix
            ∂F/∂x, used by the chord iterations instead of the exact one (cheaper; the root and
            its derivatives do not depend on it, only the number of iterations does).
    """
    iterations, root, residual = jax.lax.stop_gradient(
        _newton(period_map, jax.lax.stop_gradient(x0), tolerance, max_iterations, linearised))
    return ShootingResult(state=attach_root_derivative(period_map, root), residual=residual,
                          iterations=iterations, converged=residual <= tolerance)


def attach_root_derivative(period_map: Callable[[Array], Array], root: Array) -> Array:
    """``root``, a periodic state F(x) = x found already, with the implicit-function derivative
    dx/dp = (I − F_x)⁻¹ F_p attached (``jax.lax.custom_root``, whose solve returns the guess
    unchanged): derivatives of anything computed from it follow the root, not the iterations
    that found it. ``period_map`` (closing over the parameters) is traced only when
    differentiating."""
    n = root.shape[0]

    def tangent_solve(g, y):
        jac = jax.vmap(g, in_axes=1, out_axes=1)(jnp.eye(n, dtype=y.dtype))
        return jnp.linalg.solve(jac, y)

    return jax.lax.custom_root(lambda x: period_map(x) - x, root, lambda f, guess: guess,
                               tangent_solve)
