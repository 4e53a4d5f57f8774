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
  (:mod:`jaxdobby.batch.dense`, the equations of the batch evaluator), outputs from the
  collocation polynomial at four times per step — tens of milliseconds per run;
* ``method="rk4"`` (the default for the one-way variant): fixed-step RK4 on a precomputed table
  of the rigid mechanism (:mod:`jaxdobby.fixed_step`), a step from the highest mode
  (Δt = 1.5/ω_max: thousands per cycle), outputs at every step;
* ``method="adaptive"``: diffrax's Tsitouras 5(4) with a PID step-size controller, outputs at
  ``n_out`` times — the reference the fast paths are tested against.

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

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._x64 import require_x64
from .batch import DEFAULT_STEPS as COLLOCATION_STEPS
from .batch.dense import steady_cycle
from .dobby import DobbyModel, build_model, rigid_state, vector_field
from .errors import InputError
from .fixed_step import rigid_table, rk4_cycle, steps_per_cycle
from .machine import Machine, OperatingPoint
from .metrics import cycle_metrics
from .outputs import Timeseries, coupled_frequencies, flexible_outputs, rigid_outputs
from .steady_state import ShootingResult, periodic_state, relative_residual

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
    """

    model: DobbyModel
    series: Timeseries
    metrics: dict[str, Array]
    natural_frequencies: Array
    shooting: ShootingResult
    periodicity: Array
    converged: Array
    num_steps: Array


def default_method(machine: Machine) -> str:
    """The integrator :func:`simulate` uses unless told: collocation for the two-way coupled
    model, RK4 for the one-way variant (which the collocation path does not solve)."""
    return "collocation" if machine.coupling == "two-way" else "rk4"


def resolve_method(machine: Machine, operating: OperatingPoint, method: str | None = None,
                   steps: int | None = None, basis: Array | str | None = None
                   ) -> tuple[str, int | None]:
    """(method, steps) as :func:`simulate` runs them: the default method for the coupling, the
    default step count of the fixed-step methods; raises ``ValueError`` for a method that does
    not exist or does not solve this model (:class:`~jaxdobby.errors.InputError`)."""
    method = default_method(machine) if method is None else method
    if method not in METHODS:
        raise InputError(f"method = {method!r} is not valid: use one of {', '.join(METHODS)}")
    if method == "collocation":
        if machine.coupling != "two-way":
            raise InputError("method = 'collocation' solves the two-way coupled model: use rk4 "
                             f"or adaptive for coupling = {machine.coupling!r}")
        return method, COLLOCATION_STEPS if steps is None else steps
    if method == "rk4" and steps is None:
        steps = default_steps(machine, operating, basis)
    return method, steps


def default_steps(machine: Machine, operating: OperatingPoint,
                  basis: Array | str | None = None) -> int:
    """RK4 steps per cycle for concrete parameters (Δt = 1.5/ω_max of the arm's modes)."""
    model = eqx.filter_jit(build_model)(machine, operating, basis)
    return steps_per_cycle(float(jnp.max(model.body.frequencies_hz)), float(model.period))


def simulate(machine: Machine | None = None, operating: OperatingPoint | None = None, *,
             method: str | None = None, steps: int | None = None, n_out: int = 3001, rtol=1e-8,
             atol=1e-12, tolerance=1e-6, forward_mode: bool = False,
             basis: Array | str | None = None) -> Simulation:
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
    """
    require_x64()
    machine = Machine.default() if machine is None else machine
    operating = OperatingPoint() if operating is None else operating
    method, steps = resolve_method(machine, operating, method, steps, basis)
    return _simulate(machine, operating, basis, method=method, steps=steps, n_out=n_out,
                     rtol=rtol, atol=atol, tolerance=tolerance, forward_mode=forward_mode)


def _adaptive(model, x0, saveat, rtol, atol, adjoint):
    k = model.n_modes
    return diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field), diffrax.Tsit5(), t0=0.0, t1=model.period, dt0=None,
        y0=(x0[:k], x0[k:]), args=model, saveat=saveat,
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=500_000, adjoint=adjoint, throw=False)


def _save(model, rigid, x):
    k = model.n_modes
    return flexible_outputs(model, rigid, x[:k], x[k:]), x


@eqx.filter_jit
def _simulate(machine, operating, basis, *, method, steps, n_out, rtol, atol, tolerance,
              forward_mode):
    model = build_model(machine, operating, basis)
    k = model.n_modes
    x_rest = jnp.zeros(2 * k)
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
    elif method == "collocation":
        dense = steady_cycle(model, steps, tolerance=tolerance)
        shooting, x0, end, ts = dense.shooting, dense.shooting.state, dense.end, dense.time
        rigid = jax.vmap(lambda t: rigid_state(model, t))(ts)
        flexible = jax.vmap(lambda r, q, qd: flexible_outputs(model, r, q, qd))(
            rigid, dense.q, dense.qdot)
        solved = dense.reachable & jnp.all(jnp.isfinite(end))
        num_steps = jnp.asarray(steps)
    else:
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
    series = Timeseries(t=ts, **flexible, **rigid_outputs(model, ts))
    return Simulation(
        model=model, series=series, metrics=cycle_metrics(series),
        natural_frequencies=coupled_frequencies(model), shooting=shooting,
        periodicity=periodicity,
        converged=shooting.converged & (periodicity <= tolerance) & solved,
        num_steps=num_steps,
    )


def summary(run: Simulation, stress=None) -> dict[str, float | list | bool]:
    """The run's summary in the users' units (the keys of ``jaxdobby simulate --json``); the
    arm's stress keys from :func:`jaxdobby.stress.summary.stress_summary` (``stress``: its
    :func:`~jaxdobby.stress.cycle.run_stress`, computed here when not given)."""
    from .stress.summary import stress_summary

    m = {k: float(v) for k, v in run.metrics.items()}
    model = run.model
    mm = 1e3
    return {
        "speed_rpm": float(model.operating.speed) * 60.0 / (2.0 * np.pi),
        "warp_force_n": float(model.operating.warp_force),
        "thickness_mm": float(model.machine.arm.thickness) * mm,
        "n_modes": int(model.n_modes),
        "stroke_mm": float(model.stroke) * mm,
        "coupling": model.machine.coupling,
        "warp_law": model.machine.warp_law,
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
        "natural_frequencies_hz": [float(f) for f in run.natural_frequencies],
        "arm_frequencies_hz": [float(f) for f in model.body.frequencies_hz],
        "converged": bool(run.converged),
        "periodicity_residual": float(run.periodicity),
        "newton_iterations": int(run.shooting.iterations),
        **stress_summary(run, stress),
    }
