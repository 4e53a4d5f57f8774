"""One steady-state run of the mechanism: ``simulate(machine, operating)``.

1. :func:`~jaxdobby.dobby.build_model` — the arm's modes and invariants, the chain's references;
2. :func:`~jaxdobby.steady_state.periodic_state` — the periodic state by Newton shooting on the
   period map, one heald-frame cycle of integration;
3. one more cycle from that state, saving the outputs (:mod:`jaxdobby.outputs`), then the
   metrics (:mod:`jaxdobby.metrics`) and the coupled natural frequencies at mid-stroke.

Three integrators solve the same equations:

* ``method="collocation"`` (the default for the two-way coupled model): three-stage Gauss
  collocation (order 6, A-stable) on a phase-normalised grid of 432 steps per cycle, the rigid
  mechanism tabulated at the collocation nodes and the chain in closed form
  (:mod:`jaxdobby.periodic.dense`, the equations of the batch evaluator), outputs from the
  collocation polynomial at four times per step — tens of milliseconds per run;
* ``method="rk4"`` (the default for the one-way variant): fixed-step RK4 on a precomputed table
  of the rigid mechanism (:mod:`jaxdobby.fixed_step`), a step from the highest mode
  (Δt = 1.5/ω_max: thousands per cycle), outputs at every step;
* ``method="adaptive"``: diffrax's Tsitouras 5(4) with a PID step-size controller, outputs at
  ``n_out`` times — the reference the fast paths are tested against.

**A first answer without compiling.** Called outside any trace with the default options, the
default sizes and a CPU the package ships an executable for, ``simulate`` runs the compiled
executable of the command line's run (:func:`shipped_simulation`): ~1.3 s for the first call
in a new process instead of ~11 s of tracing and compiling (2 cores, 2026-12-06,
``benchmarks/bench_simulate.py``), whatever the float values. Elsewhere, and under
``jax.jit``/``jax.grad``/``jax.vmap``, it traces and compiles as usual.

The run is one differentiable function of the float fields of ``machine`` and ``operating``
(derivatives through the periodic state by the implicit-function theorem). Sizes are static:
``steps`` for RK4 is chosen from the model's highest frequency when not given, which needs
concrete parameters — pass it explicitly under ``jax.jit``/``jax.vmap``.

Example::

    import jax; jax.config.update("jax_enable_x64", True)
    from jaxdobby import Machine, OperatingPoint, simulate
    run = simulate(Machine.default(), OperatingPoint.from_users_units(speed_rpm=800.0))
    run.metrics["deviation_pp"]       # heald-frame displacement deviation, peak to peak [m]
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._x64 import require_x64
from .periodic import DEFAULT_STEPS as COLLOCATION_STEPS
from .periodic.dense import PER_STEP, steady_cycle
from .dobby import DobbyModel, build_model, rigid_state, vector_field
from .errors import InputError
from .fixed_step import rigid_table, rk4_cycle, steps_per_cycle
from .machine import Machine, OperatingPoint
from .metrics import cycle_metrics
from .outputs import ArmMotion, Timeseries, coupled_frequencies, flexible_outputs, rigid_outputs
from .steady_state import ShootingResult, periodic_state, relative_residual
from .validity import validity_arrays, warnings_of
from .weave.metrics import pick_metrics

METHODS = ("collocation", "rk4", "adaptive")


class Simulation(eqx.Module):
    """Result of :func:`simulate`.

    Attributes:
        model: the assembled model (modes, invariants, references).
        series: time series over the steady-state cycle.
        metrics: scalar metrics (SI, see :func:`jaxdobby.metrics.cycle_metrics`).
        natural_frequencies: coupled natural frequencies at mid-stroke [Hz].
        shooting: the Newton shooting result (residual of its last iterate).
        periodicity: relative mismatch of the saved cycle's end and start states [-].
        converged: shooting converged and the saved cycle is periodic to ``tolerance``.
        num_steps: integration steps of the saved cycle.
        pick_metrics: with a lift plan, the per-pick metrics of the repeat
            (:func:`jaxdobby.weave.metrics.pick_metrics`) and ``lift_plan``; else empty.
        arm_motion: the arm's rigid motion and q̈ at the saved times
            (:class:`~jaxdobby.outputs.ArmMotion`) where the integrator has them at no cost
            (collocation); None otherwise (the stress recovery then computes them).
    """

    model: DobbyModel
    series: Timeseries
    metrics: dict[str, Array]
    natural_frequencies: Array
    shooting: ShootingResult
    periodicity: Array
    converged: Array
    num_steps: Array
    pick_metrics: dict = eqx.field(default_factory=dict)
    arm_motion: ArmMotion | None = None


def default_method(machine: Machine) -> str:
    """The integrator :func:`simulate` uses unless told: collocation for the two-way coupled
    model, RK4 for the one-way variant (which the collocation path does not solve)."""
    return "collocation" if machine.coupling == "two-way" else "rk4"


def resolve_method(machine: Machine, operating: OperatingPoint, method: str | None = None,
                   steps: int | None = None, basis: Array | str | None = None,
                   lift_plan=None) -> tuple[str, int | None]:
    """(method, steps) as :func:`simulate` runs them: the default method for the coupling, the
    default step count of the fixed-step methods (collocation: 216 per pick, 432 for the plain
    weave's two); raises ``ValueError`` for a method that does not exist or does not solve
    this model (:class:`~jaxdobby.errors.InputError`)."""
    method = default_method(machine) if method is None else method
    if method not in METHODS:
        raise InputError(f"method = {method!r} is not valid: use one of {', '.join(METHODS)}")
    if _never_moves(lift_plan):  # static: no integrator; the collocation path's output grid
        return "static", COLLOCATION_STEPS * len(lift_plan) // 2 if steps is None else steps
    if method == "collocation":
        if machine.coupling != "two-way":
            raise InputError("method = 'collocation' solves the two-way coupled model: use rk4 "
                             f"or adaptive for coupling = {machine.coupling!r}")
        picks = 2 if lift_plan is None else len(lift_plan)
        return method, COLLOCATION_STEPS * picks // 2 if steps is None else steps
    if method == "rk4" and steps is None:
        steps = default_steps(machine, operating, basis, lift_plan)
    return method, steps


def _never_moves(lift_plan) -> bool:
    """True for a concrete lift plan that never moves (the static case,
    :mod:`jaxdobby.weave.static`)."""
    if lift_plan is None or isinstance(lift_plan, jax.core.Tracer):
        return False
    from .weave.plan import is_static

    return is_static(np.asarray(lift_plan))


def default_steps(machine: Machine, operating: OperatingPoint,
                  basis: Array | str | None = None, lift_plan=None) -> int:
    """RK4 steps per cycle (the repeat of a lift plan) for concrete parameters
    (Δt = 1.5/ω_max of the arm's modes)."""
    model = eqx.filter_jit(build_model)(machine, operating, basis, lift_plan)
    return steps_per_cycle(float(jnp.max(model.body.frequencies_hz)), float(model.period))


def simulate(machine: Machine | None = None, operating: OperatingPoint | None = None, *,
             method: str | None = None, steps: int | None = None, n_out: int = 3001, rtol=1e-8,
             atol=1e-12, tolerance=1e-6, forward_mode: bool = False,
             basis: Array | str | None = None, lift_plan=None) -> Simulation:
    """Steady-state heald-frame cycle of ``machine`` at ``operating`` (defaults: DESIGN §6).

    Args:
        machine: the mechanism (:class:`~jaxdobby.machine.Machine`).
        operating: speed and warp force (:class:`~jaxdobby.machine.OperatingPoint`).
        method: ``"collocation"`` (fast; two-way coupling), ``"rk4"`` (fixed step) or
            ``"adaptive"`` (reference); default: collocation for the two-way coupled model, RK4
            for the one-way variant.
        steps: steps per cycle of the fixed-step methods (static); default 432 for collocation
            and, for RK4, from the highest mode.
        n_out: output times of the adaptive method (static).
        rtol, atol: step-size control of the adaptive method (atol in modal coordinates ~1e-5).
        tolerance: relative periodicity required of the steady state; the adaptive period map is
            only smooth to about its rtol, so do not ask for much less than 100·rtol.
        forward_mode: make the adaptive saved cycle differentiable in forward mode
            (``jax.jacfwd``) instead of reverse mode.
        basis: optional fixed reduction basis of the arm, shape (n_dofs, n_modes), or
            ``"own"`` (the own modes with the derivative of their subspace; see
            :func:`jaxdobby.dobby.build_model`); default: the arm's own modes.
        lift_plan: the frame's lift sequence over the repeat (DESIGN §7): text "1100", a 0/1
            sequence or a float array (P,) (traced: vmappable over frames of equal P); None:
            plain weave (the closed form; "10" gives the same to round-off). The steady
            state, series and metrics then cover the repeat of P picks, and
            ``pick_metrics`` holds the per-pick ones. A concrete plan that never moves
            ("1", "00"…) is static: answered without dynamics, whatever ``method``
            (:mod:`jaxdobby.weave.static`: the equilibrium at the top or bottom of the stroke,
            constant over the repeat).
    """
    require_x64()
    machine = Machine.default() if machine is None else machine
    operating = OperatingPoint() if operating is None else operating
    lift_plan = check_lift_plan(lift_plan, machine)
    method, steps = resolve_method(machine, operating, method, steps, basis, lift_plan)
    options = dict(n_out=n_out, rtol=rtol, atol=atol, tolerance=tolerance,
                   forward_mode=forward_mode)
    if basis is None and options == _SIMULATE_DEFAULTS:
        shipped = shipped_simulation(machine, operating, lift_plan, method, steps)
        if shipped is not None:
            return shipped
    return _simulate(machine, operating, basis, lift_plan, method=method, steps=steps,
                     **options)


def check_lift_plan(lift_plan, machine: Machine):
    """The plan as :func:`simulate` takes it: None, or a float array (P,) (text and sequences
    parsed by :func:`jaxdobby.weave.plan.parse_plan`); a plan with the ``opposing`` warp law
    raises :class:`~jaxdobby.errors.InputError`."""
    if lift_plan is None:
        return None
    from .weave.plan import parse_plan

    if isinstance(lift_plan, jax.core.Tracer):
        plan = lift_plan
    else:
        plan = jnp.asarray(parse_plan(lift_plan if isinstance(lift_plan, str)
                                      else np.asarray(lift_plan)))
    if machine.warp_law != "restoring":
        raise InputError("lift_plan needs warp_law = 'restoring' (the 'opposing' law is defined "
                         "for plain weave only)")
    return plan


def _adaptive(model, x0, saveat, rtol, atol, adjoint):
    import diffrax  # the adaptive reference only: importing diffrax costs a run ~0.4 s

    k = model.n_modes
    return diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field), diffrax.Tsit5(), t0=0.0, t1=model.period, dt0=None,
        y0=(x0[:k], x0[k:]), args=model, saveat=saveat,
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=500_000, adjoint=adjoint, throw=False)


def _save(model, rigid, x):
    k = model.n_modes
    return flexible_outputs(model, rigid, x[:k], x[k:]), x


def _simulate_impl(machine, operating, basis, lift_plan=None, *, method, steps, n_out, rtol,
                   atol, tolerance, forward_mode, reverse_only=False):
    model = build_model(machine, operating, basis, lift_plan)
    k = model.n_modes
    x_rest = jnp.zeros(2 * k)
    motion = None
    if method == "rk4":
        table = rigid_table(model, steps)
        # The period map saves the outputs too (discarded here): the same compiled scan then
        # serves the shooting and the output cycle.
        shooting = periodic_state(lambda x: rk4_cycle(model, table, x, save=_save)[0], x_rest,
                                  tolerance=tolerance)
        x0 = shooting.state
        end, (flexible, states) = rk4_cycle(model, table, x0, save=_save)
        first_rigid = jax.tree.map(lambda a: a[0], table)
        first, _ = _save(model, first_rigid, x0)
        flexible = jax.tree.map(lambda a, b: jnp.concatenate([a[None], b]), first, flexible)
        ts = table.time[::2]
        solved = jnp.all(jnp.isfinite(states))
        num_steps = jnp.asarray(steps)
    elif method == "static":  # a plan that never moves: the equilibrium, no dynamics
        from .weave.static import static_cycle

        shooting, flexible, ts = static_cycle(model, PER_STEP * steps + 1, tolerance)
        x0 = end = shooting.state
        solved = jnp.all(jnp.isfinite(x0))
        num_steps = jnp.asarray(0)
    elif method == "collocation":
        dense = steady_cycle(model, steps, tolerance=tolerance, reverse_only=reverse_only)
        shooting, x0, end, ts = dense.shooting, dense.shooting.state, dense.end, dense.time
        flexible = dense.outputs  # the rigid motion's outputs included
        motion = dense.motion
        solved = dense.reachable & jnp.all(jnp.isfinite(end))
        num_steps = jnp.asarray(steps)
    else:
        import diffrax

        def period_map(x):
            sol = _adaptive(model, x, diffrax.SaveAt(t1=True), rtol, atol, diffrax.ForwardMode())
            return jnp.concatenate([sol.ys[0][-1], sol.ys[1][-1]])

        shooting = periodic_state(period_map, x_rest, tolerance=tolerance)
        x0 = shooting.state
        ts = jnp.linspace(0.0, model.period, n_out)

        def save(t, y, args):
            return _save(args, rigid_state(args, t), jnp.concatenate(y))

        adjoint = diffrax.ForwardMode() if forward_mode else diffrax.RecursiveCheckpointAdjoint()
        sol = _adaptive(model, x0, diffrax.SaveAt(ts=ts, fn=save), rtol, atol, adjoint)
        flexible, states = sol.ys
        end = states[-1]
        solved = sol.result == diffrax.RESULTS.successful
        num_steps = sol.stats["num_accepted_steps"]
    periodicity = relative_residual(x0, end)
    if method != "collocation":
        flexible = dict(flexible, **rigid_outputs(model, ts))
    series = Timeseries(t=ts, **flexible)
    picks = {}
    if lift_plan is not None:
        picks = dict(pick_metrics(series, model.lift_plan, model.chain.dwell),
                     lift_plan=model.lift_plan)
    return Simulation(
        model=model, series=series, metrics=cycle_metrics(series), pick_metrics=picks,
        natural_frequencies=coupled_frequencies(model), shooting=shooting,
        periodicity=periodicity,
        converged=shooting.converged & (periodicity <= tolerance) & solved,
        num_steps=num_steps, arm_motion=motion,
    )


_simulate = eqx.filter_jit(_simulate_impl)

_SIMULATE_DEFAULTS = dict(n_out=3001, rtol=1e-8, atol=1e-12, tolerance=1e-6, forward_mode=False)
""":func:`simulate`'s defaults of the options the command line does not set."""


def report_arrays(run: Simulation, stress=None) -> dict[str, Array]:
    """Every array the run's report needs (:func:`summary_of`, the time series, the arm's
    stress), by name: a flat dict of arrays, what :func:`stored_report`'s stored program
    returns. ``stress``: the run's :func:`~jaxdobby.stress.cycle.run_stress` if computed
    already."""
    from .stress.cycle import run_stress, stress_arrays

    stress = run_stress(run) if stress is None else stress
    model = run.model
    out = {f"metric.{k}": v for k, v in run.metrics.items()}
    out.update({f"series.{k}": getattr(run.series, k) for k in Timeseries.__dataclass_fields__})
    out.update(speed=model.operating.speed, warp_force=model.operating.warp_force,
               thickness=model.machine.arm.thickness, stroke=model.stroke,
               natural_frequencies=run.natural_frequencies,
               arm_frequencies=model.body.frequencies_hz, converged=run.converged,
               periodicity=run.periodicity, iterations=run.shooting.iterations)
    out.update(validity_arrays(run))
    out.update({f"pick.{k}": v for k, v in run.pick_metrics.items()})
    out.update(stress_arrays(stress))
    return out


def summary_of(arrays: dict, machine: Machine) -> dict[str, float | list | bool]:
    """The summary in the users' units (the keys of ``jaxdobby simulate --json``) from
    :func:`report_arrays` of a run of ``machine``."""
    from .stress.summary import stress_summary_of, warning_entries

    m = {k.removeprefix("metric."): float(v) for k, v in arrays.items()
         if k.startswith("metric.")}
    mm = 1e3
    out = {
        "speed_rpm": float(arrays["speed"]) * 60.0 / (2.0 * np.pi),
        "warp_force_n": float(arrays["warp_force"]),
        "thickness_mm": float(arrays["thickness"]) * mm,
        "n_modes": int(machine.n_modes),
        "stroke_mm": float(arrays["stroke"]) * mm,
        "coupling": machine.coupling,
        "warp_law": machine.warp_law,
        "deviation_min_mm": m["deviation_min"] * mm,
        "deviation_max_mm": m["deviation_max"] * mm,
        "deviation_pp_mm": m["deviation_pp"] * mm,
        "link_point_deviation_x_mm": m["link_point_deviation_x"] * mm,
        "link_point_deviation_y_mm": m["link_point_deviation_y"] * mm,
        "velocity_deviation_amp_m_s": m["velocity_deviation_amp"],
        "acceleration_amp_m_s2": m["acceleration_amp"],
        "acceleration_rigid_amp_m_s2": m["acceleration_rigid_amp"],
        "acceleration_deviation_amp_m_s2": m["acceleration_deviation_amp"],
        "ring_link_force_max_n": m["ring_link_force_max"],
        "link11_force_max_n": m["link11_force_max"],
        "natural_frequencies_hz": [float(f) for f in arrays["natural_frequencies"]],
        "arm_frequencies_hz": [float(f) for f in arrays["arm_frequencies"]],
        "converged": bool(arrays["converged"]),
        "periodicity_residual": float(arrays["periodicity"]),
        "newton_iterations": int(arrays["iterations"]),
        "warnings": warnings_of(arrays, _SIMULATE_DEFAULTS["tolerance"]),
        **_pick_summary(arrays),
        **stress_summary_of(arrays, machine.arm),
    }
    out["warnings"] = out["warnings"] + warning_entries(out)
    return out


def _pick_summary(arrays: dict) -> dict:
    """The lift plan's keys of the summary (none in plain weave): the plan, its picks, whether
    it never moves (``static``: the equilibrium, :mod:`jaxdobby.weave.static`), and per pick
    whether the frame moves, the deviation at shed-open and the dwell vibration [mm]."""
    if "pick.lift_plan" not in arrays:
        return {}
    from .weave.plan import is_static, plan_text

    mm = 1e3
    plan = np.asarray(arrays["pick.lift_plan"])
    return {
        "lift_plan": plan_text(plan),
        "picks": int(plan.shape[0]),
        "static": bool(is_static(plan)),
        "moves": [bool(v > 0.5) for v in np.asarray(arrays["pick.moves"])],
        "shed_deviation_mm": [float(v) * mm for v in np.asarray(arrays["pick.shed_deviation"])],
        "dwell_vibration_pp_mm": [float(v) * mm
                                  for v in np.asarray(arrays["pick.dwell_vibration"])],
        "dwell_vibration_max_mm": float(arrays["pick.dwell_vibration_max"]) * mm,
    }


def summary(run: Simulation, stress=None) -> dict[str, float | list | bool]:
    """The run's summary in the users' units (the keys of ``jaxdobby simulate --json``), the
    arm's stress included (``stress``: the run's :func:`~jaxdobby.stress.cycle.run_stress` if
    computed already)."""
    return summary_of(report_arrays(run, stress), run.model.machine)


def stored_report(setup, options, *, directory=None, ship=None
                  ) -> tuple[dict, Timeseries, object]:
    """(summary, time series, arm stress :class:`~jaxdobby.stress.cycle.CycleStress`) of
    ``simulate(setup.machine, setup.operating, method=…, steps=…)``
    as the command line reports them, through its two stored programs
    (:func:`jaxdobby.programs.stored_program`): a later run of the same configuration — the same
    sizes, laws and method; any float values — reads the traced programs from ``directory``
    (or the package's shipped ones) instead of tracing it.

    Args:
        setup: :class:`~jaxdobby.parameters.Setup` (machine and operating point).
        options: :class:`~jaxdobby.config.RunOptions` (method, steps).
        directory: where to store and look for programs; None: only the shipped ones.
        ship: where to write the two compiled executables (``python -m jaxdobby.programs``;
            :func:`jaxdobby.programs.compile_together`).
    """
    from .stress.cycle import stress_of_arrays

    arrays = stored_report_arrays(setup, options, directory=directory, ship=ship)
    series = Timeseries(**{k.removeprefix("series."): v for k, v in arrays.items()
                           if k.startswith("series.")})
    return summary_of(arrays, setup.machine), series, stress_of_arrays(arrays)


def stored_report_arrays(setup, options, *, directory=None, ship=None
                         ) -> dict[str, np.ndarray]:
    """The flat report arrays (:func:`report_arrays`, NumPy) behind :func:`stored_report`, from
    the same stored programs compiled with the same options (arguments as there): callers that
    need the raw arrays share the command line's compiled programs.

    Two programs (:func:`report_programs`): the run, and the report of the run (the arm's
    stress and the validity checks). XLA compiles them side by side
    (:func:`jaxdobby.programs.compile_together`), and they run one after the other."""
    compiled, args = _report_compiled(setup, options, directory, ship)
    run_c, report_c = compiled
    return jax.device_get(report_c(*run_c(*args)))


def compile_reports(setups, options, *, directory=None) -> list:
    """Get the programs of :func:`stored_report_arrays` ready for every setup of ``setups``
    (configurations of their own: a sweep of sizes), so that XLA compiles one while the next
    is traced: each configuration's programs are read or traced here, one after the other
    (Python work), and compiled in a background thread (XLA's work, outside Python's lock);
    :func:`stored_report_arrays` then waits for its own. ``jaxdobby sweep modes``: see
    :mod:`jaxdobby.sweep`. Returns the compilations started (``concurrent.futures.Future``):
    a caller that stops early (an interrupt) cancels those not yet running with
    :func:`cancel_compiles`, so that the process does not finish them before it exits."""
    from concurrent.futures import ThreadPoolExecutor

    from . import programs

    pool = ThreadPoolExecutor(2, thread_name_prefix="jaxdobby-compile")
    started = []
    try:
        for setup in setups:
            memo, programs_args, _ = _report_stored(setup, options, directory)
            if memo not in _REPORT_PROGRAMS:
                started.append((memo, pool.submit(programs.compile_together, programs_args,
                                                  programs.ONE_SHOT)))
                _REPORT_PROGRAMS[memo] = started[-1][1]
    except BaseException:
        cancel_compiles(started)
        raise
    finally:
        pool.shutdown(wait=False)
    return started


def cancel_compiles(started) -> None:
    """Cancel the compilations of :func:`compile_reports` that have not started, and forget
    every one that did not finish (a later call compiles it anew)."""
    for memo, future in started:
        future.cancel()
        finished = future.done() and not future.cancelled() and future.exception() is None
        if not finished and _REPORT_PROGRAMS.get(memo) is future:
            del _REPORT_PROGRAMS[memo]


def _report_stored(setup, options, directory, anew: bool = False):
    """(memo key, [(exported run, args), (exported report, its args)], the run's arrays) of
    :func:`stored_report_arrays`: the stored programs read or traced, not compiled (None where
    the process has them compiled already, unless ``anew``)."""
    from . import programs

    (name_run, run_fn, args, key), (name_report, report_fn, key_report) = report_programs(
        setup, options)
    # compiled once per process and configuration: a sweep of float values runs them again
    memo = programs.process_memo(programs.program_key(name_run, key, args), key_report,
                                 directory=directory)
    if memo in _REPORT_PROGRAMS and not anew:
        return memo, None, args
    run = programs.stored_program(name_run, run_fn, args, static_key=key, directory=directory)
    leaves = [jax.ShapeDtypeStruct(a.shape, a.dtype) for a in run.out_avals]
    report = programs.stored_program(name_report, report_fn, leaves, static_key=key_report,
                                     directory=directory)
    return memo, [(run, args), (report, leaves)], args


def _report_compiled(setup, options, directory, ship):
    """(the compiled run and report of :func:`stored_report_arrays`, the run's arrays)."""
    from concurrent.futures import Future

    from . import programs

    memo, programs_args, args = _report_stored(setup, options, directory,
                                               anew=ship is not None)
    compiled = None if ship is not None else _REPORT_PROGRAMS.get(memo)
    if isinstance(compiled, Future):
        compiled = _REPORT_PROGRAMS[memo] = compiled.result()
    if compiled is None:
        compiled = programs.compile_together(programs_args, programs.ONE_SHOT, ship=ship)
        if ship is None:
            _REPORT_PROGRAMS[memo] = compiled
    return compiled, args


_REPORT_PROGRAMS: dict = {}
"""The compiled run and report programs of :func:`stored_report_arrays`, by configuration."""


def report_programs(setup, options) -> tuple:
    """:func:`stored_report`'s two programs, as arguments of
    :func:`jaxdobby.programs.stored_program`: ((name, function of the flat arrays, the arrays,
    static_key) of the run, whose outputs are the arrays of its
    :class:`Simulation`, in order; (name, function of those arrays, static_key) of the report
    of the run, which returns :func:`report_arrays`)."""
    require_x64()
    simulation, leaves, key = _run_of_options(setup, options)
    specs = [jax.ShapeDtypeStruct(jnp.shape(a), jnp.result_type(a)) for a in leaves]
    structure = []  # the Simulation's (array structure, non-array part), once known

    def run(*values):
        arrays, rest = eqx.partition(simulation(*values), eqx.is_array)
        structure.append((jax.tree.structure(arrays), rest))
        return jax.tree.leaves(arrays)

    def report(*run_values):
        if not structure:  # the run's program was read from disk: trace its shapes alone
            shape = eqx.filter_eval_shape(simulation, *specs)
            arrays, rest = eqx.partition(shape, lambda x: isinstance(x, jax.ShapeDtypeStruct))
            structure.append((jax.tree.structure(arrays), rest))
        tree, rest = structure[-1]
        return report_arrays(eqx.combine(jax.tree.unflatten(tree, run_values), rest))

    return (RUN, run, leaves, key), ("simulate-report", report, key)


RUN = "simulate"
"""The name of the command line's run program (:func:`report_programs`)."""


def _run_of_options(setup, options):
    """:func:`_run_of` for ``setup`` run with ``options``
    (:class:`~jaxdobby.config.RunOptions`: method, steps, lift plan)."""
    plan = check_lift_plan(getattr(options, "lift_plan", None), setup.machine)
    method, steps = resolve_method(setup.machine, setup.operating, options.method,
                                   options.steps, lift_plan=plan)
    return _run_of(setup.machine, setup.operating, plan, method, steps)


def _run_of(machine, operating, plan, method, steps):
    """The command line's run as a function of flat arrays: (simulation: the arrays → the
    :class:`Simulation` of :func:`simulate`'s defaults, the arrays of ``machine``,
    ``operating`` and ``plan``, the static key of everything else)."""
    dynamic, static = eqx.partition((machine, operating, plan), eqx.is_array)
    leaves, tree = jax.tree.flatten(dynamic)

    def simulation(*values):
        m, o, p = eqx.combine(jax.tree.unflatten(tree, values), static)
        return _simulate_impl(m, o, None, p, method=method, steps=steps, **_SIMULATE_DEFAULTS)

    return simulation, leaves, repr((static, tree, method, steps, _SIMULATE_DEFAULTS))


STRUCTURE = ".structure"
"""Suffix of the file, next to a shipped run program, that holds the shapes of its
:class:`Simulation` (:func:`write_structure`)."""


def write_structure(directory, setup, options) -> None:
    """Write, next to the run program of ``setup`` and ``options`` in ``directory``, the
    :class:`Simulation` it returns with ``jax.ShapeDtypeStruct`` leaves (a pickle; what
    :func:`shipped_simulation` rebuilds the result from without tracing the run: ~2 s). For
    ``python -m jaxdobby.programs``."""
    import pickle

    from .programs import program_key

    simulation, leaves, key = _run_of_options(setup, options)
    shape = eqx.filter_eval_shape(simulation, *leaves)
    path = (directory / program_key(RUN, key, leaves)).with_suffix(STRUCTURE)
    path.write_bytes(pickle.dumps(shape))


def shipped_simulation(machine, operating, plan, method, steps) -> Simulation | None:
    """:func:`simulate`'s result (its default options) from the compiled executable of the
    command line's run that the package ships for this configuration
    (:mod:`jaxdobby.programs`: the default sizes, laws and method, on the CPUs it ships for):
    nothing traced or compiled, ~1 s in a new process instead of ~10 s. None where there is no
    such executable (another configuration, another CPU, ``JAXDOBBY_SHIPPED_EXECUTABLES=off``)
    or where ``simulate`` is being traced (``jax.jit``, ``jax.grad``, ``jax.vmap``): then
    :func:`simulate` traces and compiles as usual. The executable is compiled as the command
    line's (:data:`jaxdobby.programs.ONE_SHOT`, instruction set capped at AVX2): its results
    equal the traced program's to round-off (``tests/test_programs.py``); it runs in ~0.05 s
    (0.02 s for a program compiled here at full optimisation)."""
    if method == "adaptive":
        return None  # never exported (host callbacks)
    from . import programs

    _, leaves, key = _run_of(machine, operating, plan, method, steps)
    if any(isinstance(a, jax.core.Tracer) for a in leaves) or not programs.executables_usable():
        return None
    found = _shipped_run(str(programs.SHIPPED), key,
                         tuple((jnp.shape(a), str(jnp.result_type(a))) for a in leaves))
    if found is None:
        return None
    compiled, arrays, rest = found
    return eqx.combine(jax.tree.unflatten(arrays, compiled(*leaves)), rest)


@functools.cache
def _shipped_run(shipped: str, key: str, shapes: tuple):
    """(compiled run, tree of its arrays, the rest of its :class:`Simulation`) of the shipped
    executable for ``key`` and argument ``shapes``, loaded once per process; or None.
    ``shipped``: the folder of shipped programs (:data:`jaxdobby.programs.SHIPPED`, read by
    the caller, so that a test that moves it is not answered from this cache)."""
    import pickle

    from .programs import ONE_SHOT, shipped_executable, shipped_program, together_keys

    specs = [jax.ShapeDtypeStruct(shape, dtype) for shape, dtype in shapes]
    exported, path = shipped_program(RUN, key, specs)
    path = path.with_suffix(STRUCTURE)
    if exported is None or not path.exists():
        return None
    compiled = shipped_executable(together_keys([(exported, specs)], ONE_SHOT)[0])
    if compiled is None:
        return None
    shape = pickle.loads(path.read_bytes())  # the package's own file
    arrays, rest = eqx.partition(shape, lambda x: isinstance(x, jax.ShapeDtypeStruct))
    return compiled, jax.tree.structure(arrays), rest
