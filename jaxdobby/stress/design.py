"""The arm's stress as smooth, differentiable design constraints (``jaxdobby optimize``).

For a design (a :class:`~jaxdobby.parameters.Setup`) at a loom speed, one steady cycle by
collocation (the optimiser's own path, :func:`jaxdobby.optimize.objective.cycle_values`) and the
stress recovery with static correction (:func:`jaxdobby.stress.cycle.run_stress`) give the smooth
surrogates of the peak stress and of the Goodman utilisation 1/n
(:mod:`jaxdobby.stress.fatigue`): log-sum-exp soft maxima over the cycle and the arm, exact
derivatives by forward or reverse mode through the periodic state (implicit function theorem),
the modes, and the recovery. The constraints are

    c_stress = smax(|σ|)/σ_limit − 1 ≤ 0,     c_fatigue = n_min · smax(1/n) − 1 ≤ 0,

the worst over the speeds.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from jax import Array

COLLOCATION_STEPS = 432


def stress_surrogates(setup, basis, speed, steps: int = COLLOCATION_STEPS) -> tuple[Array, Array]:
    """(smooth peak |σ| [Pa], smooth largest Goodman utilisation 1/n [-]) of ``setup`` at
    ``speed`` [rad/s], on the reduction ``basis`` (as :func:`jaxdobby.simulate.simulate`)."""
    from ..simulate import _simulate
    from .cycle import run_stress

    operating = dataclasses.replace(setup.operating, speed=speed)
    run = _simulate(setup.machine, operating, basis, method="collocation", steps=steps,
                    n_out=0, rtol=0.0, atol=0.0, tolerance=1e-9, forward_mode=False)
    m = run_stress(run, basis=basis).metrics
    return m["stress_max_smooth"], m["fatigue_utilisation_smooth"]


def stress_constraints(setup, basis, speeds, stress_limit=None, fatigue_floor=None) -> list:
    """The rows c ≤ 0 of the module docstring that are set (stress, then fatigue)."""
    values = [stress_surrogates(setup, basis, w) for w in speeds]
    peak = jnp.max(jnp.stack([v[0] for v in values]))
    utilisation = jnp.max(jnp.stack([v[1] for v in values]))
    out = []
    if stress_limit is not None:
        out.append(peak / stress_limit - 1.0)
    if fatigue_floor is not None:
        out.append(fatigue_floor * utilisation - 1.0)
    return out
