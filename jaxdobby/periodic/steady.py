"""Steady-state metrics of one machine at one operating point, fixed-size and vmappable.

:func:`steady_state_metrics` returns the heald frame's metrics over the periodic steady cycle
(``deviation_max``, ``deviation_min``, ``deviation_pp`` [m], ``velocity_deviation_amp`` [m/s],
``acceleration_amp`` [m/s²]: peak-to-peak ranges as in :func:`jaxdobby.metrics.cycle_metrics`),
the relative periodicity residual, the number of cycles integrated and an ``ok`` flag, solving the
equations of :mod:`jaxdobby.dobby` (two-way coupling) with the collocation passes of
:mod:`jaxdobby.periodic.stepper`. Every size is static — ``steps`` per cycle of phase-normalised
time (the same for every sample whatever its speed) and at most ``max_passes`` cycles — and
nothing raises at run time: a sample that does not converge, leaves the chain's workspace or
produces a non-finite metric has ``ok = False``.

**Periodic state.** Shooting on the period map F with the chord iteration
x ← x + (I − Φ)⁻¹(F(x) − x) (as :mod:`jaxdobby.steady_state`), where Φ, the steps' Newton
matrices and the first x are those of the equations linearised about the rigid motion
(:mod:`jaxdobby.periodic.linear`, built before any cycle is integrated): the first cycle starts
from the linearised equations' periodic state, each cycle records the metrics of its start
state x, and the iteration stops when the residual ‖F(x) − x‖/‖x‖
(:func:`jaxdobby.steady_state.relative_residual`) is below ``tolerance``; the metrics returned
are those of that last cycle. Most samples of the default box need two cycles (residuals
~3e-3 from the linearised state, then ~3e-6, below 1e-5: the second cycle's metrics are
returned; see :mod:`jaxdobby.periodic.linear`), the others three or four (152, 97 and 7 of the
first 256 rows of the default design: ``benchmarks/batch_profile.py``). Under ``jax.vmap`` the
cycles after the first :data:`FULL_CYCLES` run in rounds over the lanes still pending, so a
batch does not integrate its slowest lane's cycle count for every lane (:func:`_solve`).

**Accuracy.** With the default 432 steps per cycle (6 per 1/72 of the cycle, so that the
modulator's dwell boundaries at 5/72, 31/72, 41/72, 67/72 of the cycle are step boundaries for
the default 100° dwell) and periodicity tolerance 1e-5, every metric is within 3e-5 of the
adaptive reference :func:`jaxdobby.simulate.simulate` (``method="adaptive"``, rtol 1e-8) at
the 16 corners of the default Sobol box (400–1200 r/min, 345–1035 N, 80–140 mm, 6–8 mm; a slow
test). Measured there (largest relative error over the corners and the five metrics): 576
steps 2.2e-5, 432 steps 2.9e-5, 360 steps 8.3e-5, 288 steps 2.5e-4 (the velocity deviation's
amplitude goes first); with the parabola-refined extremes of :mod:`jaxdobby.periodic.stepper`, 432
steps: 2.3e-5 on the velocity deviation's amplitude, ≤ 2.1e-6 on the other four (2026-12-01,
``benchmarks/sobol_throughput.py``); measured again with them (2026-12-06, ad hoc, against the
adaptive reference with 3001 and 12001 output times alike, and against 1728 steps, which is
within 2.2e-7 of the reference): the velocity deviation's amplitude 8.2e-4, 2.4e-4, 7.7e-5,
2.3e-5 at 216, 288, 360, 432 steps, the other four ≤ 8.3e-5, 1.3e-5, 4.1e-6, 1.8e-6: the
batch's own errors, not the reference's, which is why the steps were not cut to gain speed
(360 steps would run ~23 % faster). The shooting tolerance costs little accuracy: the metrics
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
from .linear import linearise, linearise_lanes
from .stepper import cycle_pass

DEFAULT_STEPS = 432
"""Collocation steps per cycle (see the module docstring)."""

METRICS = ("deviation_pp", "deviation_max", "deviation_min", "velocity_deviation_amp",
           "acceleration_amp")
"""The metrics :func:`steady_state_metrics` returns (SI units), besides the status entries."""

ROUND_WIDTH = 32
"""Lanes integrated per round of the batched chord iteration (:func:`_solve`); all of a
smaller batch."""

FULL_CYCLES = 2
"""Cycles every sample integrates, converged or not (the batch integrates them for all its
lanes at once, without the rounds' gathers; every sample of the default box needs two)."""


class Cycle(eqx.Module):
    """What the passes of one sample need, built once per sample by :func:`prepare`.

    Attributes:
        arm: Kane's modal terms of the arm. downstream: the chain's constants.
        tables: the rigid motion's terms at the collocation nodes, leading axes (steps, 3).
        period: cycle time T [s].
    """

    arm: ArmTerms
    downstream: Downstream
    tables: StageTables
    period: Array


def prepare(setup: Setup, steps: int = DEFAULT_STEPS) -> Cycle:
    """Build the coupled model of ``setup`` (finite elements, modal reduction) and tabulate its
    rigid motion on ``steps`` steps per cycle.

    :func:`steady_state_metrics` does the same (with the model's coupled frequencies when
    asked) once per sample, *sequentially* over a batch
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
    return Cycle(arm, ds, tables, jnp.asarray(model.period))


def steady_state_metrics(setup: Setup, *, steps: int = DEFAULT_STEPS, tolerance: float = 1e-5,
                         max_passes: int = 6, frequencies: bool = False) -> dict[str, Array]:
    """Metrics of the periodic steady cycle of ``setup`` (see the module docstring).

    Args:
        setup: machine and operating point (two-way coupling; any number of modes, either warp
            law). Vmappable over its float fields; jittable.
        steps: collocation steps per cycle (static).
        tolerance: relative periodicity residual to stop at and to call converged.
        max_passes: cycles at most (static bound of the loop).
        frequencies: also return the coupled natural frequencies over the cycle
            (:func:`jaxdobby.validity.phase_frequencies`) of the model the solve assembles,
            so that a caller checking resonances does not assemble it a second time (in a
            Sobol chunk program, a second assembly cost 9 % of the run time and as much
            compile time again for the finite elements and the modal reduction).

    Returns:
        A dict: the scalars :data:`METRICS`, ``periodicity`` (the residual), ``cycles``
        (integrated, int) and ``ok`` (bool); with ``frequencies``, ``frequencies`` [Hz],
        (:data:`jaxdobby.validity.PHASES`, modes).
    """
    require_x64()
    if setup.machine.coupling != "two-way":
        raise ValueError("the batch evaluator solves the two-way coupled model; got coupling="
                         f"{setup.machine.coupling!r} (use jaxdobby.simulate for one-way)")
    dynamic, static = eqx.partition(setup, eqx.is_array)

    def one(d):
        s = eqx.combine(d, static)
        model = build_model(s.machine, s.operating)
        if not frequencies:
            return cycle_of(model, steps), None
        from ..validity import phase_frequencies

        return cycle_of(model, steps), phase_frequencies(model)

    cycle, freqs = sequential_vmap(one)(dynamic)
    passes, residual, hi, lo, reachable = _solve(cycle, tolerance=tolerance,
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
    out["cycles"] = passes
    out["ok"] = finite & reachable & (residual <= tolerance)
    if frequencies:
        out["frequencies"] = freqs
    return out


class _Lanes(NamedTuple):
    """The chord iteration's state: cycles run, next start state x, residual of the last
    cycle, its extremes (maxima, minima) and reachability."""

    passes: Array
    x: Array
    residual: Array
    maxima: Array
    minima: Array
    reachable: Array


def _start(x: Array) -> _Lanes:
    nan3 = jnp.full(x.shape[:-1] + (3,), jnp.nan)
    return _Lanes(jnp.zeros(x.shape[:-1], int), x, jnp.full(x.shape[:-1], jnp.inf), nan3, nan3,
                  jnp.ones(x.shape[:-1], bool))


def _chord_pass(cycle: Cycle, solvers, chord_matrix: Array, lanes: _Lanes, tables=None,
                steps: int | None = None) -> _Lanes:
    """One chord cycle of one sample: integrate from x, record, step x ← x + (I − Φ)⁻¹(F(x) − x).
    ``tables``, ``solvers``, ``steps``: as :func:`cycle_pass`'s; ``tables`` None:
    ``cycle.tables``."""
    x = lanes.x
    run = cycle_pass(cycle.arm, cycle.downstream, cycle.tables if tables is None else tables,
                     cycle.period, x, solvers=solvers, outputs=True, steps=steps)
    return _Lanes(lanes.passes + 1, x + gl.matmul(chord_matrix, run.end - x),
                  relative_residual(x, run.end), run.maxima, run.minima, run.reachable)


def _solve(cycle: Cycle, *, tolerance: float, max_passes: int):
    """The chord iteration of one sample from the linearised periodic state, until the residual
    is ≤ ``tolerance`` or ``max_passes`` cycles ran.

    Returns (passes, residual, maxima, minima, reachable) of the last cycle. One sample runs a
    ``lax.while_loop``. A batch (``jax.vmap``, through ``jax.custom_batching.custom_vmap``)
    does not:

    * the linearisation runs with the lanes last (:func:`~jaxdobby.periodic.linear.linearise_lanes`)
      and every pass reads step n of the tables where they are, (batch, N, 3, ...), by a slice
      (a scan over a batch's tables first copies them step-major, for every pass: half a
      pass's time);
    * the first :data:`FULL_CYCLES` cycles run for every lane at once, the rest in rounds: a
      vmapped while loop would run every lane until the slowest has converged (on 256 samples
      of the default box the lanes need 2 to 4 cycles); here each round integrates one cycle
      for W of the lanes still pending (the first W; W = :data:`ROUND_WIDTH`), reading their
      tables and solvers step by step out of the batch's (a gather per step: a lane's cycle
      costs ~1.4 times its cycle in a full pass), until none is pending. Each lane goes
      through the same cycles as alone; the batch integrates about the cycles its lanes need.

    Measured (256 samples of the default design, one core, ad hoc, 2026-12-02, this machine's
    speed varying ±10 % between runs): 1.5–1.6 ms per sample; 1.7 with every cycle after the
    first in rounds of 64; W = 32 slightly better than 64 and 128 (1.45–1.8 against
    1.55–2.3 and 1.6 ms). ``benchmarks/batch_profile.py`` (compiled as ``jaxdobby sobol``
    compiles, one pinned core, 2026-12-02, ``results/batch_profile.json``): prepare 0.34,
    linearisation 0.26, a full cycle 0.36 ms per sample; 1.44–1.46 ms per sample in all,
    W = 32, 64 or 128 alike.
    """
    def pending(lanes):
        return (lanes.passes < min(FULL_CYCLES, max_passes)) | ((lanes.passes < max_passes)
                                         & (lanes.residual > tolerance))

    def result(lanes):
        return lanes.passes, lanes.residual, lanes.maxima, lanes.minima, lanes.reachable

    @custom_vmap
    def solve(cycle):
        lin = linearise(cycle.arm, cycle.downstream, cycle.tables, cycle.period)
        chord_matrix = jnp.linalg.inv(jnp.eye(lin.monodromy.shape[0]) - lin.monodromy)
        x = chord_matrix @ lin.rest_response
        return result(jax.lax.while_loop(
            pending, lambda c: _chord_pass(cycle, lin.solvers, chord_matrix, c), _start(x)))

    @solve.def_vmap
    def solve_batch(size, batched, cycle):
        cycle = jax.tree.map(lambda a, b: a if b else jnp.broadcast_to(a, (size,) + jnp.shape(a)),
                             cycle, batched[0])
        width = min(size, ROUND_WIDTH)
        steps = cycle.tables.height.shape[1]
        tables = cycle.tables  # lane-major, (batch, N, 3, ...)
        rest = eqx.tree_at(lambda c: c.tables, cycle, None)

        lin = linearise_lanes(cycle.arm, cycle.downstream, cycle.tables, cycle.period)
        i_phi = jnp.eye(lin.monodromy.shape[-1]) - lin.monodromy
        # one matrix at a time (a batched LAPACK call can deadlock a 2-core CPU: see prepare)
        chord_matrix = jax.lax.map(jnp.linalg.inv, i_phi)
        x = jax.vmap(gl.matmul)(chord_matrix, lin.rest_response)

        def full_pass(c, t, s, m, lanes):
            def table_at(n):
                return jax.tree.map(lambda a: a[n], t)

            return _chord_pass(c, s, m, lanes, tables=table_at, steps=steps)

        def full_cycle(_, lanes):
            return jax.vmap(full_pass, in_axes=(0, 0, 1, 0, 0))(rest, tables, lin.solvers,
                                                                chord_matrix, lanes)

        # a loop, not a Python for: one copy of the pass in the program (compile time)
        lanes = jax.lax.fori_loop(0, min(FULL_CYCLES, max_passes), full_cycle, _start(x))

        def lane_pass(lane, c, m, lanes):
            def table_at(n):
                return jax.tree.map(lambda a: a[lane, n], tables)

            def solver_at(n):
                return jax.tree.map(lambda a: a[n, lane], lin.solvers)

            return _chord_pass(c, solver_at, m, lanes, tables=table_at, steps=steps)

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

        out = result(jax.lax.while_loop(lambda c: jnp.any(pending(c)), one_round, lanes))
        return out, jax.tree.map(lambda _: True, out)

    return solve(cycle)
