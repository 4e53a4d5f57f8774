"""Scalar metrics of a steady-state cycle, and smooth surrogates for gradients.

Following the source study's usage, the *amplitude* of a signal over the cycle is its
peak-to-peak range, max − min (its 1.89 mm "displacement deviation amplitude" is the range
−0.66 … +1.23 mm). Extremes are taken over the sampled time series of one period (uniform
samples, the last one at t = T repeating the first), the extreme sample refined by the vertex of
the parabola through it and its two neighbours (wrapping around the period): the sampled
maximum of a sinusoid with n samples per period is low by ≈ (π/n)²/2 of its amplitude, the
refined one by O((π/n)⁴).

``max`` and ``min`` are only piecewise differentiable (the location of the peak jumps), so the
design optimiser uses smooth surrogates: the log-sum-exp soft maximum of the signal normalised by
its RMS, smax(x) = rms·(1/β) log mean exp(β x/rms) with β = 20 (within about log(n)/β of the
true maximum in units of the RMS; JAX-NOTES), and the RMS itself. Reports always give the true
extremes.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array
from jax.scipy.special import logsumexp

SHARPNESS = 20.0
"""β of the log-sum-exp surrogates (on RMS-normalised signals)."""


def extremes(x: Array) -> tuple[Array, Array]:
    """Refined maximum and minimum of a periodic signal sampled uniformly over one period.

    Args:
        x: samples at t = 0, T/n, …, T (shape (n + 1,); the last repeats the first).

    Returns:
        (max, min): the largest and smallest sample, each replaced by the vertex of the parabola
        through it and its neighbours (periodic wrap) where that parabola has its extremum
        there (within half a sample). Differentiable wherever the extreme sample does not change.
    """
    y = x[:-1]
    before, after = jnp.roll(y, 1), jnp.roll(y, -1)
    curvature = before - 2.0 * y + after
    slope = before - after
    safe = jnp.where(curvature == 0.0, 1.0, curvature)
    vertex = y - slope**2 / (8.0 * safe)
    i, j = jnp.argmax(y), jnp.argmin(y)
    hi = jnp.where(curvature[i] < 0.0, vertex[i], y[i])
    lo = jnp.where(curvature[j] > 0.0, vertex[j], y[j])
    return hi, lo


def peak_to_peak(x: Array) -> Array:
    """Refined max − min of a periodic signal sampled over one period (see :func:`extremes`)."""
    hi, lo = extremes(x)
    return hi - lo


def rms(x: Array, axis=0) -> Array:
    """Root mean square along ``axis``."""
    return jnp.sqrt(jnp.mean(x**2, axis=axis))


def smooth_max(x: Array, sharpness: float = SHARPNESS) -> Array:
    """Log-sum-exp soft maximum of a 1-D signal, scaled by its RMS (≤ max, differentiable)."""
    scale = rms(x) + jnp.finfo(x.dtype).tiny
    return scale * (logsumexp(sharpness * x / scale) - jnp.log(x.shape[0])) / sharpness


def smooth_peak_to_peak(x: Array, sharpness: float = SHARPNESS) -> Array:
    """Differentiable surrogate of max − min: smooth_max(x) + smooth_max(−x)."""
    return smooth_max(x, sharpness) + smooth_max(-x, sharpness)


def cycle_metrics(series) -> dict[str, Array]:
    """The scalar metrics of one cycle (SI units) from a :class:`~jaxdobby.outputs.Timeseries`.

    Keys: ``deviation_min``, ``deviation_max``, ``deviation_pp`` [m];
    ``link_point_deviation_x``, ``link_point_deviation_y`` (peak-to-peak, inertial) [m];
    ``velocity_deviation_amp`` [m/s]; ``acceleration_amp``, ``acceleration_rigid_amp``,
    ``acceleration_deviation_amp`` [m/s²]; ``ring_link_force_max``, ``link11_force_max`` [N];
    and the surrogates ``deviation_pp_smooth`` [m], ``deviation_rms`` [m],
    ``acceleration_amp_smooth`` [m/s²].
    """
    dev = series.deviation
    link11 = jnp.linalg.norm(series.link11_force, axis=-1)
    dev_max, dev_min = extremes(dev)
    ring_max, ring_min = extremes(series.ring_link_force)
    return dict(
        deviation_min=dev_min,
        deviation_max=dev_max,
        deviation_pp=dev_max - dev_min,
        link_point_deviation_x=peak_to_peak(series.link_point_deviation[:, 0]),
        link_point_deviation_y=peak_to_peak(series.link_point_deviation[:, 1]),
        velocity_deviation_amp=peak_to_peak(series.velocity_deviation),
        acceleration_amp=peak_to_peak(series.acceleration_flexible),
        acceleration_rigid_amp=peak_to_peak(series.acceleration_rigid),
        acceleration_deviation_amp=peak_to_peak(series.acceleration_deviation),
        ring_link_force_max=jnp.maximum(ring_max, -ring_min),
        link11_force_max=extremes(link11)[0],
        deviation_pp_smooth=smooth_peak_to_peak(dev),
        deviation_rms=rms(dev[:-1]),  # one period: the last sample repeats the first
        acceleration_amp_smooth=smooth_peak_to_peak(series.acceleration_flexible),
    )
