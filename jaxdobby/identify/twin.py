"""Synthetic measured traces from the model itself (twin experiments): the machine with chosen
parameters, sampled at a given rate from an arbitrary time origin, with white noise added."""

from __future__ import annotations

import numpy as np

from ..config import RunOptions
from ..modulator import cycle_period
from ..parameters import Setup
from .measurement import Measurement
from .model import MM, cycle_grids, fourier, interpolate, parameterisation, solver_settings


def model_trace(setup: Setup, time, phase: float, options: RunOptions | None = None, *,
                keys=(), lanes: int = 1):
    """Model (acceleration [m/s²], position [m]) of ``setup``'s steady cycle at ``time`` [s],
    the first sample at ``phase`` (fraction of the cycle from the middle of the bottom dwell).

    ``keys``, ``lanes``: compute through the compiled program of a fit of these parameters
    with that many starts (:func:`jaxdobby.identify.model.cycle_grids`; saves a compile)."""
    method, steps = solver_settings(setup, options)
    par = parameterisation(setup, keys)
    period, grid, _ = cycle_grids(setup, par.names, par.log, method, steps,
                                  np.zeros((lanes, len(par.names))))
    time = np.asarray(time, float)
    values = np.asarray(interpolate(fourier(grid[0]), (time - time[0]) / period[0] + phase))
    return values[0], values[1] * MM


def synthetic(setup: Setup, *, cycles: float = 2.0, rate_hz: float = 4000.0,
              phase: float = 0.3, start_s: float = 17.25, offset_mm: float = 0.0,
              noise_acceleration: float = 0.0, noise_position_mm: float = 0.0,
              channels=("acceleration", "position"), seed: int = 0,
              options: RunOptions | None = None, keys=(), lanes: int = 1) -> Measurement:
    """A measured-like trace of ``setup``: ``cycles`` heald-frame cycles sampled at
    ``rate_hz`` [Hz], times starting at ``start_s`` [s] (arbitrary), the first sample at the
    cycle fraction ``phase``, the position shifted by ``offset_mm``, Gaussian white noise of
    standard deviation ``noise_acceleration`` [m/s²] and ``noise_position_mm`` [mm]
    (``keys``, ``lanes``: see :func:`model_trace`)."""
    period = float(cycle_period(setup.operating.speed))
    n = int(round(cycles * period * rate_hz))
    time = start_s + np.arange(n) / rate_hz
    acc, pos = model_trace(setup, time, phase, options, keys=keys, lanes=lanes)
    rng = np.random.default_rng(seed)
    acc = acc + noise_acceleration * rng.standard_normal(n)
    pos = pos + (offset_mm + noise_position_mm * rng.standard_normal(n)) * MM
    return Measurement(time, acc if "acceleration" in channels else None,
                       pos if "position" in channels else None)
