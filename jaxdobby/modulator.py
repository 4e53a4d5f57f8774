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

**Lift plans** (DESIGN.md §7). A frame's lift sequence b₀…b_{P−1} (1 = up in that pick's open
shed) turns the eccentric by π in pick k iff m_k = |b_k − b_{k−1}| = 1 (cyclically), dwelling
through the pick otherwise; the repeat lasts P picks. Pick k is the index ending at the dwell
centred on ψ = 2π(k + 1), then that dwell: t = 0 is the middle of the dwell of pick P − 1 (the
frame at b_{P−1}), as today's t = 0 is the middle of the bottom dwell, so the plan "10" is
today's law. With C(u) the moves completed by u (piecewise linear between the integers,
C(n) = Σ_{j<n} m_j, periodic extension with M = Σ m_j per repeat, found by ``jnp.interp``
without the floor of f, its derivative m_n·df/dt with the bracket's m_n) and n = ⌊u⌋,

    φ(t) = φ₀ + π·b_{P−1} + π·(C(u) − m_n·[f − s(τ)]),

the same bracket as above, zero at both ends of a pick, so φ stays continuous even if C(u)
and f disagree about which pick a boundary sample is in; for "10" (m ≡ 1, C(u) = u) it is
the formula above.
"""

from __future__ import annotations

import math

import jax
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


def pick_moves(plan) -> Array:
    """m_k = |b_k − b_{k−1}| (cyclic), 1 where the frame moves in pick k, shape (P,)."""
    plan = jnp.asarray(plan, dtype=float)
    return jnp.abs(plan - jnp.roll(plan, 1))


def plan_period(speed, picks: int) -> Array:
    """Duration [s] of a repeat of ``picks`` picks at loom speed ``speed`` [rad/s]."""
    return picks * pick_period(speed)


def crank_angle(
    t,
    speed,
    *,
    dwell,
    start_angle=0.0,
    law: str = DEFAULT_MOTION_LAW,
    index_angle=math.pi,
    plan=None,
) -> Array:
    """Eccentric (crank) angle φ(t) [rad] of the modulator, elementwise in t.

    Args:
        t: time [s], any shape; t = 0 is the middle of a dwell.
        speed: loom main-shaft speed [rad/s], > 0, broadcastable with t.
        dwell: dwell per pick in main-shaft angle [rad], 0 < dwell < 2π.
        start_angle: φ₀, the crank angle during the dwell around t = 0 [rad].
        law: name of the index motion law (static).
        index_angle: eccentric turn per pick [rad] (π for the rotary dobby).
        plan: the frame's lift sequence, shape (P,) of 0/1 floats (P static), or None: plain
            weave, a move every pick (see the module docstring).

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
    if plan is None:
        return start_angle + index_angle * (u - (f - shape_law(tau)))
    plan = jnp.asarray(plan, dtype=float)
    picks = plan.shape[0]
    moves = pick_moves(plan)
    knots = jnp.concatenate([jnp.zeros(1), jnp.cumsum(moves)])  # C(0) … C(P)
    repeats = jnp.floor(u / picks)
    done = knots[-1] * repeats + jnp.interp(u - picks * repeats, jnp.arange(picks + 1.0), knots)
    move = moves[jnp.mod(jnp.floor(u), picks).astype(int)]
    # C(u)'s derivative taken as m_n f' with the same m_n as the bracket's: jnp.interp's own
    # segment search could give a boundary sample the slope of pick n − 1 and the move m_n of
    # pick n, which keeps the angle continuous but not its derivatives (seen at LLVM level 0:
    # the rigid frame's acceleration 233 m/s² instead of 0 at one sample at the end of a move,
    # plan "1100", 1000 r/min, the adaptive reference's acceleration deviation 9 % off). Its
    # value stays interp's, continuous whichever pick a boundary sample is counted in.
    done = jax.lax.stop_gradient(done - move * f) + move * f
    return start_angle + index_angle * (plan[-1] + done - move * (f - shape_law(tau)))
