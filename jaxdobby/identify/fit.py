"""Least squares through the periodic steady state: ``identify(setup, measurement, keys)``.

The weighted residuals of the measured channels c ∈ {acceleration, position},

    r_cj(u) = (m_c(t_j; u) − y_cj) / σ_c,

(model m from :mod:`jaxdobby.identify.model`, u = (z, φ, b)) are minimised by
Levenberg–Marquardt with the exact Jacobian, from several starts as one vmapped batch; the best
is kept. The steady cycle is the costly part and the measured times the many, so the work is
split: every outer iteration solves the steady cycle and its exact derivative on the model's
grid for each start (:func:`~jaxdobby.identify.model.cycle_grids`, forward mode through the
implicit-function derivative of the periodic state); the step is then the minimiser of the
residuals with the grid linearised in z, nonlinear in φ and b, damped by μ‖δ‖² — solved by
Gauss–Newton with a step-length search (:func:`~jaxdobby.identify.inner.gauss_newton`; cheap:
interpolation only, and on the residuals compressed from the m samples to the model's 2K
Fourier coefficients by one QR factorisation of the interpolation matrix,
:func:`~jaxdobby.identify.inner.compressed`). A start accepts its step when the true cost falls
(μ/3), else it shortens it (μ·10) (Moré, "The Levenberg–Marquardt
algorithm", 1978). At convergence the Jacobian of the linearised residuals at δ = 0 is the exact
Jacobian of r in (z, φ, b).

The channel scales σ_c are first the RMS of each measured channel (the position's about its
mean); with two channels the fit is repeated from its estimates with σ_c = that channel's
residual RMS (each channel weighs as its noise: the maximum-likelihood weights for white noise).

The time origin is found first, from the starting parameters: the weighted cross-correlation
Σ_j m(t_j/T + φ) y_j (means removed) is evaluated for every φ on the model's grid at once through
the data's Fourier sums D_k = Σ_j y_j e^{2πik t_j/T}, and its maximum starts φ — the residual has
a local minimum every few hundredths of a cycle.

Uncertainty (Seber & Wild, *Nonlinear Regression*, 1989, §2.1): with J the Jacobian of r at the
estimate, n residuals and P fitted unknowns (parameters and nuisances), the covariance of u is
C = s² (JᵀJ)⁻¹ with s² = ‖r‖²/(n − P); standard errors of θ follow by the delta method
(dθ/dz = θ for a log parameter). The correlation matrix is that of C over the parameters.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..config import RunOptions
from ..parameters import Setup
from .inner import Problem, full, inner, problem
from .measurement import Measurement
from .model import (MM, Parameterisation, cycle_grids, fourier, parameterisation,
                    solver_settings)

STEP_TOLERANCE = 1e-7
"""Converged: an accepted step below this in every z (a relative change of θ far below any
standard error a trace can give) …"""
COST_TOLERANCE = 1e-10
"""… or a cost decrease below this, relative."""
UNIDENTIFIABLE_CORRELATION = 0.99
UNIDENTIFIABLE_RELATIVE_ERROR = 1.0
"""A parameter is flagged not identifiable from the trace when |correlation| with another one
exceeds 0.99 or its standard error exceeds its estimate (log parameters: σ_z > 1, a factor e)."""


@dataclasses.dataclass
class Identified:
    """Result of :func:`identify` (SI values; ``keys`` name them in the users' terms).

    Attributes:
        keys: TOML keys of the fitted parameters.
        estimates, standard_errors: by key [SI].
        correlation: (p, p) correlation of the parameter estimates.
        phase: the time-origin shift as a fraction of the heald-frame cycle, in [0, 1).
        phase_error: its standard error [cycle fraction].
        position_offset: fitted offset of the position channel [m] (None: no such channel).
        residual_rms: by channel (``acceleration_m_s2``, ``position_mm``), in its unit.
        converged: the optimiser reported success and the estimate is finite.
        at_bound: keys of estimates on a bound.
        warnings: one line each (not identifiable parameters, bounds, convergence).
        setup: the identified machine at the operating point.
        fitted: (acceleration [m/s²], position [mm]) of the model at the measured times.
        jacobian: J of the weighted residuals in u at the estimate (for checks), shape
            (2·m, P): the acceleration rows, then the position rows, each padded to m samples
            with zero rows; the columns are ``unknowns``.
        covariance: C of u, (P, P) (the active unknowns; see ``unknowns``).
        unknowns: names of the columns of ``covariance``.
        starts: each start's final cost ½‖r‖².
        sigma: the channel scales σ_c of the weighted residuals (acceleration [m/s²],
            position [mm]).
    """

    keys: tuple[str, ...]
    estimates: dict[str, float]
    standard_errors: dict[str, float]
    correlation: np.ndarray
    phase: float
    phase_error: float
    position_offset: float | None
    residual_rms: dict[str, float]
    converged: bool
    at_bound: list[str]
    warnings: list[str]
    setup: Setup
    fitted: tuple[np.ndarray | None, np.ndarray | None]
    jacobian: np.ndarray
    covariance: np.ndarray
    unknowns: tuple[str, ...]
    starts: np.ndarray
    sigma: tuple[float, float]


def _starts(par: Parameterisation, starts: int, spread: float, seed: int) -> np.ndarray:
    """Starting z: the configuration's values (0), then ``starts − 1`` draws uniform in
    ±``spread``, clipped to the bounds."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(-spread, spread, (starts, len(par.names)))
    z[0] = 0.0
    return np.clip(z, par.lower, par.upper)


class _Lanes:
    """The outer Levenberg–Marquardt state of every start (numpy, lane-wise)."""

    def __init__(self, setup, par, method, steps, z, directory=None):
        self.setup, self.par, self.method, self.steps = setup, par, method, steps
        self.directory = directory
        self.data: Problem | None = None
        self.lower, self.upper = jnp.asarray(par.lower), jnp.asarray(par.upper)
        self.z = z
        self.coef, self.dcoef = self.grids(z)

    def grids(self, z):
        _, grid, dgrid = cycle_grids(self.setup, self.par.names, self.par.log, self.method,
                                     self.steps, jnp.asarray(z), directory=self.directory)
        return fourier(grid), jnp.moveaxis(fourier(jnp.moveaxis(dgrid, -1, -2)), -2, -1)

    def inner(self, coef, dcoef, z, mu, v0, scan=False):
        out = inner(coef, dcoef, jnp.asarray(z), jnp.asarray(mu), self.lower, self.upper,
                    jnp.asarray(v0), jnp.asarray(scan), self.data, directory=self.directory)
        return tuple(np.asarray(a) for a in out)

    def full(self, v0):
        out = full(self.coef, self.dcoef, jnp.asarray(self.z), self.lower, self.upper,
                   jnp.asarray(v0), self.data, directory=self.directory)
        return tuple(np.asarray(a) for a in out)


def _least_squares(lanes: _Lanes, max_iterations: int, progress=None):
    """Outer Levenberg–Marquardt on z (exact Jacobian of the steady cycle), every lane at once:
    the inner linearised step (with φ and b) from :func:`~jaxdobby.identify.inner.inner`; a
    lane accepts its step when the true cost falls (then μ/3), else μ·10 and a shorter step. Stops when every lane's step
    is below :data:`STEP_TOLERANCE` in z or the cost falls by less than
    :data:`COST_TOLERANCE` relative (or μ has grown past 1e8: no descent left)."""
    p = len(lanes.par.names)
    n_lanes = lanes.z.shape[0]
    mu = np.full(n_lanes, 1e-3)
    v0 = np.zeros((n_lanes, p + 2))
    # φ and b at the starting z: the phase scan, then the fit of (φ, b) alone (δ pinned by μ)
    _, v = lanes.inner(lanes.coef, lanes.dcoef, lanes.z, np.full(n_lanes, 1e12), v0, scan=True)
    v0[:, p:] = v[:, p:]
    cost, step = lanes.inner(lanes.coef, lanes.dcoef, lanes.z, mu, v0)
    done = np.zeros(n_lanes, bool)
    for iteration in range(max_iterations):
        if progress is not None:
            progress(f"iteration {iteration}: cost " + " ".join(f"{c:.6g}" for c in cost)
                     + " (by start)")
        z_try = np.clip(lanes.z + step[:, :p], lanes.par.lower, lanes.par.upper)
        coef_try, dcoef_try = lanes.grids(z_try)
        v_try = np.concatenate([np.zeros((n_lanes, p)), step[:, p:]], axis=1)
        cost_try, step_try = lanes.inner(coef_try, dcoef_try, z_try, mu / 3, v_try)
        accept = np.isfinite(cost_try) & (cost_try <= cost) & ~done
        small = ((np.max(np.abs(z_try - lanes.z), axis=1) < STEP_TOLERANCE)
                 | (cost - cost_try <= COST_TOLERANCE * cost))
        done |= (accept & small) | (mu > 1e8)
        lanes.z = np.where(accept[:, None], z_try, lanes.z)
        lanes.coef = jnp.where(accept[:, None, None], coef_try, lanes.coef)
        lanes.dcoef = jnp.where(accept[:, None, None, None], dcoef_try, lanes.dcoef)
        v0 = np.where(accept[:, None], v_try, v0)
        cost = np.where(accept, cost_try, cost)
        mu = np.where(accept, mu / 3, mu * 10)
        if done.all():
            break
        step_rej = (lanes.inner(lanes.coef, lanes.dcoef, lanes.z, mu, v0)[1]
                    if not accept.all() else step_try)
        step = np.where(accept[:, None], step_try, step_rej)
    return cost, v0, done


def identify(setup: Setup, meas: Measurement, keys, *, options: RunOptions | None = None,
             starts: int = 1, spread: float = 0.5, bounds=None, seed: int = 0,
             max_iterations: int = 40, progress=None, directory=None) -> Identified:
    """Fit the parameters ``keys`` (TOML keys) of ``setup`` to the measured trace.

    Args:
        setup: the machine and operating point (the speed the trace was measured at); the
            fitted parameters start from their values here.
        meas: the checked :class:`~jaxdobby.identify.measurement.Measurement`.
        keys: TOML keys (or registry names) of float parameters.
        options: solver settings (method, steps) of the steady cycle.
        starts: number of starts, solved as one vmapped batch (the first from ``setup``).
        spread: half-width of the random starts in z (log parameters: a factor e^spread).
        bounds: optional {key: (low, high)} in users' units.
        seed: of the random starts.
        max_iterations: outer Levenberg–Marquardt iterations at most.
        progress: optional callable receiving one line per iteration.
        directory: where the fit's programs are stored (the command line's programs folder:
            a later fit of the same configuration, trace length and starts skips tracing
            them; :func:`jaxdobby.programs.stored_call`); None: not stored.
    """
    from ..modulator import cycle_period
    from .measurement import check_length
    from .uncertainty import summarise

    method, steps = solver_settings(setup, options)
    par = parameterisation(setup, keys, bounds)
    period = float(cycle_period(setup.operating.speed))
    check_length(meas, period)
    sigma = [1.0, 1.0]
    if meas.acceleration is not None:
        sigma[0] = float(np.sqrt(np.mean(meas.acceleration ** 2)))
    if meas.position is not None:
        sigma[1] = float(np.std(meas.position / MM)) or 1.0
    lanes = _Lanes(setup, par, method, steps, _starts(par, starts, spread, seed), directory)
    n_coef = lanes.coef.shape[-1]
    lanes.data = problem(meas, period, sigma, n_coef)
    cost, v, done = _least_squares(lanes, max_iterations, progress)
    if len(meas.channels) == 2:  # reweight by each channel's residual RMS, refit every lane
        best = int(np.argmin(np.where(np.isfinite(cost), cost, np.inf)))
        r = _final(lanes, v)[0][best]
        n, size = meas.time.size, lanes.data.phase.size
        sigma = [float(np.sqrt(np.mean((r[c * size:c * size + n] * sigma[c]) ** 2))) or 1.0
                 for c in range(2)]
        lanes.data = problem(meas, period, sigma, n_coef)
        cost, v, done = _least_squares(lanes, max_iterations, progress)
    cost = np.where(np.isfinite(cost), cost, np.inf)
    best = int(np.argmin(cost))
    r, jac = _final(lanes, v)
    u = np.concatenate([lanes.z[best], v[best, len(par.names):]])
    return summarise(setup, meas, par, u, r[best], jac[best], sigma, lanes.data.phase.size,
                     bool(done[best]) and bool(np.all(np.isfinite(u))), cost)


def _final(lanes: _Lanes, v):
    """(residuals, Jacobian in (z, φ, b)) of every lane at its current point."""
    p = len(lanes.par.names)
    v0 = np.concatenate([np.zeros((v.shape[0], p)), v[:, p:]], axis=1)
    return lanes.full(v0)
