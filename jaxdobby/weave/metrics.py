"""Metrics of a lift plan's repeat, per pick (DESIGN.md §7: what matters while the weft flies).

The time series of a run with a plan of P picks covers the repeat t ∈ [0, T] (uniform
samples, the last repeating the first). With x = P·t/T the main shaft's turns, pick k's dwell
is centred on x = k + 1 (the shed-open of pick k; t = 0 is the middle of the last pick's
dwell, :mod:`jaxdobby.modulator`) and spans |x − (k + 1)| ≤ d/2, d = dwell/2π; pick k is
x ∈ [k + d/2, k + 1 + d/2) (its index, then its dwell).

* ``moves`` (P,): 1 where the frame moves in pick k;
* ``shed_deviation`` (P,) [m]: the deviation (flexible − rigid height) at shed-open, by linear
  interpolation between samples (the output grid has a sample there for 216·P steps);
* ``dwell_vibration`` (P,) [m]: peak-to-peak of the deviation over pick k's dwell (samples
  in the closed dwell interval);
* ``dwell_vibration_max`` [m]: the largest of them.

Everything is a fixed-size masked reduction: jittable, vmappable over frames, differentiable
wherever the extreme sample does not change.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ..modulator import pick_moves

_EDGE = 1e-9
"""Slack [turns] on the dwell's ends: a sample on a dwell boundary belongs to the dwell."""


def pick_of(t: Array, period, picks: int, dwell) -> Array:
    """Pick index k ∈ {0…P−1} of times t [s] in a repeat of ``period`` [s] (int array)."""
    x = picks * jnp.asarray(t) / period
    return jnp.mod(jnp.floor(x - 0.5 * dwell / (2.0 * jnp.pi) + _EDGE), picks).astype(int)


def pick_metrics(series, plan: Array, dwell) -> dict[str, Array]:
    """Per-pick metrics of one repeat (see the module docstring).

    Args:
        series: :class:`~jaxdobby.outputs.Timeseries` over the repeat (t from 0 to T).
        plan: the lift sequence (P,) of 0/1 floats.
        dwell: the modulator's dwell per pick [rad of main shaft].
    """
    plan = jnp.asarray(plan, dtype=float)
    picks = plan.shape[0]
    t, dev = series.t, series.deviation
    period = t[-1]
    x = picks * t / period
    centre = jnp.round(x)
    half = 0.5 * dwell / (2.0 * jnp.pi)
    in_dwell = jnp.abs(x - centre) <= half + _EDGE
    owner = jnp.mod(centre.astype(int) - 1, picks)
    mask = in_dwell[None, :] & (owner[None, :] == jnp.arange(picks)[:, None])  # (P, n)
    hi = jnp.max(jnp.where(mask, dev[None, :], -jnp.inf), axis=1)
    lo = jnp.min(jnp.where(mask, dev[None, :], jnp.inf), axis=1)
    vibration = hi - lo
    shed_times = (jnp.arange(picks) + 1.0) * period / picks
    return dict(moves=pick_moves(plan), shed_deviation=jnp.interp(shed_times, t, dev),
                dwell_vibration=vibration, dwell_vibration_max=jnp.max(vibration))
