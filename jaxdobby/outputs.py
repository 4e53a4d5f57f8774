"""What a run reports: time series of the rigid and flexible mechanism, and the coupled modes.

Everything is computed from the state (q, q̇) of :mod:`jaxdobby.dobby` by the same autodiff
kinematics the equations use: the heald frame's flexible motion is c = G(t, q) with
ċ = G_t + G_q q̇ and c̈ = G_q q̈ + h (q̈ from the equations of motion), the rigid motion the same
at q = 0. Signs: heights and forces positive up; a *deviation* is flexible minus rigid.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from .dobby import (
    LINK,
    RING,
    DobbyModel,
    RigidState,
    chain_from_joint,
    chain_inertia,
    chain_kinematics,
    equations_at,
    generalised_chain_forces,
    rigid_joint_position,
    rigid_state,
)
from .floating_frame import rotation_matrix
from .rigid_motion import time_derivatives


class Timeseries(eqx.Module):
    """Time series over one steady-state heald-frame cycle (t = 0: middle of the bottom dwell).

    Attributes (shape (n,) unless said; SI units):
        t: time [s].
        heald_rigid, heald_flexible: heald-frame height [m] (positive up, from the pivot level).
        velocity_rigid, velocity_flexible: heald-frame velocity [m/s].
        acceleration_rigid, acceleration_flexible: heald-frame acceleration [m/s²].
        link_point_deviation: link-11 joint's flexible minus rigid position, inertial x and y
            [m], shape (n, 2).
        ring_link_force: axial force of the ring link 9, tension positive [N].
        link11_force: force of link 11 on the arm, inertial x and y [N], shape (n, 2).
        modal: modal coordinates q, shape (n, k).
        modal_rate: their rates q̇ [1/s per unit of q], shape (n, k).
    """

    t: Array
    heald_rigid: Array
    heald_flexible: Array
    velocity_rigid: Array
    velocity_flexible: Array
    acceleration_rigid: Array
    acceleration_flexible: Array
    link_point_deviation: Array
    ring_link_force: Array
    link11_force: Array
    modal: Array
    modal_rate: Array

    @property
    def deviation(self) -> Array:
        """Heald-frame displacement deviation, flexible − rigid [m]."""
        return self.heald_flexible - self.heald_rigid

    @property
    def velocity_deviation(self) -> Array:
        """Heald-frame velocity deviation [m/s]."""
        return self.velocity_flexible - self.velocity_rigid

    @property
    def acceleration_deviation(self) -> Array:
        """Heald-frame acceleration deviation [m/s²]."""
        return self.acceleration_flexible - self.acceleration_rigid


class ArmMotion(eqx.Module):
    """The arm's rigid motion and the modal accelerations at a run's saved times: what the
    static correction of the arm's stress needs (:mod:`jaxdobby.stress.correction`).

    Attributes (leading axis: the saved times, n):
        cos, sin: cos θ and sin θ of the rigid arm angle θ [-].
        rate: θ̇ [rad/s]. acceleration: θ̈ [rad/s²].
        ring_direction: unit vector of the ring link 9 in the arm's body frame, (n, 2).
        link_force: link 11's force on the arm in the rigid mechanism (inverse dynamics,
            the geometric stiffening's preload), body frame [N], (n, 2).
        modal_acceleration: q̈ from the equations of motion at the saved state, (n, k).
    """

    cos: Array
    sin: Array
    rate: Array
    acceleration: Array
    ring_direction: Array
    link_force: Array
    modal_acceleration: Array


def arm_motion(model: DobbyModel, series: Timeseries) -> ArmMotion:
    """:class:`ArmMotion` at the times of ``series`` by the autodiff kinematics of
    :mod:`jaxdobby.dobby` (:func:`~jaxdobby.dobby.rigid_state`,
    :func:`~jaxdobby.dobby.equations_at`); the collocation path computes the same from its
    closed-form tables (:func:`jaxdobby.periodic.dense.outputs_at`)."""

    def one(t, q, qdot):
        rigid = rigid_state(model, t)
        mass, force = equations_at(model, rigid, q, qdot)
        f = rigid.frame
        return ArmMotion(cos=jnp.cos(f.angle), sin=jnp.sin(f.angle), rate=f.angular_velocity,
                         acceleration=f.angular_acceleration,
                         ring_direction=rigid.ring_direction, link_force=rigid.link_force,
                         modal_acceleration=jnp.linalg.solve(mass, force))

    return jax.vmap(one)(series.t, series.modal, series.modal_rate)


def flexible_outputs(model: DobbyModel, rigid: RigidState, q, qdot) -> dict[str, Array]:
    """Flexible-mechanism outputs at one instant from the rigid state there and (q, q̇)."""
    t = rigid.time
    mass, force = equations_at(model, rigid, q, qdot)
    qddot = jnp.linalg.solve(mass, force)
    c, g_q, c_dot, h, c_prime = chain_kinematics(model, rigid, q, qdot)
    c_ddot = g_q @ qddot + h
    a = rotation_matrix(rigid.frame.angle)
    if model.machine.coupling == "one-way":
        link_force = a @ rigid.link_force
    else:
        d = chain_inertia(model)
        link_force = -c_prime.T @ (d * c_ddot - generalised_chain_forces(model, t, c[1]))
    ring = model.machine.ring_link_stiffness * rigid.ring_direction @ (model.body.points[RING] @ q)
    return dict(heald_flexible=c[1], velocity_flexible=c_dot[1], acceleration_flexible=c_ddot[1],
                link_point_deviation=a @ (model.body.points[LINK] @ q), ring_link_force=ring,
                link11_force=link_force, modal=q, modal_rate=qdot)


def rigid_outputs(model: DobbyModel, t) -> dict[str, Array]:
    """Rigid heald-frame height, velocity and acceleration at times ``t`` (any shape)."""
    def height(tt):
        return chain_from_joint(model, rigid_joint_position(model, tt))[1]

    y, v, acc = jax.vmap(lambda tt: time_derivatives(height, tt))(jnp.ravel(t))
    shape = jnp.shape(t)
    return dict(heald_rigid=y.reshape(shape), velocity_rigid=v.reshape(shape),
                acceleration_rigid=acc.reshape(shape))


def mid_lift_time(model: DobbyModel) -> Array:
    """Time [s] at which the rigid heald frame passes mid-stroke while lifting (Newton on t
    from a quarter cycle; the rigid height is monotonic over the lift)."""
    def height(tt):
        return chain_from_joint(model, rigid_joint_position(model, tt))[1] - model.mid_level

    def step(_, tt):
        value, slope = jax.jvp(height, (tt,), (jnp.ones_like(tt),))
        return tt - value / slope

    return jax.lax.fori_loop(0, 6, step, 0.25 * model.period)


def coupled_frequencies(model: DobbyModel, t=None) -> Array:
    """Natural frequencies [Hz] of the arm coupled to the downstream chain, frozen at time t.

    The undamped, speed-free linearisation about the rigid configuration at ``t`` (default: the
    frame at mid-stroke while lifting): mass M + G_qᵀ D G_q (the chain's inertia through the
    partial velocities), stiffness K with the ring link along its actual direction and, for the
    restoring warp law, the warp force's stiffness F_w/(H/2) on the heald frame.

    One compiled program (inlined where a caller traces it): called eagerly (notebooks, the
    pictures), its kinematics and eigenvalue problem were compiled operation by operation:
    1.0 s in a new process instead of 6.8 s (measured 2026-12-04, 2 cores, empty cache).
    """
    return _coupled_frequencies(model, None if t is None else jnp.asarray(t, dtype=float))


@eqx.filter_jit  # t an array (or None), so that a new time does not compile a new program
def _coupled_frequencies(model: DobbyModel, t) -> Array:
    return frequencies_of(*coupled_matrices(model, t))


def coupled_matrices(model: DobbyModel, t=None) -> tuple[Array, Array]:
    """(mass, stiffness), each (k, k): the linearisation of :func:`coupled_frequencies` at time
    ``t`` (no LAPACK call: vmappable over times or samples without batching one)."""
    if model.lift_plan is not None and t is None:
        # a configuration's property: the same at mid-stroke whatever the lift plan
        model = dataclasses.replace(model, lift_plan=None)
    t = mid_lift_time(model) if t is None else jnp.asarray(t, dtype=float)
    rigid = rigid_state(model, t)
    k = model.n_modes
    _, g_q, _, _, _ = chain_kinematics(model, rigid, jnp.zeros(k), jnp.zeros(k))
    d = chain_inertia(model)
    mass = model.body.mass + g_q.T @ (d[:, None] * g_q)
    rows = model.body.points[RING]
    n, n0 = rigid.ring_direction, model.ring_direction_ref
    k9 = model.machine.ring_link_stiffness
    stiffness = model.body.stiffness + k9 * (jnp.outer(rows.T @ n, rows.T @ n)
                                             - jnp.outer(rows.T @ n0, rows.T @ n0))
    if model.machine.warp_law == "restoring":
        warp_rate = model.operating.warp_force / (0.5 * model.stroke)
        stiffness = stiffness + warp_rate * jnp.outer(g_q[1], g_q[1])
    return mass, stiffness


def frequencies_of(mass: Array, stiffness: Array) -> Array:
    """Natural frequencies [Hz] of the undamped system (mass, stiffness), ascending (k,):
    the eigenvalues of L⁻¹KL⁻ᵀ, M = LLᵀ (LAPACK: Cholesky, triangular solves, ``eigvalsh``)."""
    chol = jnp.linalg.cholesky(mass)
    a = jax.scipy.linalg.solve_triangular(
        chol, jax.scipy.linalg.solve_triangular(chol, stiffness, lower=True).T, lower=True)
    lam = jnp.linalg.eigvalsh(0.5 * (a + a.T))
    return jnp.sqrt(jnp.clip(lam, 0.0)) / (2.0 * jnp.pi)
