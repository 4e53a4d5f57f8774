"""The arm's stress over a run's steady cycle, and its metrics in SI.

:func:`run_stress` recovers the edge stresses of a :class:`~jaxdobby.simulate.Simulation` at
every saved time (mode acceleration by default, :mod:`jaxdobby.stress.correction`) and reduces
them to the metrics the command line reports:

=======================  ========================================================================
``stress_max``           largest |σ| over the arm, both edges and the cycle [Pa]
``stress_max_position``  arc length of that point from the pivot [m]
``stress_max_edge``      0 = left edge, 1 = right edge (looking from the pivot to the tip)
``stress_range``         σ_max − σ_min over the cycle at that point [Pa]
``stress_mean``          (σ_max + σ_min)/2 there [Pa]
``fatigue_safety_factor``  Goodman factor n, the smallest over all points (:mod:`.fatigue`)
``fatigue_position``     arc length where it is smallest [m]; ``fatigue_edge`` its edge
``stress_max_smooth``    smooth surrogate of ``stress_max`` [Pa] (for gradients)
``fatigue_utilisation_smooth``  smooth surrogate of 1/n [-]
``endurance_limit``      the endurance limit of the Goodman line, σ_e = k_a·k_b·σ_e′ [Pa]
=======================  ========================================================================

Extremes are those of the saved samples (four per collocation step: 1728 per cycle by default).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from ..arm import arm_beam
from .correction import arm_stress, cycle_stress
from .fatigue import (endurance_limit, goodman_factor, smooth_fatigue_utilisation,
                      smooth_peak_stress)
from .recovery import edge_points


class CycleStress(eqx.Module):
    """Edge stresses over one cycle and their metrics.

    Attributes:
        sigma: stresses [Pa], shape (n_t, n_elements, n_points, 2).
        arc_lengths: arc length of each recovery point [m], (n_elements, n_points).
        edges: body-frame positions of both edges at each point [m], (n_elements, n_points, 2, 2).
        critical: stress at the point of ``stress_max`` over the cycle [Pa], (n_t,).
        metrics: see the module docstring.
    """

    sigma: Array
    arc_lengths: Array
    edges: Array
    critical: Array
    metrics: dict[str, Array]


def stress_metrics(sigma: Array, arc_lengths: Array, arm) -> dict[str, Array]:
    """The metrics of the module docstring from stresses (n_t, n_el, n_pts, 2) [Pa]."""
    n_t = sigma.shape[0]
    flat = sigma.reshape(n_t, -1)
    hi, lo = jnp.max(flat, axis=0), jnp.min(flat, axis=0)
    peak = jnp.maximum(hi, -lo)
    i = jnp.argmax(peak)
    s = jnp.repeat(arc_lengths.reshape(-1), 2)
    edge = jnp.tile(jnp.arange(2), arc_lengths.size)
    ultimate, endurance = arm.ultimate_strength, endurance_limit(arm)
    factor = goodman_factor(hi, lo, ultimate, endurance)
    j = jnp.argmin(factor)
    return dict(
        stress_max=peak[i], stress_max_position=s[i], stress_max_edge=edge[i],
        stress_range=hi[i] - lo[i], stress_mean=0.5 * (hi[i] + lo[i]),
        fatigue_safety_factor=factor[j], fatigue_position=s[j], fatigue_edge=edge[j],
        stress_max_smooth=smooth_peak_stress(sigma),
        fatigue_utilisation_smooth=smooth_fatigue_utilisation(sigma, ultimate, endurance),
        endurance_limit=endurance,
    )


@eqx.filter_jit
def run_stress(run, correction: bool = True, basis=None) -> CycleStress:
    """Stress over the steady cycle of ``run`` (:func:`jaxdobby.simulate.simulate`).

    Args:
        run: the simulation; correction: static correction of the truncated modes (mode
            acceleration) or plain mode displacement; basis: as given to ``simulate``.
    """
    model = run.model
    stress = arm_stress(model, basis)
    sigma = cycle_stress(model, run.series, stress, correction=correction,
                         motion=run.arm_motion)
    arm = model.machine.arm
    metrics = stress_metrics(sigma, stress.operator.arc_lengths, arm)
    n_t = sigma.shape[0]
    critical = sigma.reshape(n_t, -1)[:, jnp.argmax(jnp.max(jnp.abs(sigma.reshape(n_t, -1)),
                                                            axis=0))]
    return CycleStress(sigma=sigma, arc_lengths=stress.operator.arc_lengths,
                       edges=edge_points(arm_beam(arm), stress.operator), critical=critical,
                       metrics=metrics)


def stress_arrays(stress: CycleStress) -> dict[str, Array]:
    """``stress`` as a flat dict of arrays keyed ``stress.*`` (the stored program's outputs,
    :func:`jaxdobby.simulate.report_arrays`); :func:`stress_of_arrays` inverts it."""
    out = {f"stress.{k}": getattr(stress, k) for k in ("sigma", "arc_lengths", "edges", "critical")}
    out.update({f"stress.metric.{k}": v for k, v in stress.metrics.items()})
    return out


def stress_of_arrays(arrays: dict) -> CycleStress:
    """The :class:`CycleStress` of :func:`stress_arrays`' dict."""
    metrics = {k.removeprefix("stress.metric."): v for k, v in arrays.items()
               if k.startswith("stress.metric.")}
    return CycleStress(sigma=arrays["stress.sigma"], arc_lengths=arrays["stress.arc_lengths"],
                       edges=arrays["stress.edges"], critical=arrays["stress.critical"],
                       metrics=metrics)
