"""Validity warnings per sample of a Sobol design: which rows leave the model's validity.

The checks are those of one run (:mod:`jaxdobby.validity`, same limits); a batch cannot hold
each run's time series, so a model returns, beside its metrics, scalar *validity outputs* per
row, named ``validity.*`` (not metrics: no Sobol indices are computed for them; they are kept
in ``outputs.npz``), and :func:`sample_warnings` counts the rows that fail each check:

* the default model (:data:`jaxdobby.sensitivity.dobby.DOBBY`, the reduced-in-solve batch
  evaluator) returns ``validity.converged`` (1.0 when the periodicity residual met its
  tolerance) and ``validity.resonances`` (:func:`sample_resonances`'s count, from the
  frequencies of the model its solve assembles: :func:`resonance_count`), so it counts
  ``not_converged``, ``workspace`` (a failed row that did converge: the chain left its reach, or
  a sampled stroke is beyond the slot), ``deviation_of_stroke`` and ``resonance``. It cannot
  count ``arm_deflection`` or ``transmission_angle``: both need the arm's modal coordinates over
  the cycle, which its solver reduces to the extremes of three heald-frame signals inside the
  solve (:func:`jaxdobby.periodic.steady_state_metrics`), nor the stress checks;
* the stress model (:data:`jaxdobby.sensitivity.stress.DOBBY_STRESS`) runs the whole cycle, so
  it could return every check of a single run (``validity.deflection_ratio``,
  ``validity.reach_margin``, ``validity.sin_transmission``, ``validity.yield_ratio``: counted
  below when a model returns them), but its slow test hung (idle, a LAPACK wait?) with
  :func:`jaxdobby.validity.validity_arrays` in, when its samples still ran vectorised (they
  run one after another now; not tried again), so it is not wired in yet: the stress model
  counts ``not_converged``, ``deviation_of_stroke`` and ``fatigue_limit_exceeded``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..validity import (DEFLECTION_LIMIT, DEVIATION_LIMIT, TRANSMISSION_LIMIT, CODES,
                        phase_frequencies, resonant)


def sample_resonances(setup) -> Array:
    """Number of resonant (cycle harmonic, mode) pairs of one sample's
    :class:`~jaxdobby.parameters.Setup` (float; > 0: a ``resonance`` warning, the condition of
    :func:`jaxdobby.validity.resonant`). The model is assembled and its frequencies found one
    sample at a time (``jax.custom_batching.sequential_vmap``, as the batch's own assembly:
    no batched LAPACK call, :func:`jaxdobby.periodic.steady.model_terms`)."""
    from ..dobby import build_model

    dynamic, static = eqx.partition(setup, eqx.is_array)

    def one(d):
        s = eqx.combine(d, static)
        return phase_frequencies(build_model(s.machine, s.operating))

    freqs = jax.custom_batching.sequential_vmap(one)(dynamic)
    return resonance_count(setup.operating.speed, freqs)


def resonance_count(speed, freqs) -> Array:
    """:func:`sample_resonances` from the sample's speed [rad/s] and its coupled frequencies
    over the cycle [Hz], (phases, modes) (:func:`jaxdobby.validity.phase_frequencies`, or
    ``frequencies=True`` of :func:`jaxdobby.periodic.steady_state_metrics`)."""
    cycle_hz = speed / (4.0 * jnp.pi)  # ω/(2π)/2: a cycle is two picks
    return jnp.sum(resonant(cycle_hz, jnp.min(freqs, axis=0), jnp.max(freqs, axis=0))).astype(
        float)


def sample_warnings(names, samples, outputs, stroke_mm: float) -> dict[str, dict]:
    """Per-sample warnings of a Sobol design, ``{code: {"count", "samples", "limit"}}`` with the
    design's row indices, in :data:`jaxdobby.validity.CODES` order, from its outputs (users'
    units; the validity outputs of the module docstring where the model returns them).

    A failed row (``ok`` False) is ``not_converged`` — or ``workspace`` when the model says it
    converged; the other checks count rows that did not fail: ``deviation_of_stroke``
    (``deviation_pp_mm`` over the row's stroke — sampled, or ``stroke_mm`` — above
    :data:`~jaxdobby.validity.DEVIATION_LIMIT`), and those whose outputs are there. Empty for a
    model without ``deviation_pp_mm``."""
    if "deviation_pp_mm" not in outputs:
        return {}
    samples = np.asarray(samples)
    get = lambda k: np.asarray(outputs[k], dtype=float)  # noqa: E731
    dev = get("deviation_pp_mm")
    ok = np.asarray(outputs.get("ok", np.ones(dev.shape, bool)), dtype=bool)
    flags: dict[str, tuple[np.ndarray, float | None]] = {}
    converged = get("validity.converged") > 0.5 if "validity.converged" in outputs else ok
    flags["not_converged"] = (~ok & ~converged, None)
    stroke = samples[:, list(names).index("stroke")] if "stroke" in names else stroke_mm
    workspace = ~ok & converged
    if "validity.reach_margin" in outputs:
        workspace |= ok & ~(get("validity.reach_margin") >= 0.0)
    if "validity.deflection_ratio" in outputs:
        flags["arm_deflection"] = (ok & ~(get("validity.deflection_ratio") <= DEFLECTION_LIMIT),
                                   100 * DEFLECTION_LIMIT)
    flags["deviation_of_stroke"] = (ok & ~(np.abs(dev) / stroke <= DEVIATION_LIMIT),
                                    100 * DEVIATION_LIMIT)
    flags["workspace"] = (workspace, 0.0)
    if "validity.sin_transmission" in outputs:
        sin_limit = math.sin(math.radians(TRANSMISSION_LIMIT))
        flags["transmission_angle"] = (ok & ~workspace
                                       & ~(get("validity.sin_transmission") >= sin_limit),
                                       TRANSMISSION_LIMIT)
    if "validity.resonances" in outputs:
        flags["resonance"] = (ok & (get("validity.resonances") > 0), None)
    if "validity.yield_ratio" in outputs:
        flags["yield_exceeded"] = (ok & ~(get("validity.yield_ratio") <= 1.0), 1.0)
    if "fatigue_safety_factor" in outputs:
        flags["fatigue_limit_exceeded"] = (ok & ~(get("fatigue_safety_factor") >= 1.0), 1.0)
    out = {}
    for code in CODES:
        if code in flags and np.any(flags[code][0]):
            rows = np.flatnonzero(flags[code][0])
            out[code] = {"count": int(rows.size), "samples": rows.tolist(),
                         "limit": flags[code][1]}
    return out
