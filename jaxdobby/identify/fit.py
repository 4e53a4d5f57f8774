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
Gauss–Newton with a step-length search (:func:`_gauss_newton`; cheap: interpolation only, and on
the residuals compressed from the m samples to the model's 2K Fourier coefficients by one QR
factorisation of the interpolation matrix, :func:`_compressed`). A start accepts its step when
the true cost falls (μ/3), else it shortens it (μ·10) (Moré, "The Levenberg–Marquardt
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
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..config import RunOptions
from ..parameters import Setup
from .measurement import Measurement
from .model import (MM, Parameterisation, cycle_grids, fourier, harmonics, parameterisation,
                    solver_settings)

BUCKET = 1024
"""Measured samples are padded (with zero weight) to a multiple of this, so that traces of
similar length share one compiled program."""
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


class Problem(eqx.Module):
    """The measured data, padded with zero weights to a multiple of :data:`BUCKET` samples
    (arrays, so that new values do not recompile), and its compressed form.

    Attributes: ``phase`` t/T of each sample from the first [-], shape (m,); the measured
    channels (acceleration [m/s²], position [mm]) and their weights 1/σ_c (0: absent or
    padding), shape (2, m) each; ``cos``, ``sin`` of 2πk·phase, shape (m, K) (the harmonics of
    the model's grid at the samples: a shift φ then only rotates the model's coefficients);
    ``r_factor`` (2, 2K, 2K), ``q_data`` (2, 2K) and ``rest`` (): the compressed least-squares
    problem of :func:`_compressed`."""

    phase: jax.Array
    measured: jax.Array
    weight: jax.Array
    cos: jax.Array
    sin: jax.Array
    r_factor: jax.Array
    q_data: jax.Array
    rest: jax.Array


def _problem(meas: Measurement, period: float, sigma, n_coef: int) -> Problem:
    n = meas.time.size
    size = BUCKET * math.ceil(n / BUCKET)
    measured = np.zeros((2, size))
    weight = np.zeros((2, size))
    for row, y in enumerate((meas.acceleration, None if meas.position is None
                             else meas.position / MM)):
        if y is not None:
            measured[row, :n] = y
            weight[row, :n] = 1.0 / sigma[row]
    phase = np.zeros(size)
    phase[:n] = (meas.time - meas.time[0]) / period
    cos, sin = harmonics(jnp.asarray(phase), n_coef)
    r_factor, q_data, rest = _compressed(np.asarray(cos)[:n], np.asarray(sin)[:n],
                                         weight[:, :n], measured[:, :n])
    return Problem(jnp.asarray(phase), jnp.asarray(measured), jnp.asarray(weight), cos, sin,
                   jnp.asarray(r_factor), jnp.asarray(q_data), jnp.asarray(rest))


def _compressed(cos, sin, weight, measured):
    """The weighted residuals of channel c are linear in the model's coefficients
    x_c = (Re ĉ, Im ĉ) (2K): r_c = A_c x_c − w_c y_c with A_c = w_c [cos, −sin] (m × 2K). With
    the reduced QR factorisation A_c = Q_c R_c (Golub & Van Loan, *Matrix Computations*, §5.3),
    ‖r_c‖² = ‖R_c x_c − Q_cᵀ w_c y_c‖² + ‖(I − Q_c Q_cᵀ) w_c y_c‖² exactly, for any x_c: the
    least-squares steps see the 2K rows R_c x_c − Q_cᵀ w_c y_c instead of the m samples (the same
    cost up to the constant ``rest``, the same JᵀJ and Jᵀr), 2K ≪ m. Returns (R (2, 2K, 2K),
    Qᵀwy (2, 2K), rest) (rows past m zero when m < 2K)."""
    m, n_coef = cos.shape
    basis = np.concatenate([cos, -sin], axis=1)  # (m, 2K)
    r_factor = np.zeros((2, 2 * n_coef, 2 * n_coef))
    q_data = np.zeros((2, 2 * n_coef))
    rest = 0.0
    for c in range(2):
        wy = weight[c] * measured[c]
        q, r = np.linalg.qr(weight[c][:, None] * basis)  # reduced: q (m, min(m, 2K))
        rows = r.shape[0]
        r_factor[c, :rows], q_data[c, :rows] = r, q.T @ wy
        rest += float(wy @ wy - q_data[c] @ q_data[c])
    return r_factor, q_data, max(rest, 0.0)


def _coefficients(v, coef, dcoef, z, lower, upper):
    """The model's coefficients (2, K) at v = (δ, φ, b): the grid's moved by its exact
    derivative times the step δ (clipped to the bounds), rotated by the shift φ, the position's
    mean moved by b."""
    p = z.shape[0]
    delta = jnp.clip(z + v[:p], lower, upper) - z
    c = coef + dcoef @ delta  # (2, K)
    # the shift φ rotates the coefficients: e^{2πik(φ_j + φ)} = e^{2πikφ_j} e^{2πikφ}
    c = c * jnp.exp(2j * jnp.pi * jnp.arange(c.shape[-1]) * v[p])
    return c.at[1, 0].add(v[p + 1])


def _linear_residuals(v, coef, dcoef, z, lower, upper, data: Problem):
    """Weighted residuals (2·m,) of the model linearised in z at v = (δ, φ, b) (the grid moved
    by its exact derivative times δ, sampled at t/T + φ, the position offset by b)."""
    c = _coefficients(v, coef, dcoef, z, lower, upper)
    model = c.real @ data.cos.T - c.imag @ data.sin.T  # (2, m)
    return (data.weight * (model - data.measured)).ravel()


def _compressed_residuals(v, coef, dcoef, z, damping, lower, upper, data: Problem):
    """The residuals of :func:`_linear_residuals` compressed to 2·2K rows (:func:`_compressed`:
    the same cost up to a constant, the same JᵀJ), then ``damping``·δ (the Levenberg–Marquardt
    term √μ D δ of the outer step, D the column norms of J: Marquardt's scaling)."""
    p = z.shape[0]
    c = _coefficients(v, coef, dcoef, z, lower, upper)
    x = jnp.concatenate([c.real, c.imag], axis=1)  # (2, 2K)
    r = (jnp.einsum("cij,cj->ci", data.r_factor, x) - data.q_data).ravel()
    return jnp.concatenate([r, damping * v[:p]])


def _phase_scan(coef, data: Problem):
    """(φ, b) from the weighted cross-correlation of model and data (module docstring) and
    the difference of the measured and modelled mean positions [mm]."""
    n_coef = coef.shape[-1]
    n = 2 * (n_coef - 1)
    k = jnp.arange(n_coef)
    w2 = data.weight ** 2
    mean = jnp.sum(w2 * data.measured, axis=1) / jnp.maximum(jnp.sum(w2, axis=1), 1e-300)
    d = (w2 * (data.measured - mean[:, None])) @ (data.cos + 1j * data.sin)  # (2, K): Σ_j w_j² y_j e^{2πikφ_j}
    # Σ_j w_j² m(t_j/T + φ) y_j = Re Σ_k c_k D_k e^{2πikφ}: for φ = i/n at once by one FFT
    spectrum = jnp.zeros(n, complex).at[k].set(jnp.sum(coef.at[:, 0].set(0.0) * d, axis=0))
    score = jnp.real(jnp.fft.ifft(spectrum)) * n
    return jnp.argmax(score) / n, mean[1] - coef[1, 0].real


INNER_ITERATIONS = 30
"""Gauss–Newton iterations of the inner (linearised) problem at most; from the phase scan it
converges in a few (linear in δ and b, smooth in φ)."""
SCALES = np.array([1.0, 0.5, 0.25, 0.125, 0.0])
"""Step lengths tried by each inner Gauss–Newton iteration (the one of least cost is taken;
0 keeps the point: the cost never rises)."""


def _gauss_newton(fn, start, max_iterations=INNER_ITERATIONS):
    """Minimise ½‖fn(v)‖² from ``start`` by Gauss–Newton with a step-length search over
    :data:`SCALES` (the step: the least-squares solution of J Δ = −r, minimum norm where J is
    rank-deficient, e.g. no position channel: b does not move). Stops when a step moves no
    unknown by more than 1e-13·(1 + |v|). Returns (v, converged)."""
    def cost(v):
        r = fn(v)
        return r @ r

    def cond(state):
        i, _, done = state
        return (i < max_iterations) & ~done

    def body(state):
        i, v, _ = state
        r, jac = fn(v), jax.jacfwd(fn)(v)
        step = -jnp.linalg.lstsq(jac, r)[0]
        scales = jnp.asarray(SCALES)
        costs = jax.vmap(lambda a: cost(v + a * step))(scales)
        costs = jnp.where(jnp.isfinite(costs), costs, jnp.inf)
        moved = scales[jnp.argmin(costs)] * step
        done = jnp.all(jnp.abs(moved) <= 1e-13 * (1.0 + jnp.abs(v)))
        return i + 1, v + moved, done

    _, v, done = jax.lax.while_loop(cond, body, (0, start, False))
    return v, done


@eqx.filter_jit
def _inner(coef, dcoef, z, mu, lower, upper, v0, scan, data: Problem):
    """For each lane (vmapped): the cost ½‖r‖² at v0 (true cost: δ = 0 there), then the
    damped linearised step v = (δ, φ, b) by :func:`_gauss_newton` from v0 (φ, b from
    :func:`_phase_scan` where ``scan``) and its success. On the compressed residuals
    (:func:`_compressed_residuals`): 2·2K rows instead of 2·m."""
    def one(coef, dcoef, z, mu, v0):
        p = z.shape[0]

        def fn(v, damping):
            return _compressed_residuals(v, coef, dcoef, z, damping, lower, upper, data)

        zero = jnp.zeros(p)
        r0 = fn(v0, zero)[:-p]
        jac = jax.jacfwd(lambda v: fn(v, zero))(v0)[:-p, :p]
        damping = jnp.sqrt(mu) * jnp.linalg.norm(jac, axis=0)
        phase, offset = _phase_scan(coef, data)
        start = jnp.where(scan, v0.at[p].set(phase).at[p + 1].set(offset), v0)
        v, ok = _gauss_newton(lambda v: fn(v, damping), start)
        return 0.5 * (r0 @ r0 + data.rest), v, ok

    return jax.vmap(one)(coef, dcoef, z, mu, v0)


@eqx.filter_jit
def _full(coef, dcoef, z, lower, upper, v0, data: Problem):
    """For each lane (vmapped): the weighted residuals r (2·m,) at v0 and their Jacobian in
    v = (δ, φ, b) (at δ = 0 the exact Jacobian of r in (z, φ, b))."""
    def one(coef, dcoef, z, v0):
        def fn(v):
            return _linear_residuals(v, coef, dcoef, z, lower, upper, data)

        return fn(v0), jax.jacfwd(fn)(v0)

    return jax.vmap(one)(coef, dcoef, z, v0)


def _starts(par: Parameterisation, starts: int, spread: float, seed: int) -> np.ndarray:
    """Starting z: the configuration's values (0), then ``starts − 1`` draws uniform in
    ±``spread``, clipped to the bounds."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(-spread, spread, (starts, len(par.names)))
    z[0] = 0.0
    return np.clip(z, par.lower, par.upper)


class _Lanes:
    """The outer Levenberg–Marquardt state of every start (numpy, lane-wise)."""

    def __init__(self, setup, par, method, steps, z):
        self.setup, self.par, self.method, self.steps = setup, par, method, steps
        self.data: Problem | None = None
        self.lower, self.upper = jnp.asarray(par.lower), jnp.asarray(par.upper)
        self.z = z
        self.coef, self.dcoef = self.grids(z)

    def grids(self, z):
        _, grid, dgrid = cycle_grids(self.setup, self.par.names, self.par.log, self.method,
                                     self.steps, jnp.asarray(z))
        return fourier(grid), jnp.moveaxis(fourier(jnp.moveaxis(dgrid, -1, -2)), -2, -1)

    def inner(self, coef, dcoef, z, mu, v0, scan=False):
        out = _inner(coef, dcoef, jnp.asarray(z), jnp.asarray(mu), self.lower, self.upper,
                     jnp.asarray(v0), jnp.asarray(scan), self.data)
        return tuple(np.asarray(a) for a in out)

    def full(self, v0):
        out = _full(self.coef, self.dcoef, jnp.asarray(self.z), self.lower, self.upper,
                    jnp.asarray(v0), self.data)
        return tuple(np.asarray(a) for a in out)


def _least_squares(lanes: _Lanes, max_iterations: int, progress=None):
    """Outer Levenberg–Marquardt on z (exact Jacobian of the steady cycle), every lane at once:
    the inner linearised step (with φ and b) from :func:`_inner`; a lane accepts its step when
    the true cost falls (then μ/3), else μ·10 and a shorter step. Stops when every lane's step
    is below :data:`STEP_TOLERANCE` in z or the cost falls by less than
    :data:`COST_TOLERANCE` relative (or μ has grown past 1e8: no descent left)."""
    p = len(lanes.par.names)
    n_lanes = lanes.z.shape[0]
    mu = np.full(n_lanes, 1e-3)
    v0 = np.zeros((n_lanes, p + 2))
    # φ and b at the starting z: the phase scan, then the fit of (φ, b) alone (δ pinned by μ)
    _, v, _ = lanes.inner(lanes.coef, lanes.dcoef, lanes.z, np.full(n_lanes, 1e12), v0,
                                scan=True)
    v0[:, p:] = v[:, p:]
    cost, step, ok = lanes.inner(lanes.coef, lanes.dcoef, lanes.z, mu, v0)
    done = np.zeros(n_lanes, bool)
    for iteration in range(max_iterations):
        if progress is not None:
            progress(f"iteration {iteration}: cost " + " ".join(f"{c:.6g}" for c in cost)
                     + " (by start)")
        z_try = np.clip(lanes.z + step[:, :p], lanes.par.lower, lanes.par.upper)
        coef_try, dcoef_try = lanes.grids(z_try)
        v_try = np.concatenate([np.zeros((n_lanes, p)), step[:, p:]], axis=1)
        cost_try, step_try, ok_try = lanes.inner(coef_try, dcoef_try, z_try, mu / 3,
                                                       v_try)
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
        _, step_rej, ok_rej = (lanes.inner(lanes.coef, lanes.dcoef, lanes.z, mu, v0)
                               if not accept.all() else (None, step_try, ok_try))
        step = np.where(accept[:, None], step_try, step_rej)
        ok = np.where(accept, ok_try, ok_rej)
    return cost, v0, done


def identify(setup: Setup, meas: Measurement, keys, *, options: RunOptions | None = None,
             starts: int = 1, spread: float = 0.5, bounds=None, seed: int = 0,
             max_iterations: int = 40, progress=None) -> Identified:
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
    lanes = _Lanes(setup, par, method, steps, _starts(par, starts, spread, seed))
    n_coef = lanes.coef.shape[-1]
    lanes.data = _problem(meas, period, sigma, n_coef)
    cost, v, done = _least_squares(lanes, max_iterations, progress)
    if len(meas.channels) == 2:  # reweight by each channel's residual RMS, refit every lane
        best = int(np.argmin(np.where(np.isfinite(cost), cost, np.inf)))
        r = _final(lanes, v)[1][best]
        n, size = meas.time.size, lanes.data.phase.size
        sigma = [float(np.sqrt(np.mean((r[c * size:c * size + n] * sigma[c]) ** 2))) or 1.0
                 for c in range(2)]
        lanes.data = _problem(meas, period, sigma, n_coef)
        cost, v, done = _least_squares(lanes, max_iterations, progress)
    cost = np.where(np.isfinite(cost), cost, np.inf)
    best = int(np.argmin(cost))
    _, r, jac = _final(lanes, v)
    u = np.concatenate([lanes.z[best], v[best, len(par.names):]])
    return summarise(setup, meas, par, u, r[best], jac[best], sigma, lanes.data.phase.size,
                     bool(done[best]) and bool(np.all(np.isfinite(u))), cost)


def _final(lanes: _Lanes, v):
    """(None, residuals, Jacobian in (z, φ, b)) of every lane at its current point."""
    p = len(lanes.par.names)
    v0 = np.concatenate([np.zeros((v.shape[0], p)), v[:, p:]], axis=1)
    r, jac = lanes.full(v0)
    return None, r, jac
