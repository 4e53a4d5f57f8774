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
``tolerance``; the metrics returned are those of that last cycle's start state x. Under
``jax.vmap`` the chord cycles run in rounds over the lanes still pending, so a batch does not
integrate its slowest lane's cycle count for every lane (:func:`_settle`).

**Accuracy.** With the default 432 steps per cycle (6 per 1/72 of the cycle, so that the
modulator's dwell boundaries at 5/72, 31/72, 41/72, 67/72 of the cycle are step boundaries for
the default 100° dwell) and periodicity tolerance 1e-5, every metric is within 3e-5 of the
adaptive reference :func:`jaxdobby.simulate.simulate` (``method="adaptive"``, rtol 1e-8) at
the 16 corners of the default Sobol box (400–1200 r/min, 345–1035 N, 80–140 mm, 6–8 mm; a slow
test). Measured there (largest relative error over the corners and the five metrics): 576
steps 2.2e-5, 432 steps 2.9e-5, 360 steps 8.3e-5, 288 steps 2.5e-4 (the velocity deviation's
amplitude goes first); with the parabola-refined extremes of :mod:`jaxdobby.batch.stepper`, 432
steps: 2.3e-5 on the velocity deviation's amplitude, ≤ 2.1e-6 on the other four (2026-12-01,
``benchmarks/sobol_throughput.py``). The shooting tolerance costs little accuracy: the metrics
are those of a start state within ~``tolerance`` of the periodic one, and on 256 random samples
1e-5 changed them by ≤ 7e-7 relative against 1e-7.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array
from jax.custom_batching import custom_vmap, sequential_vmap

from .._x64 import require_x64
from ..dobby import DobbyModel, build_model
from ..parameters import Setup
from ..steady_state import relative_residual
from . import collocation as gl
from .chain import Downstream, downstream
from .cycle import ArmTerms, StageTables, arm_terms, node_phases, rigid_arm, tables_at
from .stepper import _residuals, cycle_pass

DEFAULT_STEPS = 432
"""Collocation steps per cycle (see the module docstring)."""

METRICS = ("deviation_pp", "deviation_max", "deviation_min", "velocity_deviation_amp",
           "acceleration_amp")
"""The metrics :func:`steady_state_metrics` returns (SI units), besides the status entries."""

ROUND_WIDTH = 64
"""Lanes integrated per round of the batched chord iteration (:func:`_settle`); all of a
smaller batch."""


def static_state(model: DobbyModel, arm: ArmTerms, ds: Downstream) -> Array:
    """x = (q, 0) at rest in the static equilibrium at t = 0 (bottom dwell), by Newton's method
    on the full residual (three iterations from q = 0; the chain is nearly linear there).
    ``arm``, ``ds``: ``model``'s :func:`arm_terms` and :func:`downstream`."""
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


class Cycle(eqx.Module):
    """What the passes of one sample need, built once per sample by :func:`prepare`.

    Attributes:
        arm: Kane's modal terms of the arm. downstream: the chain's constants.
        tables: the rigid motion's terms at the collocation nodes, leading axes (steps, 3).
        rest: the start state x = (q, 0) of the first cycle (static equilibrium at t = 0).
        period: cycle time T [s].
    """

    arm: ArmTerms
    downstream: Downstream
    tables: StageTables
    rest: Array
    period: Array


def prepare(setup: Setup, steps: int = DEFAULT_STEPS) -> Cycle:
    """Build the coupled model of ``setup`` (finite elements, modal reduction, static
    equilibrium) and tabulate its rigid motion on ``steps`` steps per cycle.

    :func:`steady_state_metrics` runs this once per sample, *sequentially* over a batch
    (``jax.custom_batching.sequential_vmap``): it is where the LAPACK calls are (Cholesky,
    ``eigh``, LU of the 31-DOF arm), and jaxlib spreads a batched LAPACK call over the CPU's
    intra-op threads and blocks one of them until the pieces finish, so two such calls running
    side by side on a 2-core CPU wait on each other for ever (seen with chunks of 256 samples).
    One matrix at a time never splits. It is a small part of a sample's cost; the cycle passes,
    which are all of the rest, stay vectorised over the batch.
    """
    return cycle_of(build_model(setup.machine, setup.operating), steps)


def cycle_of(model: DobbyModel, steps: int = DEFAULT_STEPS) -> Cycle:
    """:class:`Cycle` of an assembled (two-way coupled) ``model`` on ``steps`` steps per cycle."""
    arm, ds = arm_terms(model), downstream(model)
    tables = tables_at(arm, ds, rigid_arm(model, node_phases(steps)), model.period)
    return Cycle(arm, ds, tables, static_state(model, arm, ds), jnp.asarray(model.period))


def steady_state_metrics(setup: Setup, *, steps: int = DEFAULT_STEPS, tolerance: float = 1e-5,
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
    dynamic, static = eqx.partition(setup, eqx.is_array)
    cycle = sequential_vmap(lambda d: prepare(eqx.combine(d, static), steps))(dynamic)
    arm, ds, tables, period = cycle.arm, cycle.downstream, cycle.tables, cycle.period
    k = arm.mass.shape[0]
    eye = jnp.eye(2 * k)

    x0 = cycle.rest
    first = cycle_pass(arm, ds, tables, period, x0, tangents=eye, full_jacobian=True)
    chord_matrix = sequential_vmap(jnp.linalg.inv)(eye - first.tangents)
    x1 = x0 + chord_matrix @ (first.end - x0)
    passes, residual, hi, lo, reachable = _settle(cycle, chord_matrix, x1, tolerance=tolerance,
                                                  max_passes=max_passes)
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
    out["ok"] = finite & reachable & (residual <= tolerance)
    return out


class _Lanes(NamedTuple):
    """The chord iteration's state: chord passes run, next start state x, residual of the last
    pass, its extremes (maxima, minima) and reachability."""

    passes: Array
    x: Array
    residual: Array
    maxima: Array
    minima: Array
    reachable: Array


def _chord_pass(cycle: Cycle, chord_matrix: Array, lanes: _Lanes, tables=None,
                steps: int | None = None) -> _Lanes:
    """One chord cycle of one sample: integrate from x, record, step x ← x + (I − Φ)⁻¹(F(x) − x).
    ``tables``, ``steps``: as :func:`cycle_pass`'s, instead of ``cycle.tables``."""
    x = lanes.x
    run = cycle_pass(cycle.arm, cycle.downstream, cycle.tables if tables is None else tables,
                     cycle.period, x, outputs=True, steps=steps)
    return _Lanes(lanes.passes + 1, x + chord_matrix @ (run.end - x),
                  relative_residual(x, run.end), run.maxima, run.minima, run.reachable)


def _settle(cycle: Cycle, chord_matrix: Array, x1: Array, *, tolerance: float,
            max_passes: int):
    """Chord cycles from x1 until the residual is ≤ ``tolerance`` or ``max_passes`` ran.

    Returns (passes, residual, maxima, minima, reachable) of the last cycle. One sample runs a
    ``lax.while_loop``. A batch (``jax.vmap``, through ``jax.custom_batching.custom_vmap``)
    does not: a vmapped while loop runs every lane until the slowest has converged (on 256
    samples of the default box the lanes need 1 to 4 chord cycles, 2.3 on average, and the
    batch ran 4 for all). Here each round integrates one cycle for W of the lanes still pending
    (the first W; W = :data:`ROUND_WIDTH`), reading their tables step by step out of the
    batch's, step-major (copying a round's whole tables first was slower: XLA's CPU backend
    copies such 5-D arrays slowly), until none is pending: each lane goes through the same
    cycles as alone, and the batch integrates about the cycles its lanes need, rounded up to
    whole rounds. Measured (256 samples, one core,
    nothing else running; ad hoc, 2026-12-02): ``steady_state_metrics`` 5.5 ms per sample,
    against 8.0 ms with the vmapped while loop and 6.8 ms with the tables copied per round;
    the metrics equal to 6e-14. W = 32, 64, 128 of 256 lanes (two runs side by side, tables
    copied): 6.1, 5.4, 6.9 ms; in ``benchmarks/sobol_throughput.py`` (chunks of 256) one
    device gave 164 samples/s with W = 64 and 135 with 128, two devices of one process (128
    lanes each) 252 with W = 32 and 273 with 64: 64 lanes is best in both.
    """
    def pending(lanes):
        return (lanes.passes < max_passes) & (lanes.residual > tolerance)

    def start(x):
        nan3 = jnp.full(x.shape[:-1] + (3,), jnp.nan)
        return _Lanes(jnp.zeros(x.shape[:-1], int), x, jnp.full(x.shape[:-1], jnp.inf), nan3,
                      nan3, jnp.ones(x.shape[:-1], bool))

    def result(lanes):
        return lanes.passes, lanes.residual, lanes.maxima, lanes.minima, lanes.reachable

    @custom_vmap
    def settle(cycle, chord_matrix, x1):
        return result(jax.lax.while_loop(pending, lambda c: _chord_pass(cycle, chord_matrix, c),
                                         start(x1)))

    @settle.def_vmap
    def settle_batch(size, batched, cycle, chord_matrix, x1):
        cycle, chord_matrix, x1 = jax.tree.map(
            lambda a, b: a if b else jnp.broadcast_to(a, (size,) + jnp.shape(a)),
            (cycle, chord_matrix, x1), tuple(batched))
        width = min(size, ROUND_WIDTH)

        # the tables step-major, (N, batch, 3, ...): a round reads step n of its lanes from
        # them (a small gather per step) instead of copying its lanes' whole tables first
        by_step = jax.tree.map(lambda a: jnp.moveaxis(a, 0, 1), cycle.tables)
        steps = cycle.tables.height.shape[1]
        rest = eqx.tree_at(lambda c: c.tables, cycle, None)

        def lane_pass(lane, c, m, lanes):
            def table_at(n):
                return jax.tree.map(lambda a: a[n, lane], by_step)

            return _chord_pass(c, m, lanes, tables=table_at, steps=steps)

        def one_round(lanes):
            todo = pending(lanes)
            pick = jnp.argsort(jnp.where(todo, 0, 1), stable=True)[:width]
            take = jax.tree.map(lambda a: a[pick], (rest, chord_matrix, lanes))
            new = jax.vmap(lane_pass)(pick, *take)
            keep = todo[pick]

            def put(old, value):
                mask = keep.reshape(keep.shape + (1,) * (value.ndim - 1))
                return old.at[pick].set(jnp.where(mask, value, old[pick]))

            return jax.tree.map(put, lanes, new)

        out = result(jax.lax.while_loop(lambda c: jnp.any(pending(c)), one_round, start(x1)))
        return out, jax.tree.map(lambda _: True, out)

    return settle(cycle, chord_matrix, x1)
