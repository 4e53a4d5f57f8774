"""The periodic steady state with ``scipy.integrate.solve_ivp``: the same definition as jaxdobby.

jaxdobby's steady state (:mod:`jaxdobby.steady_state`) is the state x₀ = (q, q̇) at t = 0 that one
heald-frame cycle (two picks) of integration returns unchanged, F(x₀) = x₀, to a relative
residual ``tolerance`` (blockwise ‖F(x) − x‖∞/‖F(x)‖∞, :func:`relative_residual`), starting
from the arm at rest in its rigid motion (x = 0). It finds it by Newton–chord shooting: the
monodromy matrix ∂F/∂x once, at x = 0, by forward-mode autodiff (one solve carrying 2k
tangents), then plain period maps.

scipy has no forward-mode derivative of a solve, so two counterparts, both here:

* ``"newton"`` — the same Newton–chord iteration with the monodromy by forward finite
  differences: 2k extra period maps (perturbations of 1 % of each block's amplitude in F(0); the
  adaptive solvers make F smooth only to about their rtol, so a larger step keeps the
  derivative's noise ~100·rtol, and the chord method needs only an approximate derivative).
  Cost: 1 + 2k + (iterations) period maps. The algorithm a scipy user copies from jaxdobby.
* ``"cycles"`` — integrate cycle after cycle until the residual is below the tolerance. Needs
  no derivative, but its cost follows the slowest decay of the start-up transient: measured
  here, one mode had not reached 1e-6 after 60 cycles, and the four-mode reference (rtol
  1e-12, to 1e-9) was still cycling when stopped after 12 CPU-minutes.
  The algorithm a scipy user writes first; the benchmarks use ``"newton"``
  (:func:`default_strategy`).

Both stop on the same residual as jaxdobby, so the state they return is as periodic as
jaxdobby's. Then one more cycle from x₀, sampled at the same
times as jaxdobby's outputs (``t_eval``: the solvers' own dense output), gives the series and
the metrics (:func:`benchmarks.scipy_model.cycle_metrics`).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from scipy.integrate import solve_ivp

from .scipy_model import NumpyDobby, cycle_metrics

IMPLICIT = ("Radau", "BDF", "LSODA")
"""Methods that use a Jacobian (given, or by finite differences)."""


def relative_residual(x, fx) -> float:
    """max over the q and q̇ blocks of ‖F(x) − x‖∞/‖F(x)‖∞ (jaxdobby's definition)."""
    k = x.shape[0] // 2
    r = fx - x
    tiny = np.finfo(float).tiny
    return float(max(np.max(np.abs(r[:k])) / (np.max(np.abs(fx[:k])) + tiny),
                     np.max(np.abs(r[k:])) / (np.max(np.abs(fx[k:])) + tiny)))


@dataclasses.dataclass
class Problem:
    """One right-hand side for ``solve_ivp``: its function, Jacobian and the model's numpy form.

    Attributes:
        name: ``"numpy"`` (plain numpy RHS, Jacobian by scipy's finite differences, vectorised
            for them) or ``"jitted"`` (``jax.jit`` RHS and ``jax.jacfwd`` Jacobian).
        fun: f(t, y) → dy/dt.
        jac: J(t, y) or None (finite differences).
        fun_vectorized: f(t, y) for y of shape (n, m), or None; given to the implicit methods
            (scipy's ``vectorized=True``: one call for a whole finite-difference Jacobian).
        numpy_model: :class:`NumpyDobby` for outputs and metrics (shared by both variants).
    """

    name: str
    fun: object
    jac: object
    fun_vectorized: object
    numpy_model: NumpyDobby

    @property
    def period(self) -> float:
        return self.numpy_model.period


@dataclasses.dataclass
class Counter:
    period_maps: int = 0
    nfev: int = 0
    njev: int = 0
    nlu: int = 0

    def add(self, sol):
        self.period_maps += 1
        self.nfev += int(sol.nfev)
        self.njev += int(sol.njev)
        self.nlu += int(sol.nlu)


def integrate_cycle(problem: Problem, x, method, rtol, atol, t_eval=None, counter=None,
                    dense_output=False):
    """One cycle of ``solve_ivp`` from state x; raises if the solver fails."""
    fun, options = problem.fun, {"method": method, "rtol": rtol, "atol": atol}
    if method in IMPLICIT and problem.jac is not None:
        options["jac"] = problem.jac
    elif method in ("Radau", "BDF") and problem.fun_vectorized is not None:
        fun, options["vectorized"] = problem.fun_vectorized, True
    sol = solve_ivp(fun, (0.0, problem.period), np.asarray(x, dtype=float),
                    t_eval=t_eval, dense_output=dense_output, **options)
    if not sol.success:
        raise RuntimeError(f"solve_ivp {method} failed: {sol.message}")
    if counter is not None:
        counter.add(sol)
    return sol


def _end(sol):
    return sol.y[:, -1]


def _try_map(period_map, x):
    """F(x), or None where the cycle cannot be integrated from x (the chain leaves its
    workspace: a singular mass matrix, a failed solve, non-finite values)."""
    try:
        with np.errstate(all="ignore"):
            fx = period_map(x)
    except (RuntimeError, np.linalg.LinAlgError, FloatingPointError, ValueError):
        return None
    return fx if np.all(np.isfinite(fx)) else None


def newton_chord(period_map, x0, tolerance, max_iterations=8, step=1e-2, max_halvings=8):
    """jaxdobby's Newton–chord iteration with a finite-difference monodromy at x0.

    Safeguarded: a chord step from which the cycle cannot be integrated (with an approximate
    monodromy near a resonance, I − Φ is nearly singular and the full step can throw the arm out
    of the chain's workspace) is halved until it can, at most ``max_halvings`` times.
    """
    import scipy.linalg

    n = x0.shape[0]
    k = n // 2
    fx = period_map(x0)
    scale = np.concatenate([np.full(k, np.max(np.abs(fx[:k]))), np.full(k, np.max(np.abs(fx[k:])))])
    h = step * np.where(scale > 0.0, scale, 1.0)
    monodromy = np.empty((n, n))
    for j in range(n):
        xj = x0.copy()
        xj[j] += h[j]
        monodromy[:, j] = (period_map(xj) - fx) / h[j]
    lu = scipy.linalg.lu_factor(np.eye(n) - monodromy)
    residual = relative_residual(x0, fx)
    x, iterations = x0, 1
    while True:
        dx = scipy.linalg.lu_solve(lu, fx - x)
        for _ in range(max_halvings + 1):
            new = _try_map(period_map, x + dx)
            if new is not None:
                break
            dx = 0.5 * dx
        else:
            raise RuntimeError("Newton-chord: no step from which the cycle can be integrated")
        x, fx = x + dx, new
        residual = relative_residual(x, fx)
        iterations += 1
        if iterations >= max_iterations or residual <= tolerance:
            break
    # x is the state whose residual was measured last; the caller integrates one more cycle
    # from it (as jaxdobby returns the start state of its last cycle).
    return x, residual, iterations


def cycles(period_map, x0, tolerance, max_cycles=60):
    """x ← F(x) until the relative residual is below the tolerance."""
    x, residual, n = x0, np.inf, 0
    while residual > tolerance and n < max_cycles:
        fx = period_map(x)
        residual = relative_residual(x, fx)
        x, n = fx, n + 1
    return x, residual, n


STRATEGIES = {"newton": newton_chord, "cycles": cycles}


def default_strategy(n_modes: int) -> str:
    """``"newton"``: its cost is bounded (1 + 2k + a few period maps) where cycling's depends on
    the slowest decay of the start-up transient — measured: with one mode the residual was still
    1e-6 after 60 cycles, and the default 4-mode arm did not reach 1e-9 in 60 cycles at rtol
    1e-12 either. (``n_modes`` kept for callers that may want to choose by size.)"""
    del n_modes
    return "newton"


@dataclasses.dataclass
class SteadyRun:
    """A scipy steady-state run: the state, its metrics, cost counters and wall time [s]."""

    method: str
    rhs: str
    strategy: str
    rtol: float
    atol: float
    state: np.ndarray
    residual: float
    periodicity: float
    converged: bool
    metrics: dict
    counter: Counter
    seconds: float
    solution: object = None

    def record(self) -> dict:
        return {"method": self.method, "rhs": self.rhs, "strategy": self.strategy, "rtol": self.rtol,
                    "atol": self.atol, "residual": self.residual, "periodicity": self.periodicity,
                    "converged": self.converged, "metrics": self.metrics, "seconds": self.seconds,
                    "period_maps": self.counter.period_maps, "nfev": self.counter.nfev,
                    "njev": self.counter.njev, "nlu": self.counter.nlu}


def steady_state(problem: Problem, method: str, rtol: float, atol: float, t_out, *,
                 strategy="cycles", tolerance=1e-6, dense_output=False) -> SteadyRun:
    """Periodic steady state, then one sampled cycle and its metrics, timed end to end.

    ``t_out``: the output times of the sampled cycle (the metrics are taken over them).
    ``dense_output``: keep the sampled cycle's interpolant (``SteadyRun.solution``, for a
    reference evaluated on other grids, :func:`metrics_on`).
    """
    counter = Counter()
    start = time.perf_counter()

    def period_map(x):
        return _end(integrate_cycle(problem, x, method, rtol, atol, counter=counter))

    k = problem.numpy_model.n_modes
    x0, residual, _ = STRATEGIES[strategy](period_map, np.zeros(2 * k), tolerance)
    sol = integrate_cycle(problem, x0, method, rtol, atol, t_eval=t_out, counter=counter,
                          dense_output=dense_output)
    series = problem.numpy_model.outputs(sol.t, sol.y.T)
    metrics = cycle_metrics(series)
    seconds = time.perf_counter() - start
    periodicity = relative_residual(x0, sol.y[:, -1])
    return SteadyRun(method=method, rhs=problem.name, strategy=strategy, rtol=rtol, atol=atol,
                     state=x0, residual=residual, periodicity=periodicity,
                     converged=bool(residual <= tolerance and periodicity <= tolerance),
                     metrics=metrics, counter=counter, seconds=seconds,
                     solution=sol.sol if dense_output else None)


def metrics_on(run: SteadyRun, numpy_model: NumpyDobby, t) -> dict:
    """The metrics of a dense-output run re-sampled at the times ``t`` (a reference on another
    run's output grid, so that comparing metrics measures integration error, not sampling)."""
    t = np.asarray(t, dtype=float)
    return cycle_metrics(numpy_model.outputs(t, run.solution(t).T))


def numpy_problem(numpy_model: NumpyDobby) -> Problem:
    """The plain-numpy variant (scipy's finite-difference Jacobian, vectorised)."""
    return Problem("numpy", numpy_model.rhs, None, numpy_model.rhs_vectorized, numpy_model)


def jitted_problem(model, numpy_model: NumpyDobby) -> Problem:
    """The jitted variant: jaxdobby's vector field and its Jacobian under ``jax.jit``."""
    from .scipy_model import jitted_rhs

    fun, jac = jitted_rhs(model)
    return Problem("jitted", fun, jac, None, numpy_model)


_BUILD = None


def build(setup):
    """jaxdobby's model of a :class:`~jaxdobby.parameters.Setup` (jitted once per process) and
    its numpy form: the modal matrices both sides share."""
    global _BUILD
    if _BUILD is None:
        import equinox as eqx

        from jaxdobby.dobby import build_model

        _BUILD = eqx.filter_jit(build_model)
    model = _BUILD(setup.machine, setup.operating)
    return model, NumpyDobby.from_model(model)


def solve_setup(setup, *, rhs="numpy", method="RK45", rtol=1e-6, atol=None, n_out=3001,
                tolerance=1e-6, strategy=None) -> SteadyRun:
    """Build and solve one setup with scipy: the scipy user's per-sample work, end to end
    (``seconds`` includes building the model). ``atol`` defaults to 1e-4·rtol (the modal
    coordinates are ~1e-5 m scaled; cf. jaxdobby's adaptive default rtol 1e-8, atol 1e-12)."""
    start = time.perf_counter()
    model, numpy_model = build(setup)
    problem = numpy_problem(numpy_model) if rhs == "numpy" else jitted_problem(model, numpy_model)
    atol = 1e-4 * rtol if atol is None else atol
    run = steady_state(problem, method, rtol, atol, np.linspace(0.0, numpy_model.period, n_out),
                       tolerance=tolerance,
                       strategy=strategy or default_strategy(numpy_model.n_modes))
    run.seconds = time.perf_counter() - start
    return run
