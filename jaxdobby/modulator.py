"""The modulator: the eccentric's intermittent rotation, 180° per pick with a dwell.

The loom's main shaft turns uniformly, ψ = speed·t. Per pick (one main-shaft turn, 2π) the
modulator holds the eccentric still for a dwell of ``dwell`` [rad of ψ] centred on shed-open,
then turns it by ``index_angle`` (π) over the rest of the pick, 2π − dwell, following a
normalised motion law s(τ) (:mod:`jaxdobby.motion_laws`; modified sine by default). Two picks
turn the eccentric once, so the heald-frame cycle lasts T = 2·2π/speed (DESIGN.md §6 "drive",
"modulator").

With t = 0 the middle of a dwell, and n the number of the pick (counting from the one whose
dwell contains t = 0),

    ψ' = speed·t + dwell/2,   n = ⌊ψ'/2π⌋,   τ = (ψ' − 2πn − dwell)/(2π − dwell),
    φ(t) = φ₀ + index_angle·(n + s(τ)),

with s(τ) = 0 for τ ≤ 0 (the dwell) and s continuous into the next pick (s(1) = 1 = the next
pick's n + 0). ⌊·⌋ is piecewise constant and s is clipped, so dφ/dt and d²φ/dt² are exactly
zero during dwells and forward-mode autodiff in t is exact everywhere else.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
from jax import Array

from .motion_laws import DEFAULT_MOTION_LAW, motion_law

_TWO_PI = 2.0 * math.pi


def pick_period(speed) -> Array:
    """Duration of one pick [s] (one main-shaft turn) at loom speed ``speed`` [rad/s]."""
    return _TWO_PI / jnp.asarray(speed, dtype=float)


def cycle_period(speed) -> Array:
    """Duration [s] of one heald-frame cycle (two picks, one eccentric turn) at ``speed`` [rad/s]."""
    return 2.0 * pick_period(speed)


def crank_angle(
    t,
    speed,
    *,
    dwell,
    start_angle=0.0,
    law: str = DEFAULT_MOTION_LAW,
    index_angle=math.pi,
) -> Array:
    """Eccentric (crank) angle φ(t) [rad] of the modulator, elementwise in t.

    Args:
        t: time [s], any shape; t = 0 is the middle of a dwell.
        speed: loom main-shaft speed [rad/s], > 0, broadcastable with t.
        dwell: dwell per pick in main-shaft angle [rad], 0 < dwell < 2π.
        start_angle: φ₀, the crank angle during the dwell around t = 0 [rad].
        law: name of the index motion law (static).
        index_angle: eccentric turn per pick [rad] (π for the rotary dobby).

    Returns:
        φ(t) [rad], shape ``broadcast(t, speed).shape``; it increases without wrapping.
    """
    shape_law = motion_law(law).displacement
    psi = jnp.asarray(speed, dtype=float) * jnp.asarray(t, dtype=float) + 0.5 * dwell
    # φ = φ₀ + π(n + s(τ)) with n = ⌊u⌋ completed picks, u = ψ/2π, written as
    # φ₀ + π(u − [f − s(τ(f))]) with f = u − ⌊u⌋: the bracket is 0 at f = 0 and at f = 1, so the
    # angle stays continuous even where XLA evaluates ⌊u⌋ twice with different rounding (seen on
    # CPU at a pick boundary inside a large vectorised program: one pick off, the heald frame at
    # the wrong end of its stroke for one sample).
    u = psi / _TWO_PI
    f = u - jnp.floor(u)
    tau = (_TWO_PI * f - dwell) / (_TWO_PI - dwell)
    return start_angle + index_angle * (u - (f - shape_law(tau)))
