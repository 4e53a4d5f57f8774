"""Normalised dwell-rise-dwell motion laws of cams and indexing drives.

A motion law maps normalised time τ ∈ [0, 1] of one index (rise) to normalised displacement
s(τ) ∈ [0, 1] with s(0) = 0, s(1) = 1 and zero velocity s'(τ) at both ends, so the follower
dwells before and after the rise. Every law here is also symmetric, s(τ) = 1 − s(1 − τ), and has
zero acceleration at both ends (no jerk spike at the dwell joins except for the modified
trapezoid's finite jerk). τ outside [0, 1] is clipped, so s is 0 before and 1 after the rise and
its derivatives there are exactly zero: a modulator can feed it raw time and get exact dwells.

The characteristic values are the peak normalised velocity Cv = max s' and peak acceleration
Ca = max |s''| (VDI 2143; Rothbart, *Cam Design Handbook*, 2004, ch. 3; Norton, *Cam Design and
Manufacturing Handbook*, 2nd ed., 2009, ch. 3):

=====================  ======  ======  =============================================
law                    Cv      Ca      formula (first half; second half by symmetry)
=====================  ======  ======  =============================================
``modified_sine``      1.760   5.528   sine acceleration pulses of quarter/three-quarter period
``cycloidal``          2.000   6.283   s = τ − sin(2πτ)/(2π)
``polynomial_345``     1.875   5.774   s = 10τ³ − 15τ⁴ + 6τ⁵
``modified_trapezoid`` 2.000   4.888   sine ramps over 1/8, constant acceleration over 1/4
=====================  ======  ======  =============================================

All laws are written with ``jnp.where`` over closed-form segments that join with continuous
displacement, velocity and acceleration, so forward- and reverse-mode autodiff (to second order)
is exact inside each segment and continuous across the joins.

Example::

    from jaxdobby.motion_laws import motion_law
    law = motion_law("modified_sine")
    law.displacement(0.5)        # 0.5
    law.peak_velocity            # 4π/(4+π) ≈ 1.7596
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import jax.numpy as jnp
from jax import Array

_PI = math.pi


def _symmetric(first_half: Callable[[Array], Array]) -> Callable[[Array], Array]:
    """Complete a law from its first half by point symmetry about (1/2, 1/2), clipping τ to [0, 1].

    s(τ) = f(τ) for τ ≤ 1/2 and 1 − f(1 − τ) otherwise. Both branches are finite everywhere, so
    ``jnp.where`` gives clean gradients (no NaN leaking from the branch not taken).
    """

    def law(tau):
        tau = jnp.clip(jnp.asarray(tau, dtype=float), 0.0, 1.0)
        return jnp.where(tau <= 0.5, first_half(tau), 1.0 - first_half(1.0 - tau))

    law.__doc__ = first_half.__doc__
    return law


@_symmetric
def modified_sine(tau):
    """Modified sine law (Kloomok & Muffley 1955), Cv = 4π/(4+π), Ca = 4π²/(4+π).

    s = (πτ − ¼ sin 4πτ)/(4+π) for τ ≤ 1/8 and s = (2 + πτ − 9/4 sin(π/3 + 4πτ/3))/(4+π) for
    1/8 ≤ τ ≤ 7/8 (Rothbart 2004, table 3.4).
    """
    k = 4.0 + _PI
    early = (_PI * tau - 0.25 * jnp.sin(4.0 * _PI * tau)) / k
    middle = (2.0 + _PI * tau - 2.25 * jnp.sin(_PI / 3.0 + 4.0 * _PI * tau / 3.0)) / k
    return jnp.where(tau <= 0.125, early, middle)


@_symmetric
def cycloidal(tau):
    """Cycloidal law, s = τ − sin(2πτ)/(2π); Cv = 2, Ca = 2π."""
    return tau - jnp.sin(2.0 * _PI * tau) / (2.0 * _PI)


@_symmetric
def polynomial_345(tau):
    """3-4-5 polynomial, s = 10τ³ − 15τ⁴ + 6τ⁵; Cv = 15/8, Ca = 10/√3."""
    return tau**3 * (10.0 + tau * (-15.0 + 6.0 * tau))


_TRAP_CA = 8.0 * _PI / (2.0 + _PI)  # from s(1/2) = 1/2 with the acceleration shape below


@_symmetric
def modified_trapezoid(tau):
    """Modified trapezoid law, Cv = 2, Ca = 8π/(2+π).

    Acceleration A sin(4πτ) on [0, 1/8], A on [1/8, 3/8], A cos(4π(τ − 3/8)) on [3/8, 1/2],
    integrated twice in closed form; A follows from s(1/2) = 1/2 (Norton 2009, §3.9).
    """
    a = _TRAP_CA
    w = 4.0 * _PI
    v1 = a / w  # velocity at τ = 1/8
    s1 = a / w * (0.125 - 1.0 / w)  # displacement at τ = 1/8
    v2 = v1 + 0.25 * a  # at τ = 3/8
    s2 = s1 + 0.25 * v1 + 0.5 * a * 0.25**2
    ramp_up = a / w * (tau - jnp.sin(w * tau) / w)
    u = tau - 0.125
    constant = s1 + v1 * u + 0.5 * a * u**2
    r = tau - 0.375
    ramp_down = s2 + v2 * r + a / w**2 * (1.0 - jnp.cos(w * r))
    return jnp.where(tau <= 0.125, ramp_up, jnp.where(tau <= 0.375, constant, ramp_down))


class MotionLaw(NamedTuple):
    """A named motion law with its characteristic values.

    Attributes:
        name: registry key.
        displacement: s(τ), elementwise, τ clipped to [0, 1].
        peak_velocity: Cv = max ds/dτ (closed form).
        peak_acceleration: Ca = max |d²s/dτ²| (closed form).
    """

    name: str
    displacement: Callable[[Array], Array]
    peak_velocity: float
    peak_acceleration: float


MOTION_LAWS: dict[str, MotionLaw] = {
    "modified_sine": MotionLaw(
        "modified_sine", modified_sine, 4.0 * _PI / (4.0 + _PI), 4.0 * _PI**2 / (4.0 + _PI)
    ),
    "cycloidal": MotionLaw("cycloidal", cycloidal, 2.0, 2.0 * _PI),
    "polynomial_345": MotionLaw("polynomial_345", polynomial_345, 1.875, 10.0 / math.sqrt(3.0)),
    "modified_trapezoid": MotionLaw("modified_trapezoid", modified_trapezoid, 2.0, _TRAP_CA),
}
"""Registry of the available motion laws by name; ``"modified_sine"`` is the default."""

DEFAULT_MOTION_LAW = "modified_sine"


def motion_law(name: str) -> MotionLaw:
    """Look a motion law up by name; raise ``ValueError`` listing the valid names otherwise."""
    try:
        return MOTION_LAWS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown motion law {name!r}: choose one of {', '.join(sorted(MOTION_LAWS))}"
        ) from None
