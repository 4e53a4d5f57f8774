"""Scalar metrics of a steady-state cycle, and smooth surrogates for gradients.

Following the source study's usage, the *amplitude* of a signal over the cycle is its
peak-to-peak range, max − min (its 1.89 mm "displacement deviation amplitude" is the range
−0.66 … +1.23 mm). Extremes are taken over the sampled time series.

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


def peak_to_peak(x: Array, axis=0) -> Array:
    """max − min along ``axis``."""
    return jnp.max(x, axis=axis) - jnp.min(x, axis=axis)


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
    return dict(
        deviation_min=jnp.min(dev),
        deviation_max=jnp.max(dev),
        deviation_pp=peak_to_peak(dev),
        link_point_deviation_x=peak_to_peak(series.link_point_deviation[:, 0]),
        link_point_deviation_y=peak_to_peak(series.link_point_deviation[:, 1]),
        velocity_deviation_amp=peak_to_peak(series.velocity_deviation),
        acceleration_amp=peak_to_peak(series.acceleration_flexible),
        acceleration_rigid_amp=peak_to_peak(series.acceleration_rigid),
        acceleration_deviation_amp=peak_to_peak(series.acceleration_deviation),
        ring_link_force_max=jnp.max(jnp.abs(series.ring_link_force)),
        link11_force_max=jnp.max(link11),
        deviation_pp_smooth=smooth_peak_to_peak(dev),
        deviation_rms=rms(dev),
        acceleration_amp_smooth=smooth_peak_to_peak(series.acceleration_flexible),
    )
