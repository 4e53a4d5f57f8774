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
1e-5 changed them by ≤ 7e-7 relative against 1e-7 (and 1e-4 by up to 4.7e-5 on 512: the
tolerance cannot be relaxed to save the third cycle; 2026-12-07).

**Steps by speed** (``steps="speed"``, what a Sobol study runs). The error at a given step
count falls with the speed: the arm's modes, which set it, get more steps per period of theirs
when the cycle is short. So each sample may take the fewest steps that keep the 432 steps'
accuracy at 400 r/min: :data:`STEPS_BY_SPEED`, 360 steps from 450 r/min, 288 from 650, 216
from 1000 (multiples of 72, so the default dwell's boundaries stay step boundaries). Measured
at the slowest speed of each (8 corners of warp force × stroke × thickness against the
adaptive reference, 2026-12-07; largest relative error, the velocity deviation's amplitude
each time): 2.5e-5, 2.8e-5, 1.6e-5 (432 steps at 400 r/min: 2.3e-5); above a threshold it
falls (1.7e-5 at 480 r/min with 360 steps, 2.2e-5 at 700 with 288, 1.0e-5 at 1100 with 216); a
slow test holds the thresholds to 3e-5. The tables keep the 432 rows of the default (a static
size) and the linearisation and the passes loop over the run-time count; a batch integrates
the most its lanes need, so :mod:`jaxdobby.sensitivity` gives each chunk rows of one count
(averaging ~297 steps over the default box). Reverse-mode gradients need the fixed steps.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array
from jax.custom_batching import custom_vmap

from .._x64 import require_x64
from ..dobby import DobbyModel, build_model, machine_parts
from ..eigen import MAX_MODES
from ..kinematics import dead_centres
from ..parameters import Setup
from ..steady_state import relative_residual
from . import collocation as gl
from .chain import Downstream, downstream
from .cycle import (ArmTerms, RigidArm, StageTables, arm_terms, node_phases, rigid_arm,
                    rigid_arm_of, tables_at)
from .linear import linearise
from .stepper import cycle_pass

DEFAULT_STEPS = 432
"""Collocation steps per cycle (see the module docstring)."""

STEPS_BY_SPEED = ((0.0, 432), (450.0, 360), (650.0, 288), (1000.0, 216))
"""(lowest loom speed [r/min], collocation steps per cycle) of ``steps="speed"`` (see the module
docstring): the fewest steps that keep the default's accuracy at that speed and above."""

METRICS = ("deviation_pp", "deviation_max", "deviation_min", "velocity_deviation_amp",
           "acceleration_amp")
"""The metrics :func:`steady_state_metrics` returns (SI units), besides the status entries."""

ROUND_WIDTH = 16
"""Lanes integrated per round of the batched chord iteration (:func:`_solve`); all of a
smaller batch. A Sobol chunk gives each device 64 samples
(:data:`jaxdobby.sensitivity.batch.DEVICE_CHUNK`), of which ~40 % need a third cycle.
Measured with 32 per device (256 rows of 650–1000 r/min, one pinned core, AMD EPYC,
2026-12-07, rounds copying their lanes' tables): 16 lanes per round 1.42–1.43 ms per sample,
32 lanes 1.48–1.50, 8 lanes 1.43–1.44; with 64 per device and the rounds reading their lanes
step by step (``benchmarks/sobol_throughput.py --chunk 128``, Intel Xeon, 2026-12-07): 16
lanes 2140 and 2099 samples/s, 32 lanes 2260 and 1869, 64 lanes 2101."""

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


class Terms(eqx.Module):
    """What a sample's cycle needs besides the rigid motion: the arm's Kane terms, the chain's
    constants and the cycle time T [s]."""

    arm: ArmTerms
    downstream: Downstream
    period: Array

    def cycle(self, tables: StageTables | None) -> Cycle:
        """The :class:`Cycle` of these terms on ``tables`` (None: without its tables)."""
        return Cycle(self.arm, self.downstream, tables, self.period)


def terms_of(model: DobbyModel) -> Terms:
    """:class:`Terms` of an assembled (two-way coupled) ``model``."""
    return Terms(arm_terms(model), downstream(model), jnp.asarray(model.period))


def prepare(setup: Setup, steps: int = DEFAULT_STEPS) -> Cycle:
    """Build the coupled model of ``setup`` (finite elements, modal reduction) and tabulate its
    rigid motion on ``steps`` steps per cycle: one sample's :class:`Cycle`."""
    return cycle_of(build_model(setup.machine, setup.operating), steps)


def model_terms(setup: Setup, *, frequencies: bool = False):
    """(:class:`Terms`, coupled natural frequencies [Hz] or None) of ``setup``; vmapped, one
    sample at a time (:func:`_lane_by_lane`, as ``jax.custom_batching.sequential_vmap``), the
    arm's finite elements and modes once per distinct machine of the batch.

    Here are the LAPACK calls (Cholesky, ``eigh``, LU of the 31-DOF arm), and jaxlib spreads a
    batched LAPACK call over the CPU's intra-op threads and blocks one of them until the
    pieces finish, so two such calls running side by side on a 2-core CPU wait on each other
    for ever (seen with chunks of 256 samples). One matrix at a time never splits. The tables
    and the cycle passes, all of the rest, stay vectorised over the batch.

    The machine's part of the model (:func:`jaxdobby.dobby.machine_parts`: the finite
    elements, the modal reduction, the linkage's dead centres) does not depend on the operating
    point, and a Saltelli design repeats machines: each base sample's 2D + 2 rows hold 4
    distinct machines when two of its D = 4 parameters are the machine's (the default
    problem: stroke and thickness), 2 when one is. So a batch builds it once per distinct
    machine among its lanes (``unique`` of :func:`_lane_by_lane`) and every lane then adds its
    operating point (the chain's constants, the cycle time, the frequencies: these depend on
    the warp force). ``frequencies``: see :func:`steady_state_metrics`.
    """
    dynamic, static = eqx.partition(setup, eqx.is_array)

    def parts(machine):
        return machine_parts(eqx.combine(machine, static.machine))

    from ..validity import frequencies_hz, phase_matrices

    # the frequencies' eigenvalue problems of a few modes run vectorised over the whole batch
    # after the loop (jaxdobby.eigen); those of more modes, LAPACK's, inside it
    vectorised = setup.machine.n_modes <= MAX_MODES

    def one(machine, operating, built):
        model = DobbyModel(machine=eqx.combine(machine, static.machine),
                           operating=eqx.combine(operating, static.operating), **built)
        terms = terms_of(model)
        if not frequencies:
            return terms, None
        matrices = phase_matrices(model)
        return terms, matrices if vectorised else frequencies_hz(*matrices)

    built = _lane_by_lane(parts, unique=True)(dynamic.machine)
    terms, extra = _lane_by_lane(one)(dynamic.machine, dynamic.operating, built)
    if frequencies and vectorised:
        extra = frequencies_hz(*extra)
    return terms, extra


def _lane_by_lane(f, unique: bool = False):
    """``f`` vmapped one sample at a time (as ``jax.custom_batching.sequential_vmap``), its
    results written with the lanes last into buffers (..., B) and handed on as their
    transposes (B, ...), as a batching rule must. ``unique``: ``f`` runs once per distinct
    lane (lanes whose batched inputs are equal bit for bit share its result; ``f`` must be a
    function of its inputs alone), in a loop of as many iterations as there are.

    :func:`batch_terms` transposes them back: XLA cancels the two transposes, and the passes
    read the buffers as written, lanes last and contiguous (the optimised program's layouts
    show it). Stacked lanes first (as ``sequential_vmap`` stacks them), XLA made the transpose
    to lanes last free by laying its result out lanes first, and every step of every pass read
    the arm's terms strided. Measured (256 samples of the default design, one pinned core,
    2026-12-07, a machine varying ±10 % between runs): 1.93–2.06 ms per sample stacked lanes
    first, 1.75–1.80 with a layout constraint instead (``with_layout_constraint``, which
    ``jax.export`` refuses), 1.78–1.95 with these buffers.
    """
    @custom_vmap
    def mapped(*x):
        return f(*x)

    @mapped.def_vmap
    def rule(size, batched, *x):
        batched = tuple(batched)
        if unique:
            first = _first_equal_lane(x, batched, size)
        x = jax.tree.map(lambda a, b: a if b else jnp.broadcast_to(a, (size,) + jnp.shape(a)),
                         x, batched)
        shapes = jax.eval_shape(f, *jax.tree.map(lambda a: a[0], x))
        buffers = jax.tree.map(lambda a: jnp.zeros(a.shape + (size,), a.dtype), shapes)

        def lane(i, buffers):
            out = f(*jax.tree.map(lambda a: a[i], x))
            return jax.tree.map(lambda b, o: b.at[..., i].set(o), buffers, out)

        if unique:
            distinct = first == jnp.arange(size)
            todo = jnp.argsort(jnp.where(distinct, 0, 1), stable=True)
            buffers = jax.lax.fori_loop(0, jnp.sum(distinct),
                                        lambda j, b: lane(todo[j], b), buffers)
            buffers = jax.tree.map(lambda b: b[..., first], buffers)
        else:
            buffers = jax.lax.fori_loop(0, size, lane, buffers)
        out = jax.tree.map(lambda b: jnp.moveaxis(b, -1, 0), buffers)
        return out, jax.tree.map(lambda _: True, out)

    return mapped


def _first_equal_lane(x, batched, size: int) -> Array:
    """For each of ``size`` lanes, the first lane whose batched leaves of ``x`` (lanes on axis
    0; ``batched``: pytree of bools) are all equal to its own, bit for bit (NaNs included),
    (size,) int; lanes without a batched leaf are all equal."""
    same = jnp.ones((size, size), bool)
    for a, b in zip(jax.tree.leaves(x), jax.tree.leaves(batched)):
        if not b:
            continue
        a = jnp.reshape(a, (size, -1))
        if jnp.issubdtype(a.dtype, jnp.floating):
            a = jax.lax.bitcast_convert_type(a, jnp.dtype(f"int{a.dtype.itemsize * 8}"))
        same = same & jnp.all(a[:, None, :] == a[None, :, :], axis=-1)
    return jnp.argmax(same, axis=1)


def rigid_motion(setup: Setup, steps: int = DEFAULT_STEPS) -> RigidArm:
    """The rigid arm's motion at the collocation nodes of ``steps`` steps per cycle, from the
    linkage alone (the crank start as :func:`~jaxdobby.dobby.build_model`'s): a batch whose
    linkage is not sampled computes it once for all its lanes."""
    return _rigid(_linkage(setup), steps, steps)


def _linkage(setup: Setup):
    """(chain, crank angle at t = 0 [rad]) of ``setup``: what its rigid motion depends on."""
    chain = setup.machine.chain
    (crank_start, _), _ = dead_centres(chain)
    return chain, crank_start


def cycle_of(model: DobbyModel, steps: int = DEFAULT_STEPS) -> Cycle:
    """:class:`Cycle` of an assembled (two-way coupled) ``model`` on ``steps`` steps per cycle."""
    terms = terms_of(model)
    return terms.cycle(tables_at(terms.arm, terms.downstream,
                                 rigid_arm(model, node_phases(steps)), terms.period))


def steps_for_speed(speed) -> Array:
    """Collocation steps per cycle that keep the default accuracy at loom speed ``speed``
    [rad/s] (:data:`STEPS_BY_SPEED`), int, any shape."""
    speed_rpm = jnp.asarray(speed) * (30.0 / jnp.pi)
    out = jnp.full(jnp.shape(speed_rpm), STEPS_BY_SPEED[0][1])
    for lower, n in STEPS_BY_SPEED[1:]:
        out = jnp.where(speed_rpm >= lower, n, out)
    return out


def steady_state_metrics(setup: Setup, *, steps: int | str = DEFAULT_STEPS,
                         tolerance: float = 1e-5, max_passes: int = 6,
                         frequencies: bool = False) -> dict[str, Array]:
    """Metrics of the periodic steady cycle of ``setup`` (see the module docstring).

    Args:
        setup: machine and operating point (two-way coupling; any number of modes, either warp
            law). Vmappable over its float fields; jittable.
        steps: collocation steps per cycle (static), or ``"speed"``: by the sample's speed,
            :func:`steps_for_speed` (see the module docstring; a batch integrates its lanes'
            most).
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
    if steps == "speed":
        size, count = DEFAULT_STEPS, steps_for_speed(setup.operating.speed)
    elif isinstance(steps, int) and not isinstance(steps, bool) and steps >= 1:
        size, count = steps, None
    else:
        raise ValueError(f"steps must be a positive integer or 'speed'; got {steps!r}")
    terms, freqs = model_terms(setup, frequencies=frequencies)
    passes, residual, hi, lo, reachable = _solve(
        terms, _linkage(setup), jnp.asarray(size if count is None else count),
        size=size, fixed=count is None, tolerance=tolerance, max_passes=max_passes)
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
    """The iteration's state before any cycle, from x (2k, lanes...)."""
    lanes = x.shape[1:]
    nan3 = jnp.full((3,) + lanes, jnp.nan)
    return _Lanes(jnp.zeros(lanes, int), x, jnp.full(lanes, jnp.inf), nan3, nan3,
                  jnp.ones(lanes, bool))


def _chord_pass(cycle: Cycle, solvers, chord_matrix: Array, lanes: _Lanes, tables=None,
                steps: int | None = None, outputs: bool = True, count=None) -> _Lanes:
    """One chord cycle of one sample: integrate from x, record, step x ← x + (I − Φ)⁻¹(F(x) − x).
    ``tables``, ``solvers``, ``steps``: as :func:`cycle_pass`'s; ``tables`` None:
    ``cycle.tables``. ``outputs`` False: a cycle whose extremes and reachability a later one
    replaces (NaN extremes, reachable)."""
    x = lanes.x
    run = cycle_pass(cycle.arm, cycle.downstream, cycle.tables if tables is None else tables,
                     cycle.period, x, solvers=solvers, outputs=outputs, steps=steps,
                     count=count)
    return _Lanes(lanes.passes + 1, x + gl.matmul(chord_matrix, run.end - x),
                  relative_residual(x, run.end), run.maxima, run.minima, run.reachable)


def batch_terms(terms: Terms, batched, size: int) -> Terms:
    """A batch's :class:`Terms` with the lanes last: each leaf (..., B), from a batch of
    ``size`` lanes with the leaves marked in ``batched`` (pytree of bools) batched on axis 0
    and the others shared (broadcast to every lane)."""
    return jax.tree.map(lambda a, b: jnp.moveaxis(a, 0, -1) if b else
                        jnp.broadcast_to(a[..., None], jnp.shape(a) + (size,)), terms, batched)


def batch_tables(terms: Terms, rigid: RigidArm, batched=False) -> StageTables:
    """The tables of a batch with the lanes last (:func:`batch_terms`), built so from a rigid
    motion the lanes share or from one batched on axis 0 (``batched``: pytree of bools, a
    linkage sampled with the rest), whose few leaves (N, 3) per lane are moved to lanes last
    first. Built lane by lane and then transposed, the tables were read strided by every step
    of every pass (see :func:`_solve`): measured (the first 32 rows of the default design, whose
    stroke moves the linkage, 432 steps, one pinned core, Intel Xeon, 2026-12-07) 1.42 ms per
    sample so against 1.12 built lanes last, the same metrics to 1e-12."""
    if not any(jax.tree.leaves(batched)):
        return tables_at(terms.arm, terms.downstream, rigid, terms.period)
    size = terms.period.shape[-1]
    rigid = jax.tree.map(lambda a, b: jnp.moveaxis(a, 0, -1) if b else
                         jnp.broadcast_to(a[..., None], a.shape + (size,)), rigid, batched)
    return tables_at(terms.arm, terms.downstream, rigid, terms.period, rigid_lanes=True)


def batch_linearise(terms: Terms, tables: StageTables, count=None):
    """The linearisation of a batch with the lanes last (:func:`batch_terms`,
    :func:`batch_tables`): (the :class:`Cycle` without its tables, the
    :class:`~jaxdobby.periodic.linear.Linearisation`, the chord matrix (I − Φ)⁻¹ and the start
    state x_lin), each with the lanes last."""
    lin = linearise(terms.arm, terms.downstream, tables, terms.period, count)
    i_phi = jnp.moveaxis(jnp.eye(lin.monodromy.shape[0])[..., None] - lin.monodromy, -1, 0)
    # one matrix at a time (a batched LAPACK call can deadlock a 2-core CPU: see model_terms)
    chord_matrix = jnp.moveaxis(jax.lax.map(jnp.linalg.inv, i_phi), 0, -1)
    rest = terms.cycle(None)
    return rest, lin, chord_matrix, gl.matmul(chord_matrix, lin.rest_response)


def _rigid(linkage, count, size: int) -> RigidArm:
    """The rigid arm at the nodes of ``count`` steps per cycle in tables of ``size`` rows, from
    ``linkage`` = (chain, crank start) (:func:`rigid_motion`)."""
    chain, crank_start = linkage
    return rigid_arm_of(chain, crank_start, node_phases(count, size))


def _solve(terms: Terms, linkage, count, *, size: int, fixed: bool, tolerance: float,
           max_passes: int):
    """The chord iteration of one sample from the linearised periodic state, until the residual
    is ≤ ``tolerance`` or ``max_passes`` cycles ran.

    Returns (passes, residual, maxima, minima, reachable) of the last cycle. One sample runs a
    ``lax.while_loop``. A batch (``jax.vmap``, through ``jax.custom_batching.custom_vmap``)
    does not:

    * every array of the batch has its lanes *last*: the tables (N, 3, ..., B), built so by
      :func:`~jaxdobby.periodic.cycle.tables_at` from the rigid motion the lanes share, the
      solvers, Φ and the states, and the linearisation and the passes are those of one sample
      run on them (the unrolled small products of :mod:`jaxdobby.periodic.collocation` then
      loop over contiguous lanes). Lanes first, as ``jax.vmap`` lays them out, the inner axes
      are the 3 nodes and the k modes: measured (256 samples of the default design, one pinned
      core, 2026-12-07) a pass cost 0.39 ms per sample so against 0.25 lanes last. The tables
      are built lanes last, not transposed: XLA makes a transpose free by giving its result
      the operand's layout, so every step then read its tables strided (a pass 0.45 ms). A
      linkage sampled with the rest (the rigid motion differs per lane) computes the rigid
      motion lane by lane and moves it, not the tables, to lanes last
      (:func:`batch_tables`).
    * the first :data:`FULL_CYCLES` cycles run for every lane at once (those before the last
      of them without the extremes, which a later cycle's always replace: 0.88 against 0.85 ms
      per sample of the default design, 128 samples on one pinned core, 2026-12-07), the rest
      in rounds: a vmapped while loop would run every lane until the slowest has converged
      (on 256 samples of the default box the lanes need 2 to 4 cycles); here each round
      gathers W of the lanes still pending (the first W; W = :data:`ROUND_WIDTH`) and
      integrates one cycle for them, until none is pending, each step reading those lanes of
      its tables and solvers out of the batch's. Each lane goes through the same cycles as
      alone; the batch integrates about the cycles its lanes need. Copying the W lanes'
      tables and solvers whole before each round cost ~0.2 ms per sample of the batch (64 rows
      of the default design, steps by speed, one pinned core, Intel Xeon, 2026-12-07: 1.00
      against 0.81 ms per sample read step by step, the same metrics bit for bit).
    """
    def pending(lanes):
        return (lanes.passes < min(FULL_CYCLES, max_passes)) | ((lanes.passes < max_passes)
                                         & (lanes.residual > tolerance))

    def result(lanes):
        return lanes.passes, lanes.residual, lanes.maxima, lanes.minima, lanes.reachable

    @custom_vmap
    def solve(terms, linkage, count):
        count = None if fixed else count
        rigid = _rigid(linkage, size if fixed else count, size)
        cycle = terms.cycle(tables_at(terms.arm, terms.downstream, rigid, terms.period))
        lin = linearise(cycle.arm, cycle.downstream, cycle.tables, cycle.period, count)
        chord_matrix = jnp.linalg.inv(jnp.eye(lin.monodromy.shape[0]) - lin.monodromy)
        x = chord_matrix @ lin.rest_response
        return result(jax.lax.while_loop(
            pending, lambda c: _chord_pass(cycle, lin.solvers, chord_matrix, c, count=count),
            _start(x)))

    @solve.def_vmap
    def solve_batch(lanes_in, batched, terms, linkage, count):
        terms = batch_terms(terms, batched[0], lanes_in)
        # the batch integrates the most steps any of its lanes needs (all, in a chunk of
        # rows grouped by their step count: jaxdobby.sensitivity.dobby)
        count = None if fixed else (jnp.max(count) if batched[2] else count)
        linked = jax.tree.map(lambda b: 0 if b else None, batched[1])
        moving = any(jax.tree.leaves(batched[1]))
        n = size if fixed else count
        rigid = (jax.vmap(lambda link: _rigid(link, n, size), in_axes=(linked,))(linkage)
                 if moving else _rigid(linkage, n, size))
        tables = batch_tables(terms, rigid, jax.tree.map(lambda _: moving, rigid))
        rest, lin, chord_matrix, x = batch_linearise(terms, tables, count)
        width = min(lanes_in, ROUND_WIDTH)

        def full_cycle(lanes, outputs):
            return _chord_pass(rest, lin.solvers, chord_matrix, lanes, tables=tables,
                               outputs=outputs, count=count)

        # a Python loop, not a fori_loop: a pass (a scan) inside another loop ran 8-10 % slower
        # in all (2026-12-07, 256 samples, one pinned core: 2.49 against 2.28 ms per sample;
        # with the compile options of jaxdobby.sensitivity.batch, 2.31 against 1.77), for a
        # second copy of the pass in the program (compiled 2-3 s longer)
        lanes = _start(x)
        full = min(FULL_CYCLES, max_passes)
        for n in range(full):
            lanes = full_cycle(lanes, outputs=n == full - 1)

        def one_round(lanes):
            todo = pending(lanes)
            pick = jnp.argsort(jnp.where(todo, 0, 1), stable=True)[:width]
            # the W lanes' terms, chord matrices and states gathered; their tables and
            # solvers read step by step out of the batch's (no copy of the whole tables)
            part, matrix, state = jax.tree.map(
                lambda a: a[..., pick], (rest, chord_matrix, lanes))

            def step_of(tree):  # step n's rows of the W lanes
                return lambda n: jax.tree.map(lambda a: a[n][..., pick], tree)

            new = _chord_pass(part, step_of(lin.solvers), matrix, state,
                              tables=step_of(tables), count=count, steps=size)
            keep = todo[pick]
            return jax.tree.map(
                lambda old, value: old.at[..., pick].set(jnp.where(keep, value, old[..., pick])),
                lanes, new)

        out = result(jax.lax.while_loop(lambda c: jnp.any(pending(c)), one_round, lanes))
        out = jax.tree.map(lambda a: jnp.moveaxis(a, -1, 0), out)
        return out, jax.tree.map(lambda _: True, out)

    return solve(terms, linkage, count)
