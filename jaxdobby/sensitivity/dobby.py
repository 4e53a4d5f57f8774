"""The dobby as a Sobol model: any scalar float parameter of the machine, steady-state metrics.

:data:`DOBBY` plugs the coupled dobby model into the Sobol pipeline (:class:`ModelSpec`). Its
registry is :data:`jaxdobby.parameters.PARAMETERS` (every scalar float parameter of the machine
and the operating point, in the users' units of the configuration file); the default problem is
the source study's: speed 400–1200 r/min, peak warp force 345–1035 N, stroke 80–140 mm and arm
plate thickness 6–8 mm (DESIGN.md §6). Parameters a problem does not vary keep the values of
the base machine (the built-in default unless :func:`dobby_model` is given another).

One sample row is evaluated by :func:`jaxdobby.periodic.steady_state_metrics` (the two-way coupled
equations, periodic steady state by collocation and chord shooting, extremes reduced inside the
solve) and returns, in the users' units of ``jaxdobby simulate``'s summary:

``deviation_pp_mm``, ``deviation_max_mm``, ``deviation_min_mm`` (heald frame displacement
deviation, flexible − rigid), ``velocity_deviation_amp_m_s`` and ``acceleration_amp_m_s2``
(peak-to-peak ranges over the cycle), plus ``ok`` (False when the periodic state did not
converge, the chain left its workspace, or a metric is not finite: a *failed sample*) and the
validity outputs ``validity.converged``, ``validity.resonances``
(:mod:`jaxdobby.sensitivity.validity`: counted per sample, no indices).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..periodic import DEFAULT_STEPS, steady_state_metrics
from ..periodic.steady import steps_for_speed
from ..parameters import PARAMETERS, Setup, apply
from ..stroke import arc_length_for_stroke, stroke_range
from .models import ModelSpec
from .space import ParameterSpace, ParameterSpec
from .validity import resonance_count

VECTOR_PARAMETERS = ("depth_positions",)
"""Parameters that are lists (not sampled; ``depth`` is sampled as a uniform depth)."""

METRIC_UNITS = {
    "deviation_pp": ("deviation_pp_mm", 1e3),
    "deviation_max": ("deviation_max_mm", 1e3),
    "deviation_min": ("deviation_min_mm", 1e3),
    "velocity_deviation_amp": ("velocity_deviation_amp_m_s", 1.0),
    "acceleration_amp": ("acceleration_amp_m_s2", 1.0),
}
"""Batch metric (SI) → (output name, factor to the users' unit)."""

DOBBY_PARAMETERS: dict[str, ParameterSpec] = {
    p.name: ParameterSpec(p.name, unit=p.unit or "1", bounds=p.bounds, si_scale=p.scale,
                          limits=(float(p.limits[0]), float(p.limits[1])), description=p.description)
    for p in PARAMETERS.values() if p.name not in VECTOR_PARAMETERS
}
"""Every scalar float parameter of the model, with the default Sobol bounds where it has one."""

DEFAULT_PROBLEM = ("speed", "warp_force", "stroke", "thickness")
"""The source study's four parameters (DESIGN.md §6)."""


def dobby_model(base: Setup | None = None, *, steps: int | None = None,
                tolerance: float = 1e-5):
    """``build(space)`` for the dobby: a pure function of one sample row (see the module).

    Args:
        base: the machine and operating point the samples start from (default: built-in).
        steps: collocation steps per cycle (:func:`jaxdobby.periodic.steady_state_metrics`);
            None: by the row's speed (``steps="speed"``: the fewest that keep the accuracy of
            432 steps at 400 r/min; a batch integrates its rows' most, so the pipeline groups
            rows by it, :func:`step_groups`).
        tolerance: relative periodicity residual of the steady state.
    """
    steps = "speed" if steps is None else steps
    def build(space: ParameterSpace):
        names, scales = space.names, space.si_scales
        start = Setup() if base is None else base  # built here: needs float64 switched on

        check_strokes(space, start)

        def model(x):
            setup, ok = setup_of_row(start, names, scales, x)
            # the resonance check takes its frequencies from the model the solve assembles
            out = steady_state_metrics(setup, steps=steps, tolerance=tolerance,
                                       frequencies=True)
            metrics = {name: out[key] * factor for key, (name, factor) in METRIC_UNITS.items()}
            metrics["ok"] = out["ok"] & ok
            # validity outputs (jaxdobby.sensitivity.validity): not metrics
            metrics["validity.converged"] = (out["periodicity"] <= tolerance).astype(float)
            metrics["validity.resonances"] = resonance_count(setup.operating.speed,
                                                             out["frequencies"])
            return metrics

        return model

    return build


def step_groups(space: ParameterSpace, samples) -> np.ndarray | None:
    """Steps per cycle of each row of ``samples`` under the default build (by its speed,
    :func:`jaxdobby.periodic.steady.steps_for_speed`), (M,) ints; None when the speed is not
    sampled (every row then the base machine's)."""
    if "speed" not in space.names:
        return None
    i = space.names.index("speed")
    return np.asarray(steps_for_speed(np.asarray(samples)[:, i] * space.si_scales[i]))


def setup_of_row(base: Setup, names, scales, x):
    """The machine and operating point of one sample row: ``base`` with the row's values (users'
    units, times ``scales`` to SI) of the parameters ``names``, a stroke set through the
    link-11 joint's arc length on the slot (:func:`jaxdobby.stroke.arc_length_for_stroke`).
    Returns (setup, ok): ok is False for a stroke the slot cannot give (possible when the
    linkage is sampled too), which is then replaced by the nearest reachable one (a failed
    sample, not a run-time error that would stop the whole batch; no ``eqx.error_if`` in the
    batch: host callbacks can stall programs sharded over CPU devices). Jittable, vmappable.
    """
    values = {n: x[i] * scales[i] for i, n in enumerate(names)}
    target = values.pop("stroke", None)
    setup = apply(base, values)
    ok = jnp.array(True)
    if target is not None:
        chain = setup.machine.chain
        lo, hi = stroke_range(chain)
        ok = (target >= lo) & (target <= hi)
        s = arc_length_for_stroke(chain, jnp.clip(target, lo, hi), check=False)
        setup = eqx.tree_at(lambda u: u.machine, setup, setup.machine.with_link11_arc_length(s))
    return setup, ok


def check_strokes(space: ParameterSpace, base: Setup) -> None:
    """Refuse stroke bounds the base machine's slot cannot give (when no linkage dimension is
    sampled, the reachable range is fixed and known before the run)."""
    if "stroke" not in space.names or any(PARAMETERS[n].section == "linkage"
                                          for n in space.names):
        return
    lo, hi = (float(v) * 1e3 for v in stroke_range(base.machine.chain))
    b_lo, b_hi = space.bounds[space.names.index("stroke")]
    if b_lo < lo or b_hi > hi:
        raise ValueError(f"parameter 'stroke': bounds must lie in the reachable range "
                         f"[{lo:.2f}, {hi:.2f}] mm of this machine's slot; got "
                         f"[{b_lo}, {b_hi}]")


DOBBY = ModelSpec("dobby", DOBBY_PARAMETERS, DEFAULT_PROBLEM, dobby_model(),
                  lambda steps: dobby_model(steps=steps), DEFAULT_STEPS, step_groups)
"""The dobby (built-in default machine) as a Sobol model."""
