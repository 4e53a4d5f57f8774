"""The inner step of :mod:`jaxdobby.identify.fit`: the measured data as arrays, the residuals of
the model linearised in the fitted parameters (nonlinear in the time shift φ and the position
offset b), their exact compression to the model's Fourier coefficients, the phase scan, and the
damped Gauss–Newton solve of each outer Levenberg–Marquardt step (see the docstring of
:mod:`~jaxdobby.identify.fit` for the method).

Why not a general least-squares library here: the inner problem has p + 2 unknowns and is
solved ~40 times per fit; :class:`optimistix.LevenbergMarquardt` on it took 6–15 s per call
(its per-step machinery under ``vmap``, 2 shared cores) — 260 of a fit's 280 s — where this
Gauss–Newton takes 0.3–1 s with the same solutions (to 3e-9 of the estimates).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .measurement import Measurement
from .model import MM, harmonics

BUCKET = 1024
"""Measured samples are padded (with zero weight) to a multiple of this, so that traces of
similar length share one compiled program."""


class Problem(eqx.Module):
    """The measured data, padded with zero weights to a multiple of :data:`BUCKET` samples
    (arrays, so that new values do not recompile), and its compressed form.

    Attributes: ``phase`` t/T of each sample from the first [-], shape (m,); the measured
    channels (acceleration [m/s²], position [mm]) and their weights 1/σ_c (0: absent or
    padding), shape (2, m) each; ``cos``, ``sin`` of 2πk·phase, shape (m, K) (the harmonics of
    the model's grid at the samples: a shift φ then only rotates the model's coefficients);
    ``r_factor`` (2, 2K, 2K), ``q_data`` (2, 2K) and ``rest`` (): the compressed least-squares
    problem of :func:`compressed`."""

    phase: jax.Array
    measured: jax.Array
    weight: jax.Array
    cos: jax.Array
    sin: jax.Array
    r_factor: jax.Array
    q_data: jax.Array
    rest: jax.Array


def problem(meas: Measurement, period: float, sigma, n_coef: int) -> Problem:
    """The :class:`Problem` of ``meas`` for a model of cycle ``period`` [s] with ``n_coef``
    harmonics per channel, each channel weighted by 1/``sigma[c]`` (its units)."""
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
    r_factor, q_data, rest = compressed(np.asarray(cos)[:n], np.asarray(sin)[:n],
                                         weight[:, :n], measured[:, :n])
    return Problem(jnp.asarray(phase), jnp.asarray(measured), jnp.asarray(weight), cos, sin,
                   jnp.asarray(r_factor), jnp.asarray(q_data), jnp.asarray(rest))


def compressed(cos, sin, weight, measured):
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


def coefficients(v, coef, dcoef, z, lower, upper):
    """The model's coefficients (2, K) at v = (δ, φ, b): the grid's moved by its exact
    derivative times the step δ (clipped to the bounds), rotated by the shift φ, the position's
    mean moved by b."""
    p = z.shape[0]
    delta = jnp.clip(z + v[:p], lower, upper) - z
    c = coef + dcoef @ delta  # (2, K)
    # the shift φ rotates the coefficients: e^{2πik(φ_j + φ)} = e^{2πikφ_j} e^{2πikφ}
    c = c * jnp.exp(2j * jnp.pi * jnp.arange(c.shape[-1]) * v[p])
    return c.at[1, 0].add(v[p + 1])


def linear_residuals(v, coef, dcoef, z, lower, upper, data: Problem):
    """Weighted residuals (2·m,) of the model linearised in z at v = (δ, φ, b) (the grid moved
    by its exact derivative times δ, sampled at t/T + φ, the position offset by b)."""
    c = coefficients(v, coef, dcoef, z, lower, upper)
    model = c.real @ data.cos.T - c.imag @ data.sin.T  # (2, m)
    return (data.weight * (model - data.measured)).ravel()


def compressed_residuals(v, coef, dcoef, z, damping, lower, upper, data: Problem):
    """The residuals of :func:`linear_residuals` compressed to 2·2K rows (:func:`compressed`:
    the same cost up to a constant, the same JᵀJ), then ``damping``·δ (the Levenberg–Marquardt
    term √μ D δ of the outer step, D the column norms of J: Marquardt's scaling)."""
    p = z.shape[0]
    c = coefficients(v, coef, dcoef, z, lower, upper)
    x = jnp.concatenate([c.real, c.imag], axis=1)  # (2, 2K)
    r = (jnp.einsum("cij,cj->ci", data.r_factor, x) - data.q_data).ravel()
    return jnp.concatenate([r, damping * v[:p]])


def phase_scan(coef, data: Problem):
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


def gauss_newton(fn, start, max_iterations=INNER_ITERATIONS):
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


def inner(coef, dcoef, z, mu, lower, upper, v0, scan, data: Problem, *, directory=None):
    """:func:`_inner` through a stored program (:func:`jaxdobby.programs.stored_call`, kept in
    ``directory``)."""
    from ..programs import stored_call

    return stored_call("identify-inner", _inner,
                       (coef, dcoef, z, mu, lower, upper, v0, scan, data), directory=directory)


def full(coef, dcoef, z, lower, upper, v0, data: Problem, *, directory=None):
    """:func:`_full` through a stored program (:func:`jaxdobby.programs.stored_call`, kept in
    ``directory``)."""
    from ..programs import stored_call

    return stored_call("identify-full", _full, (coef, dcoef, z, lower, upper, v0, data),
                       directory=directory)


def _inner(coef, dcoef, z, mu, lower, upper, v0, scan, data: Problem):
    """For each lane (vmapped): the cost ½‖r‖² at v0 (true cost: δ = 0 there), then the
    damped linearised step v = (δ, φ, b) by :func:`gauss_newton` from v0 (φ, b from
    :func:`phase_scan` where ``scan``; the caller keeps a step only if the true cost falls, so
    the solve's own convergence flag is not returned). On the compressed residuals
    (:func:`compressed_residuals`): 2·2K rows instead of 2·m."""
    def one(coef, dcoef, z, mu, v0):
        p = z.shape[0]

        def fn(v, damping):
            return compressed_residuals(v, coef, dcoef, z, damping, lower, upper, data)

        zero = jnp.zeros(p)
        r0 = fn(v0, zero)[:-p]
        jac = jax.jacfwd(lambda v: fn(v, zero))(v0)[:-p, :p]
        damping = jnp.sqrt(mu) * jnp.linalg.norm(jac, axis=0)
        phase, offset = phase_scan(coef, data)
        start = jnp.where(scan, v0.at[p].set(phase).at[p + 1].set(offset), v0)
        v, _ = gauss_newton(lambda v: fn(v, damping), start)
        return 0.5 * (r0 @ r0 + data.rest), v

    return jax.vmap(one)(coef, dcoef, z, mu, v0)


def _full(coef, dcoef, z, lower, upper, v0, data: Problem):
    """For each lane (vmapped): the weighted residuals r (2·m,) at v0 and their Jacobian in
    v = (δ, φ, b) (at δ = 0 the exact Jacobian of r in (z, φ, b))."""
    def one(coef, dcoef, z, v0):
        def fn(v):
            return linear_residuals(v, coef, dcoef, z, lower, upper, data)

        return fn(v0), jax.jacfwd(fn)(v0)

    return jax.vmap(one)(coef, dcoef, z, v0)
