"""Kane's equations of a flexible body in a floating frame with a prescribed rigid motion.

The body frame has its origin O at ``pivot(t)`` [m] and turns by ``angle(t)`` = θ [rad] in the
inertial plane; ω = θ̇ and α = θ̈ (and the pivot acceleration a_O) come from forward-mode
autodiff of those functions, so any differentiable motion can be prescribed. A material point at
body-frame position x moves to x + u with u = N Φ q, and with A = A(θ), S = [[0, −1], [1, 0]]

    r̈ = a_O + A [ N Φ q̈ + 2ω S N Φ q̇ + α S (x + N Φ q) − ω² (x + N Φ q) ].

The partial velocities ∂ṙ/∂q̇ᵢ = A N Φᵢ turn d'Alembert's principle into (Kane & Levinson,
*Dynamics: Theory and Applications*, 1985, ch. 6; Banerjee, *Flexible Multibody Dynamics*, 2016)

    M q̈ + (C + 2ω G) q̇ + (K − ω² M_t + α G + K_g) q
        = ω² f_ω − α f_α + F_tr Aᵀ(g − a_O) + Σ_p Φ_pᵀ Aᵀ F_p,

with the invariants of :class:`~jaxdobby.flexible_body.FlexibleBody` (M, C, K, M_t, G = Φᵀ∫NᵀSN
dm Φ, f_ω = Φᵀ∫Nᵀx dm, f_α = Φᵀ∫NᵀSx dm, F_tr = Φᵀ∫Nᵀ dm), gravity g and inertial point forces
F_p, and the geometric stiffness K_g = s·(ω² K_ω − α K_α + Σ_c (Aᵀ(g − a_O))_c K_c +
Σ_p (Aᵀ F_p)·K_p) switched by the factor s ∈ [0, 1] (``stiffening``). The sign conventions are
checked by the tests (energy balance, rotating-beam frequencies, quasi-static limit), not trusted
from here.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from ._arrays import as_float

from .flexible_body import FlexibleBody



def rotation_matrix(angle) -> Array:
    """2×2 matrix A(θ) taking body-frame components to inertial components."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([[c, -s], [s, c]])


def derivatives(fn, t):
    """Value, first and second time derivative of ``fn(t)`` by nested forward-mode autodiff."""
    t = jnp.asarray(t, dtype=float)

    def value_and_rate(tau):
        return jax.jvp(fn, (tau,), (jnp.ones_like(tau),))

    (value, rate), (_, accel) = jax.jvp(value_and_rate, (t,), (jnp.ones_like(t),))
    return value, rate, accel


class FrameMotion(eqx.Module):
    """A prescribed rigid motion of a body frame: override :meth:`angle` (and :meth:`pivot`)."""

    def angle(self, t) -> Array:
        """Angle θ(t) of the body x axis from the inertial x axis [rad]."""
        raise NotImplementedError

    def pivot(self, t) -> Array:
        """Inertial position of the body-frame origin [m]; fixed at the origin by default."""
        return jnp.zeros(2) + 0.0 * t


class ConstantSpin(FrameMotion):
    """Rotation at constant angular velocity ``rate`` [rad/s] about a fixed pivot."""

    rate: Array = eqx.field(converter=as_float)

    def angle(self, t):
        return self.rate * t


class SpinUp(FrameMotion):
    """The Kane–Ryan–Banerjee (1987) spin-up manoeuvre of a rotating cantilever.

    θ(t) = (Ω/T)[t²/2 + (T/2π)²(cos(2πt/T) − 1)] for t < T, then Ω(t − T/2): the rate rises
    smoothly from 0 to ``final_rate`` Ω [rad/s] over ``duration`` T [s] and stays there.
    """

    final_rate: Array = eqx.field(converter=as_float)
    duration: Array = eqx.field(converter=as_float)

    def angle(self, t):
        big_t, omega = self.duration, self.final_rate
        c = big_t / (2.0 * jnp.pi)
        tt = jnp.minimum(t, big_t)
        ramp = omega / big_t * (0.5 * tt**2 + c**2 * (jnp.cos(tt / c) - 1.0))
        return ramp + omega * jnp.maximum(t - big_t, 0.0)


class FrameState(eqx.Module):
    """Rigid motion of the frame at one instant (inertial components unless said)."""

    angle: Array
    angular_velocity: Array
    angular_acceleration: Array
    pivot_acceleration: Array


def frame_state(motion: FrameMotion, t) -> FrameState:
    """θ, ω, α and the pivot acceleration of ``motion`` at time ``t`` [s]."""
    theta, omega, alpha = derivatives(motion.angle, t)
    _, _, a_o = derivatives(motion.pivot, t)
    return FrameState(theta, omega, alpha, a_o)


def kane_terms(body: FlexibleBody, frame: FrameState, q: Array, qdot: Array, *,
               point_forces: Array | None = None, preload_forces: Array | None = None,
               gravity=(0.0, 0.0), stiffening=1.0):
    """Generalised mass matrix and force of the flexible body: ``mass @ q̈ = force``.

    Args:
        body: modal invariants.
        frame: rigid motion of the frame at this instant (:func:`frame_state`).
        q, qdot: modal coordinates and rates, shape (n_modes,).
        point_forces: inertial forces [N] at ``body.points``, shape (n_points, 2); they also
            stiffen the beam through ``body.point_stiffening``.
        preload_forces: inertial forces [N] at ``body.points`` that enter the geometric
            stiffness only (forces whose work is already accounted for elsewhere, e.g. a link
            force transmitted through coupling terms), shape (n_points, 2).
        gravity: inertial gravity vector [m/s²].
        stiffening: factor s on the geometric stiffness (1 = on, 0 = off).

    Returns:
        ``(mass, force)`` with shapes (k, k) and (k,).
    """
    omega, alpha = frame.angular_velocity, frame.angular_acceleration
    a_t = rotation_matrix(frame.angle).T
    field = a_t @ (jnp.asarray(gravity, dtype=float) - frame.pivot_acceleration)
    kg = body.stiffening
    k_geo = omega**2 * kg["centrifugal"] - alpha * kg["euler"] + field[0] * kg["x"] + field[1] * kg["y"]
    force = omega**2 * body.centrifugal - alpha * body.euler + body.translation @ field
    if point_forces is not None:
        local = point_forces @ a_t.T  # body-frame components, (n_points, 2)
        force = force + jnp.einsum("pck,pc->k", body.points, local)
        k_geo = k_geo + jnp.einsum("pckl,pc->kl", body.point_stiffening, local)
    if preload_forces is not None:
        k_geo = k_geo + jnp.einsum("pckl,pc->kl", body.point_stiffening, preload_forces @ a_t.T)
    stiffness = (body.stiffness - omega**2 * body.translational_mass + alpha * body.gyroscopic
                 + stiffening * k_geo)
    damping = body.damping + 2.0 * omega * body.gyroscopic
    return body.mass, force - damping @ qdot - stiffness @ q
