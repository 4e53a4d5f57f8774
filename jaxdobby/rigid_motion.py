"""Rigid motion of the lifting chain in time: arm angle θ(t), heald-frame height y_H(t), rates.

The modulator (:mod:`jaxdobby.modulator`) drives the eccentric from the crank-rocker's extended
dead centre: t = 0 is the middle of a dwell with the heald frame at the **bottom** of its stroke;
the first pick lifts it, it dwells at the top around t = T/2, the second pick lowers it
(T = 4π/speed, :func:`jaxdobby.modulator.cycle_period`). The dwells are exactly at the bottom
dead centre and 180° of crank later; the default crank-rocker is centric to 0.011°, so the top
dwell sits that far from the folded dead centre — at a stationary point of θ(φ), which makes the
top-dwell height lower than the true extreme by ~1e-9 m only.

Velocities and accelerations come from forward-mode autodiff in time (nested ``jax.jvp``,
:func:`time_derivatives`), never from hand-derived formulas. All functions take ``speed`` as an
array argument [rad/s of the loom main shaft] and are elementwise in ``t`` (any shape), so they
jit once and vmap over speeds and linkages.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from . import modulator
from ._x64 import require_x64
from .kinematics import (
    DobbyLinkage,
    arm_angle_from_crank,
    dead_centres,
    heald_frame_height_from_arm,
    link11_joint_position,
    ring_link_direction_from_crank,
)


def time_derivatives(f, t):
    """(f(t), f'(t), f''(t)) of an elementwise function of time by nested forward-mode autodiff.

    ``f`` must act elementwise on ``t`` (output shape ``t.shape + extra``): one ``jax.jvp`` with a
    unit tangent gives f', a ``jax.jvp`` of that gives f''.
    """
    t = jnp.asarray(t, dtype=float)
    ones = jnp.ones_like(t)

    def value_and_rate(tt):
        return jax.jvp(f, (tt,), (ones,))

    (value, rate), (_, acceleration) = jax.jvp(value_and_rate, (t,), (ones,))
    return value, rate, acceleration


def crank_angle(linkage: DobbyLinkage, t, speed) -> Array:
    """Eccentric angle φ(t) [rad]: the modulator started at the extended (bottom) dead centre."""
    require_x64()
    (phi_bottom, _), _ = dead_centres(linkage)
    return modulator.crank_angle(
        t, speed, dwell=linkage.dwell, start_angle=phi_bottom, law=linkage.motion_law
    )


def arm_angle(linkage: DobbyLinkage, t, speed) -> Array:
    """Rigid arm angle θ(t) [rad] at times t [s] for loom speed ``speed`` [rad/s]."""
    return arm_angle_from_crank(linkage, crank_angle(linkage, t, speed))


def arm_motion(linkage: DobbyLinkage, t, speed) -> tuple[Array, Array, Array]:
    """Rigid arm angle θ [rad], angular velocity ω = θ̇ [rad/s], acceleration α = θ̈ [rad/s²]."""
    return time_derivatives(lambda tt: arm_angle(linkage, tt, speed), t)


def ring_link_direction(linkage: DobbyLinkage, t, speed) -> Array:
    """Unit vector (inertial) from the eccentric pin to the arm joint at t [s]; ``t.shape + (2,)``.

    The ring link's axial force acts on the arm along it (DESIGN.md §2 item 2).
    """
    return ring_link_direction_from_crank(linkage, crank_angle(linkage, t, speed))


def link11_joint_motion(linkage: DobbyLinkage, t, speed, s=None):
    """Rigid link-11 joint position [m], velocity [m/s], acceleration [m/s²], ``t.shape + (2,)``.

    ``s`` [m] is the joint's arc length on the arm (default ``linkage.link11_arc_length``).
    """
    return time_derivatives(
        lambda tt: link11_joint_position(linkage, arm_angle(linkage, tt, speed), s), t
    )


def heald_frame_motion(linkage: DobbyLinkage, t, speed, s=None):
    """Rigid heald-frame height y_H [m], velocity [m/s], acceleration [m/s²] at times t [s].

    y_H is positive up, measured from the level of the arm pivot B0 (negative: the frame hangs
    about 0.46 m below it).
    """
    return time_derivatives(
        lambda tt: heald_frame_height_from_arm(linkage, arm_angle(linkage, tt, speed), s), t
    )
