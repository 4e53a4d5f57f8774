"""The periodic steady cycle of one machine by collocation, as time series.

The fast path of :func:`jaxdobby.simulate.simulate` (``method="collocation"``): the equations of
the batch evaluator (:mod:`jaxdobby.batch.cycle`, :mod:`jaxdobby.batch.stepper`: the two-way
coupled model, three-stage Gauss collocation on a phase-normalised grid, the chain in closed
form) with

* the periodic state by Newton–chord shooting (the chord matrix from the frozen Newton
  matrices' tangents, as the batch evaluator) and the implicit-function derivative of :func:`jaxdobby.steady_state.periodic_state` (so gradients
  through a run follow dx₀/dp = (I − F_x)⁻¹ F_p, not the iterations), started from the static
  equilibrium at t = 0;
* the steady cycle as the collocation polynomial (:func:`jaxdobby.batch.collocation.dense_weights`)
  sampled ``per_step`` times per step, uniformly in time, plus the end point t = T.

The collocation solution is accurate to O(h⁴) between the step boundaries (the stage order) and
O(h⁶) at them; with the default 432 steps per cycle its metrics agree with the adaptive reference
to ~3e-5 (:mod:`jaxdobby.batch.steady`; the tests compare this path too).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..dobby import DobbyModel
from ..steady_state import ShootingResult, periodic_state
from . import collocation as gl
from .chain import Downstream, chain_reachable
from .collocation import MATRIX2, NODES, dense_weights
from .cycle import ArmTerms, rigid_arm, tables_at
from .steady import cycle_of
from .stepper import _residuals, cycle_pass

PER_STEP = 4
"""Output times per collocation step (uniform in time)."""


def static_state(model: DobbyModel, arm: ArmTerms, ds: Downstream) -> Array:
    """x = (q, 0) at rest in the static equilibrium at t = 0 (bottom dwell), by Newton's method
    on the full residual (three iterations from q = 0; the chain is nearly linear there).
    ``arm``, ``ds``: ``model``'s :func:`~jaxdobby.batch.cycle.arm_terms` and
    :func:`~jaxdobby.batch.chain.downstream`."""
    table = tables_at(arm, ds, rigid_arm(model, jnp.zeros(1)), model.period)
    k = model.n_modes
    zero = jnp.zeros((1, k))

    def residual(q):
        return _residuals(arm, ds, table, q[None], zero, zero)[0][0]

    q = jnp.zeros(k)
    for _ in range(3):
        jac = jax.jacfwd(residual)(q)
        q = q - gl.lu_solve(gl.lu(jac), residual(q))
    return jnp.concatenate([q, jnp.zeros(k)])


class DenseCycle(eqx.Module):
    """The steady cycle of :func:`steady_cycle`.

    Attributes:
        time: output times t [s], shape (n,), 0 … T uniformly (n = steps·per_step + 1).
        q, qdot: modal coordinates and rates there, shape (n, k).
        shooting: the periodic state's shooting result.
        end: the state after the saved cycle, (2k,) (for the periodicity check).
        reachable: the chain closed at every collocation node of the saved cycle.
    """

    time: Array
    q: Array
    qdot: Array
    shooting: ShootingResult
    end: Array
    reachable: Array


def steady_cycle(model: DobbyModel, steps: int, *, tolerance=1e-6, per_step: int = PER_STEP,
                 max_iterations: int = 8) -> DenseCycle:
    """Periodic steady cycle of ``model`` by collocation (see the module docstring).

    Args:
        model: the coupled model (two-way coupling).
        steps: collocation steps per cycle (static).
        tolerance: relative periodicity to stop the shooting at.
        per_step: output times per step (static).
        max_iterations: shooting iterations at most (static).
    """
    if model.machine.coupling != "two-way":
        raise ValueError("the collocation path solves the two-way coupled model; got coupling="
                         f"{model.machine.coupling!r} (use method='rk4' or 'adaptive')")
    cycle = cycle_of(model, steps)
    arm, ds, tables, period = cycle.arm, cycle.downstream, cycle.tables, cycle.period

    def period_map(x):
        return cycle_pass(arm, ds, tables, period, x).end

    def linearised(x):
        # the frozen Newton matrices' tangents (as the batch evaluator): ~1e-3 from the exact
        # monodromy matrix, at a seventh of the cost of 2k forward-mode tangents
        run = cycle_pass(arm, ds, tables, period, x, tangents=jnp.eye(x.shape[0]),
                         full_jacobian=True)
        return run.end, run.tangents

    rest = static_state(model, arm, ds)
    shooting = periodic_state(period_map, rest, tolerance=tolerance,
                              max_iterations=max_iterations, linearised=linearised)
    run = cycle_pass(arm, ds, tables, period, shooting.state, record=True)
    q, v, acc = run.trajectory
    h = period / steps
    theta = np.arange(per_step) / per_step
    w1, w2 = (jnp.asarray(w) for w in dense_weights(theta))
    k = q.shape[1]
    qs = (q[:, None] + (h * jnp.asarray(theta))[None, :, None] * v[:, None]
          + h**2 * jnp.einsum("jm,nmk->njk", w2, acc)).reshape(-1, k)
    vs = (v[:, None] + h * jnp.einsum("jm,nmk->njk", w1, acc)).reshape(-1, k)
    t = (h * (jnp.arange(steps)[:, None] + jnp.asarray(theta)[None])).reshape(-1)
    # the chain must close at every collocation node (stage positions Qᵢ of every step)
    stage_q = q[:, None] + h * jnp.asarray(NODES)[None, :, None] * v[:, None] \
        + h**2 * jnp.einsum("im,nmk->nik", jnp.asarray(MATRIX2), acc)
    frames = jax.tree.map(lambda a: a.reshape(-1), tables.frame)
    reach = jax.vmap(chain_reachable, in_axes=(None, 0, 0))(
        ds, frames, stage_q.reshape(-1, k) @ ds.rows.T)
    return DenseCycle(time=jnp.concatenate([t, period[None]]),
                      q=jnp.concatenate([qs, run.end[None, :k]]),
                      qdot=jnp.concatenate([vs, run.end[None, k:]]),
                      shooting=shooting, end=run.end, reachable=jnp.all(reach))
