"""Steady-state metrics of one machine at one operating point, fixed-size and vmappable.

:func:`steady_state_metrics` returns the heald frame's metrics over the periodic steady cycle
(``deviation_max``, ``deviation_min``, ``deviation_pp`` [m], ``velocity_deviation_amp`` [m/s],
``acceleration_amp`` [m/s²]: peak-to-peak ranges as in :func:`jaxdobby.metrics.cycle_metrics`),
the relative periodicity residual, the number of cycles integrated and an ``ok`` flag, solving the
equations of :mod:`jaxdobby.dobby` (two-way coupling) with the collocation passes of
:mod:`jaxdobby.batch.stepper`. Every size is static — ``steps`` per cycle of phase-normalised
time (the same for every sample whatever its speed) and at most ``max_passes`` cycles — and
nothing raises at run time: a sample that does not converge, leaves the chain's workspace or
produces a non-finite metric has ``ok = False``.

**Periodic state.** Shooting on the period map F: the first cycle starts from the static
equilibrium at the middle of the bottom dwell (t = 0, where ω = α = 0) and carries the 2k
tangents of the frozen Newton matrices (with the chain's stiffness and damping), whose
monodromy matrix Φ gives the chord iteration x ← x + (I − Φ)⁻¹(F(x) − x) (as
:mod:`jaxdobby.steady_state`). The chord contracts by ~1e-3 per cycle (the frozen tangents'
error), so two or three further cycles — each also recording the metrics of its start state —
bring the residual ‖F(x) − x‖/‖x‖ (:func:`jaxdobby.steady_state.relative_residual`) below
``tolerance``; the metrics returned are those of that last cycle's start state x.

**Accuracy.** With the default 576 steps per cycle (8 per 1/72 of the cycle, so that the
modulator's dwell boundaries at 5/72, 31/72, 41/72, 67/72 of the cycle are step boundaries for
the default 100° dwell) the tests find the metrics within 1e-5 of the adaptive reference
:func:`jaxdobby.simulate.simulate` (``method="adaptive"``) at the corners of the default Sobol
box (400–1200 r/min, 345–1035 N, 80–140 mm, 6–8 mm).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jax import Array

from .._x64 import require_x64
from ..dobby import DobbyModel, build_model
from ..parameters import Setup
from ..steady_state import relative_residual
from . import collocation as gl
from .chain import downstream
from .cycle import arm_terms, node_phases, rigid_arm, tables_at
from .stepper import _residuals, cycle_pass

DEFAULT_STEPS = 576
"""Collocation steps per cycle (see the module docstring)."""

METRICS = ("deviation_pp", "deviation_max", "deviation_min", "velocity_deviation_amp",
           "acceleration_amp")
"""The metrics :func:`steady_state_metrics` returns (SI units), besides the status entries."""


def static_state(model: DobbyModel) -> Array:
    """x = (q, 0) at rest in the static equilibrium at t = 0 (bottom dwell), by Newton's method
    on the full residual (three iterations from q = 0; the chain is nearly linear there)."""
    arm, ds = arm_terms(model), downstream(model)
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


def steady_state_metrics(setup: Setup, *, steps: int = DEFAULT_STEPS, tolerance: float = 1e-7,
                         max_passes: int = 6) -> dict[str, Array]:
    """Metrics of the periodic steady cycle of ``setup`` (see the module docstring).

    Args:
        setup: machine and operating point (two-way coupling; any number of modes, either warp
            law). Vmappable over its float fields; jittable.
        steps: collocation steps per cycle (static).
        tolerance: relative periodicity residual to stop at and to call converged.
        max_passes: cycles after the first (static bound of the loop).

    Returns:
        A dict of scalars: :data:`METRICS`, ``periodicity`` (the residual), ``cycles``
        (integrated, int) and ``ok`` (bool).
    """
    require_x64()
    if setup.machine.coupling != "two-way":
        raise ValueError("the batch evaluator solves the two-way coupled model; got coupling="
                         f"{setup.machine.coupling!r} (use jaxdobby.simulate for one-way)")
    model = build_model(setup.machine, setup.operating)
    arm, ds = arm_terms(model), downstream(model)
    period = model.period
    tables = tables_at(arm, ds, rigid_arm(model, node_phases(steps)), period)
    k = model.n_modes
    eye = jnp.eye(2 * k)

    x0 = static_state(model)
    first = cycle_pass(arm, ds, tables, period, x0, tangents=eye, full_jacobian=True)
    lu = jsl.lu_factor(eye - first.tangents)
    x1 = x0 + jsl.lu_solve(lu, first.end - x0)

    def chord(carry):
        i, x, _, _ = carry
        run = cycle_pass(arm, ds, tables, period, x, outputs=True)
        r = relative_residual(x, run.end)
        return i + 1, x + jsl.lu_solve(lu, run.end - x), r, run

    def unconverged(carry):
        i, _, r, _ = carry
        return (i < max_passes) & (r > tolerance)

    nan3 = jnp.full(3, jnp.nan)
    start = (jnp.asarray(0), x1, jnp.asarray(jnp.inf),
             first._replace(tangents=jnp.zeros((2 * k, 0)), maxima=nan3, minima=nan3))
    passes, _, residual, last = jax.lax.while_loop(unconverged, chord, start)
    hi, lo = last.maxima, last.minima
    out = {
        "deviation_pp": hi[0] - lo[0],
        "deviation_max": hi[0],
        "deviation_min": lo[0],
        "velocity_deviation_amp": hi[1] - lo[1],
        "acceleration_amp": hi[2] - lo[2],
    }
    finite = jnp.all(jnp.stack([jnp.isfinite(v) for v in out.values()]))
    out["periodicity"] = residual
    out["cycles"] = passes + 1
    out["ok"] = finite & last.reachable & (residual <= tolerance)
    return out
