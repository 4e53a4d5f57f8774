"""Everything of one cycle that does not depend on the elastic state, tabulated once per sample.

**Normalised time.** With τ = t/T ∈ [0, 1) the phase of the heald-frame cycle, the modulator's
crank angle is a function of τ alone (ψ = speed·t = 4πτ), so the rigid arm angle θ(τ), its
τ-derivatives θ', θ'' and the ring link's direction n(τ) depend on the linkage only, not on the
speed, the stroke setting or the arm; in physical time ω = θ'/T and α = θ''/T². Every sample of
a batch therefore uses the same grid of τ (a fixed number of steps per cycle, a static size), and
under ``jax.vmap`` the rigid-arm tables of :func:`rigid_arm` are computed once per batch when the
linkage is not sampled (they do not depend on batched values).

**Kane's terms.** The arm's part of :func:`jaxdobby.dobby.equations_at` is linear in (q, q̇)
with coefficients that are combinations of constant modal matrices (:func:`arm_terms`):

    K(τ) = K_b + ω²(K_ω − M_t) + α(G − K_α) + a_x K_x + a_y K_y + f_x K_P,x + f_y K_P,y
           + k₉ R_rᵀ (n nᵀ − n₀ n₀ᵀ) R_r,
    C(τ) = C_b + 2ω G,     f(τ) = ω² f_ω − α f_α + F_tr a,

(:func:`jaxdobby.floating_frame.kane_terms` with the ring link's correction of
:mod:`jaxdobby.dobby`), a = Aᵀ(0, −g) the gravity field in the body frame and f the preload of
link 11 from rigid inverse dynamics (:func:`jaxdobby.periodic.chain.chain_terms` at q = 0). K(τ) and
f(τ) are tabulated at the collocation nodes τ = (n + cᵢ)/N by one contraction of a stack of
matrices with their coefficients.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from ..dobby import LINK, RING, DobbyModel, crank_angle
from ..kinematics import arm_angle_from_crank, ring_link_direction_from_crank
from ..rigid_motion import time_derivatives
from .chain import Downstream, Frame, chain_terms
from .collocation import NODES, stored

REFERENCE_SPEED = 4.0 * jnp.pi
"""Loom speed [rad/s] whose cycle lasts 1 s: rigid tables are evaluated with it at t = τ (a
lift plan of P picks: 2πP, its repeat lasting 1 s)."""


class ArmTerms(eqx.Module):
    """Kane's modal terms of one arm (see the module docstring); k modes.

    Attributes:
        mass: M_b (k, k). damping: C_b (k, k) [1/s]. gyroscopic: G (k, k).
        stiffness: the stack [K_b − k₉R_rᵀn₀n₀ᵀR_r, K_ω − M_t, G − K_α, K_x, K_y, K_P,x, K_P,y,
            k₉R_rᵀE₁₁R_r, k₉R_rᵀ(E₁₂ + E₂₁)R_r, k₉R_rᵀE₂₂R_r], (10, k, k).
        centrifugal: f_ω (k,). euler: f_α (k,). translation: F_tr (k, 2).
        gravity: g₀ [m/s²].
        ring_rows: Φ at the ring-link joint, body frame (2, k). ring_stiffness: k₉ [N/m].
    """

    mass: Array
    damping: Array
    gyroscopic: Array
    stiffness: Array
    centrifugal: Array
    euler: Array
    translation: Array
    gravity: Array
    ring_rows: Array
    ring_stiffness: Array


def arm_terms(model: DobbyModel) -> ArmTerms:
    """:class:`ArmTerms` of ``model`` (two-way coupling)."""
    b, m = model.body, model.machine
    kg = b.stiffening
    rows = b.points[RING]
    k9 = m.ring_link_stiffness
    n0 = model.ring_direction_ref

    def ring(e):
        return k9 * rows.T @ e @ rows

    stack = jnp.stack([
        b.stiffness - ring(jnp.outer(n0, n0)),
        kg["centrifugal"] - b.translational_mass,
        b.gyroscopic - kg["euler"],
        kg["x"], kg["y"],
        b.point_stiffening[LINK, 0], b.point_stiffening[LINK, 1],
        ring(jnp.array([[1.0, 0.0], [0.0, 0.0]])),
        ring(jnp.array([[0.0, 1.0], [1.0, 0.0]])),
        ring(jnp.array([[0.0, 0.0], [0.0, 1.0]])),
    ])
    return ArmTerms(mass=b.mass, damping=b.damping, gyroscopic=b.gyroscopic, stiffness=stack,
                    centrifugal=b.centrifugal, euler=b.euler, translation=b.translation,
                    gravity=m.gravity, ring_rows=rows, ring_stiffness=k9)


class RigidArm(eqx.Module):
    """The rigid arm at phases τ (any shape): cos θ, sin θ, θ' [rad], θ'' [rad] per unit τ, and
    the ring link's direction in the arm's body frame, shape τ.shape + (2,)."""

    phase: Array
    cos: Array
    sin: Array
    rate: Array
    accel: Array
    ring: Array


def rigid_arm(model: DobbyModel, phase) -> RigidArm:
    """:class:`RigidArm` at phases τ (speed-free; see the module docstring)."""
    return rigid_arm_of(model.chain, model.crank_start, phase, model.lift_plan,
                        None if model.lift_plan is None else model.picks)


def rigid_arm_of(chain, crank_start, phase, plan=None, picks=None) -> RigidArm:
    """:func:`rigid_arm` from the linkage ``chain`` and the crank angle at t = 0
    (``crank_start`` [rad], :attr:`jaxdobby.dobby.DobbyModel.crank_start`) alone: no finite
    elements, so a batch whose linkage is not sampled computes it once for all its lanes.
    ``plan``, ``picks``: a lift plan and its repeat in picks (None: plain weave)."""
    speed = REFERENCE_SPEED if plan is None else 2.0 * jnp.pi * picks

    def one(tau):
        def theta(t):
            return arm_angle_from_crank(chain, crank_angle(chain, crank_start, t, speed, plan))

        th, th1, th2 = time_derivatives(theta, tau)
        n = ring_link_direction_from_crank(chain, crank_angle(chain, crank_start, tau, speed,
                                                              plan))
        c, s = jnp.cos(th), jnp.sin(th)
        return RigidArm(tau, c, s, th1, th2, jnp.stack([c * n[0] + s * n[1], -s * n[0] + c * n[1]]))

    phase = jnp.asarray(phase, dtype=float)
    flat = jax.vmap(one)(phase.reshape(-1))
    return jax.tree.map(lambda a: a.reshape(phase.shape + a.shape[1:]), flat)


class StageTables(eqx.Module):
    """One sample's cycle at the collocation nodes, leading axes (N, 3) (or any shape).

    Attributes:
        frame: the arm frame (:class:`~jaxdobby.periodic.chain.Frame`) in physical time.
        stiffness: K(τ) (..., k, k). force: f(τ) (..., k) (see the module docstring).
        height, velocity, acceleration: rigid heald-frame height [m], velocity [m/s] and
            acceleration [m/s²].
        link_force: link 11's force on the rigid arm, body frame [N], (..., 2).
    """

    frame: Frame
    stiffness: Array
    force: Array
    height: Array
    velocity: Array
    acceleration: Array
    link_force: Array


def tables_at(arm: ArmTerms, ds: Downstream, rigid: RigidArm, period,
              rigid_lanes: bool = False) -> StageTables:
    """:class:`StageTables` at the phases of ``rigid`` for a cycle of ``period`` T [s].

    One sample: ``period`` a scalar. A batch with its lanes last (as
    :mod:`jaxdobby.periodic.steady` runs one): ``period`` (B,), every leaf of ``arm`` and ``ds``
    with a trailing lane axis, ``rigid`` shared by the lanes, or with ``rigid_lanes`` each
    lane's own, its leaves with the trailing lane axis too (``phase`` (..., B), ``ring``
    (..., 2, B)); every table then has the lanes last, e.g. ``stiffness`` (..., k, k, B).
    """
    lanes = jnp.shape(period)
    shape = rigid.phase.shape[:rigid.phase.ndim - len(lanes)] if rigid_lanes else rigid.phase.shape

    def node(a):  # a rigid table, broadcast against the lanes
        if rigid_lanes:
            return a
        return jnp.broadcast_to(a.reshape(a.shape + (1,) * len(lanes)), shape + lanes)

    def per_node(a, axes=1):  # a lane quantity (k..., lanes) against the phases' axes
        return jnp.expand_dims(a, tuple(range(len(shape), len(shape) + axes)))

    omega, alpha = node(rigid.rate) / period, node(rigid.accel) / period**2
    cos, sin = node(rigid.cos), node(rigid.sin)
    frame = Frame(cos, sin, omega, alpha, node(rigid.phase))
    zero = jnp.zeros(2)
    ct = jax.vmap(chain_terms, in_axes=(None, 0, None, None))(
        ds, jax.tree.map(lambda a: a.reshape((-1,) + lanes), frame), zero, zero)
    # kept in memory (a conditional XLA must materialise: without it the chain's terms are
    # recomputed in each of their consumers, once per entry of the k × k stiffness tables);
    # its key is a run-time value that is ≥ 0 whatever the period, even NaN
    ct = stored(jax.tree.map(lambda a: a.reshape(shape + a.shape[1:]), ct),
                jnp.isfinite(jnp.ravel(period)[0]).astype(int))
    link = ct.grad_body * per_node(ct.phi)  # link-11 force on the arm, body frame [N]
    link_x, link_y = (jnp.take(link, i, axis=len(shape)) for i in (0, 1))
    g0 = arm.gravity
    field_x, field_y = -g0 * sin, -g0 * cos
    n_x, n_y = (node(jnp.take(rigid.ring, i, axis=len(shape))) for i in (0, 1))
    coef = (jnp.ones(shape + lanes), omega**2, alpha, field_x, field_y, link_x, link_y, n_x**2,
            n_x * n_y, n_y**2)
    stiffness = sum(per_node(c, 2) * arm.stiffness[i] for i, c in enumerate(coef))
    force = (per_node(omega**2) * arm.centrifugal - per_node(alpha) * arm.euler
             + per_node(field_x) * arm.translation[:, 0]
             + per_node(field_y) * arm.translation[:, 1])
    return StageTables(frame=frame, stiffness=stiffness, force=force, height=ct.height,
                       velocity=ct.slope * ct.beta_rate,
                       acceleration=ct.slope * ct.h_beta + ct.curvature * ct.beta_rate**2,
                       link_force=link)


def node_phases(steps, size: int | None = None) -> Array:
    """τ at the collocation nodes of ``steps`` equal steps per cycle, shape (steps, 3); with
    ``size`` (static, ≥ steps), shape (size, 3), ``steps`` then possibly traced: the nodes of
    the first ``steps`` rows, the rest beyond the cycle's end (tables nobody reads)."""
    size = steps if size is None else size
    return (jnp.arange(size)[:, None] + jnp.asarray(NODES)[None, :]) / steps
