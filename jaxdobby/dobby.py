"""Two-way rigid–flexible coupled dynamics of the dobby's lifting mechanism.

The bending arm is the flexible body of :mod:`jaxdobby.floating_frame`, its frame turning with
the *rigid* arm angle θ(t) of the crank-rocker (:mod:`jaxdobby.rigid_motion`): pinned at the
pivot and held at the ring-link joint by the ring link, an axial spring k₉ whose direction n(t)
the rigid kinematics gives (the modes use its direction at mid-lift; the change of direction
over the cycle enters as the time-varying stiffness k₉Φ_rᵀ(n nᵀ − n_ref n_refᵀ)Φ_r).

Everything downstream of the arm — link 11, the big blade (inertia J_b about its pivot), the
tumblers and the heald frame (mass m_H) — is a rigid one-degree-of-freedom chain driven by the
*actual* position of the link-11 joint on the deformed arm, P = A(θ)(p + Φ_P q). Its coordinates
c = (β, y_H) = G(t, q) (blade angle and heald-frame height, :mod:`jaxdobby.kinematics`) have
partial velocities ∂c/∂q̇ = G_q, so by Kane's method the chain adds (DESIGN.md §2 item 5)

    mass   += G_qᵀ D G_q,                       D = diag(J_b, m_H),
    force  += G_qᵀ (Q − D h),                   c̈ = G_q q̈ + h,  h = d/dt(G_t + G_q q̇)|_{q̈=0},
    Q = (0, −m_H g + F_warp(y_H)),

all by forward-mode autodiff of G (no hand-derived Jacobians). The warp force follows the
flexible motion. Geometric stiffening of the arm comes from the rigid-motion loads and from the
link-11 force of rigid inverse dynamics, f_P = −(∂c/∂P)ᵀ(D c̈ − Q) at q = 0 (a preload: the
force itself acts through the coupling terms).

The source study's *one-way* variant replaces the downstream terms by f_P applied at the joint as
an external force, and only reads the heald-frame motion off the deformed arm.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from .arm import arm_beam, arm_supports
from .flexible_body import FlexibleBody, flexible_body
from .floating_frame import FrameState, kane_terms, rotation_matrix
from . import modulator
from .kinematics import (
    DobbyLinkage,
    arm_angle_from_crank,
    blade_angle,
    dead_centres,
    heald_frame_height_from_arm,
    heald_frame_height_from_blade,
    ring_link_direction_from_crank,
)
from .machine import Machine, OperatingPoint
from .modal import ModalBasis, modal_basis
from .rigid_motion import time_derivatives

RING, LINK = 0, 1
"""Indices of the ring-link joint and the link-11 joint among the flexible body's points."""


class DobbyModel(eqx.Module):
    """The coupled model of one machine at one operating point, ready to integrate.

    Attributes:
        machine, operating: the parameters it was built from.
        chain: the linkage with the arm's geometry (:attr:`Machine.chain`).
        body: modal invariants of the supported arm; points = (ring joint, link-11 joint).
        ring_direction_ref: ring-link direction in the arm's body frame used for the modes [-].
        link_joint: body-frame position of the link-11 joint on the undeformed arm [m].
        stroke: rigid heald-frame stroke H [m].
        mid_level: heald-frame height at mid-stroke (zero of the warp force) [m].
        crank_start: eccentric angle at the bottom dead centre [rad].
        lift_plan: the frame's lift sequence b₀…b_{P−1}, shape (P,) of 0/1 floats, or None for
            plain weave (a move every pick; :mod:`jaxdobby.modulator`). t = 0 is the middle
            of the dwell of pick P − 1 (plain weave: the bottom dwell).
    """

    machine: Machine
    operating: OperatingPoint
    chain: DobbyLinkage
    body: FlexibleBody
    ring_direction_ref: Array
    link_joint: Array
    stroke: Array
    mid_level: Array
    crank_start: Array
    lift_plan: Array | None = None

    @property
    def picks(self) -> int:
        """Picks in the periodic cycle (static): 2 for plain weave, else the plan's length."""
        return 2 if self.lift_plan is None else self.lift_plan.shape[-1]

    @property
    def period(self) -> Array:
        """The periodic cycle [s]: one heald-frame cycle (two picks) in plain weave, the repeat
        of the lift plan otherwise."""
        return modulator.plan_period(self.operating.speed, self.picks)

    @property
    def n_modes(self) -> int:
        return self.body.n_modes


def crank_angle(chain: DobbyLinkage, crank_start, t, speed, plan=None) -> Array:
    """Eccentric angle φ(t) [rad] of the modulator (t = 0: middle of the bottom dwell, or of
    the last pick's dwell of a lift ``plan``; :func:`jaxdobby.modulator.crank_angle`)."""
    return modulator.crank_angle(t, speed, dwell=chain.dwell, start_angle=crank_start,
                                 law=chain.motion_law, plan=plan)


def _reference_direction(chain: DobbyLinkage) -> Array:
    """Ring-link direction in the arm's frame at the middle of the lifting index [-]."""
    (phi_bottom, _), _ = dead_centres(chain)
    phi_ref = phi_bottom + 0.5 * jnp.pi
    return (rotation_matrix(arm_angle_from_crank(chain, phi_ref)).T
            @ ring_link_direction_from_crank(chain, phi_ref))


def arm_modes(machine: Machine) -> ModalBasis:
    """The modes :func:`build_model` reduces the arm with (supports at mid-lift), all DOFs.

    Their shapes, held fixed, are the reduction basis of a design study (``basis=`` of
    :func:`build_model`).
    """
    supports = arm_supports(_reference_direction(machine.chain), machine.ring_link_stiffness,
                            machine.arm.ring_joint_node)
    return modal_basis(arm_beam(machine.arm), supports, machine.n_modes)


def build_model(machine: Machine, operating: OperatingPoint, basis: Array | str | None = None,
                lift_plan=None) -> DobbyModel:
    """Assemble the arm, its modes at mid-lift and the chain's reference values (jittable).

    The modes use the ring-link direction at the middle of the lifting index (crank a quarter
    turn past the bottom dead centre), a configuration that does not depend on the speed.
    With ``basis`` (n_dofs, n_modes), e.g. ``arm_modes(reference).shapes``, the arm is reduced
    on that fixed basis instead of its own modes (:func:`jaxdobby.flexible_body.flexible_body`):
    no eigen-decomposition on the differentiated path; identical to the modal model when the
    basis is the machine's own modes. ``basis="own"``: the own modes, differentiated as the
    subspace they span (:func:`jaxdobby.modal.mode_subspace`; the design optimiser's choice).
    ``lift_plan``: the frame's lift sequence, (P,) 0/1 floats (or None: plain weave); with the
    ``restoring`` warp law only (the ``opposing`` law is defined by the plain weave's picks).
    """
    if lift_plan is not None:
        lift_plan = jnp.asarray(lift_plan, dtype=float)
        if machine.warp_law != "restoring":
            raise ValueError("a lift plan needs warp_law = 'restoring' (the 'opposing' law is "
                             f"defined for plain weave only), got {machine.warp_law!r}")
    return DobbyModel(machine=machine, operating=operating, lift_plan=lift_plan,
                      **machine_parts(machine, basis))


def machine_parts(machine: Machine, basis: Array | str | None = None) -> dict:
    """What :func:`build_model` assembles from the machine alone (the operating point only
    rides along): the fields ``chain``, ``body``, ``ring_direction_ref``, ``link_joint``,
    ``stroke``, ``mid_level`` and ``crank_start`` of a :class:`DobbyModel`, by name. A batch
    whose rows share a machine at different operating points builds them once per machine
    (:func:`jaxdobby.periodic.steady.model_terms`)."""
    chain = machine.chain
    (phi_bottom, _), (theta_bottom, theta_top) = dead_centres(chain)
    n_ref = _reference_direction(chain)
    supports = arm_supports(n_ref, machine.ring_link_stiffness, machine.arm.ring_joint_node)
    s_link = chain.link11_arc_length
    body = flexible_body(arm_beam(machine.arm), supports, machine.n_modes,
                         points=jnp.stack([machine.arm.ring_joint_arc_length, s_link]),
                         damping_ratio=machine.damping_ratio, basis=basis)
    y_bottom = heald_frame_height_from_arm(chain, theta_bottom)
    y_top = heald_frame_height_from_arm(chain, theta_top)
    return dict(chain=chain, body=body, ring_direction_ref=n_ref,
                link_joint=chain.arm.point(s_link), stroke=y_top - y_bottom,
                mid_level=0.5 * (y_top + y_bottom), crank_start=phi_bottom)


# -- the rigid mechanism at time t -------------------------------------------------------------
class RigidState(eqx.Module):
    """Quantities of the rigid mechanism at one instant (they depend on time only).

    Attributes:
        time: t [s].
        frame: the arm frame's angle θ, rates ω, α (pivot fixed).
        ring_direction: ring-link direction in the arm's body frame [-], (2,).
        link_force: force of link 11 on the arm by rigid inverse dynamics, body frame [N], (2,).
    """

    time: Array
    frame: FrameState
    ring_direction: Array
    link_force: Array


def arm_angle(model: DobbyModel, t) -> Array:
    """Rigid arm angle θ(t) [rad]."""
    phi = crank_angle(model.chain, model.crank_start, t, model.operating.speed, model.lift_plan)
    return arm_angle_from_crank(model.chain, phi)


def rigid_joint_position(model: DobbyModel, t) -> Array:
    """Inertial position [m] of the link-11 joint on the rigid arm."""
    return rotation_matrix(arm_angle(model, t)) @ model.link_joint


def rigid_state(model: DobbyModel, t) -> RigidState:
    """The rigid mechanism at time t [s]: arm motion, ring-link direction, link-11 force.

    Rates by forward-mode autodiff in time. The link-11 force comes from the chain's d'Alembert
    balance for a virtual move of the joint: −f·δP = (D c̈ − Q)·δc, so f = −(∂c/∂P)ᵀ(D c̈ − Q),
    with c̈ the rigid chain's accelerations.
    """
    t = jnp.asarray(t, dtype=float)
    theta, omega, alpha = time_derivatives(lambda tt: arm_angle(model, tt), t)
    frame = FrameState(theta, omega, alpha, jnp.zeros(2))
    phi = crank_angle(model.chain, model.crank_start, t, model.operating.speed, model.lift_plan)
    a_t = rotation_matrix(theta).T
    p0 = rotation_matrix(theta) @ model.link_joint
    c, _, c_tt = time_derivatives(lambda tt: chain_from_joint(model, rigid_joint_position(model, tt)), t)
    dc_dp = jax.jacfwd(lambda p: chain_from_joint(model, p))(p0)
    force = -dc_dp.T @ (chain_inertia(model) * c_tt - generalised_chain_forces(model, t, c[1]))
    return RigidState(time=t, frame=frame,
                      ring_direction=a_t @ ring_link_direction_from_crank(model.chain, phi),
                      link_force=a_t @ force)


# -- the downstream chain ------------------------------------------------------------------------
def chain_from_joint(model: DobbyModel, joint) -> Array:
    """Downstream coordinates c = (β [rad], y_H [m]) for an inertial link-11 joint position."""
    beta = blade_angle(model.chain, joint)
    return jnp.stack([beta, heald_frame_height_from_blade(model.chain, beta)])


def joint_position(model: DobbyModel, t, q) -> Array:
    """Inertial position [m] of the link-11 joint on the deformed arm, A(θ)(p + Φ_P q)."""
    return rotation_matrix(arm_angle(model, t)) @ (model.link_joint + model.body.points[LINK] @ q)


def chain_coordinates(model: DobbyModel, t, q) -> Array:
    """c = G(t, q) = (β, y_H): the downstream chain driven by the deformed arm."""
    return chain_from_joint(model, joint_position(model, t, q))


def warp_force(model: DobbyModel, t, height) -> Array:
    """Warp-yarn force on the heald frame [N, positive up] (law: ``machine.warp_law``)."""
    peak = model.operating.warp_force
    offset = (height - model.mid_level) / (0.5 * model.stroke)
    if model.machine.warp_law == "restoring":
        return -peak * offset
    # "opposing": magnitude of the restoring law, sign against the current pick's lift
    # direction: up during the first pick of the cycle (from the bottom dwell), down after.
    lifting = jnp.mod(t, model.period) < 0.5 * model.period
    return -peak * jnp.abs(offset) * jnp.where(lifting, 1.0, -1.0)


def generalised_chain_forces(model: DobbyModel, t, height) -> Array:
    """Q = (blade torque, frame force) of gravity and the warp force on the chain [N·m, N]."""
    m = model.machine
    return jnp.stack([0.0 * height, -m.heald_frame_mass * m.gravity + warp_force(model, t, height)])


def chain_inertia(model: DobbyModel) -> Array:
    """D = diag(J_b, m_H) [kg·m², kg], as a vector."""
    return jnp.stack([model.machine.blade_inertia, model.machine.heald_frame_mass])


def chain_kinematics(model: DobbyModel, rigid: RigidState, q, qdot):
    """c, G_q (2, k), ċ, h = c̈ − G_q q̈ and C'(P) (2, 2) of the chain driven by the deformed arm.

    With r = p + Φ_P q in the body frame and A = A(θ): P = A r, Ṗ = A(ωSr + Φ_P q̇) and
    P̈ = A(Φ_P q̈ + 2ωSΦ_P q̇ + αSr − ω²r). With C the chain's closure map, c = C(P),
    ċ = C'Ṗ and c̈ = C'P̈ + C''[Ṗ, Ṗ]; C' and C''[Ṗ, Ṗ] by forward-mode autodiff.
    """
    f = rigid.frame
    omega, alpha = f.angular_velocity, f.angular_acceleration
    a = rotation_matrix(f.angle)
    rows = model.body.points[LINK]
    r = model.link_joint + rows @ q
    sr = jnp.stack([-r[1], r[0]])
    v_el = rows @ qdot
    p, p_dot = a @ r, a @ (omega * sr + v_el)
    closure = lambda x: chain_from_joint(model, x)  # noqa: E731
    jac = lambda x: jax.jacfwd(closure)(x)  # noqa: E731
    c_prime, c_second = jax.jvp(jac, (p,), (p_dot,))  # C'(P), C''(P)[Ṗ]
    c = closure(p)
    p_acc_rest = a @ (2.0 * omega * jnp.stack([-v_el[1], v_el[0]]) + alpha * sr - omega**2 * r)
    return (c, c_prime @ a @ rows, c_prime @ p_dot, c_prime @ p_acc_rest + c_second @ p_dot,
            c_prime)


# -- equations of motion ------------------------------------------------------------------------
def _ring_correction(model: DobbyModel, rigid: RigidState, q) -> Array:
    """Generalised force of the ring link's change of direction from the reference one."""
    rows = model.body.points[RING]
    n, n0 = rigid.ring_direction, model.ring_direction_ref
    u = rows @ q
    return -model.machine.ring_link_stiffness * rows.T @ (n * (n @ u) - n0 * (n0 @ u))


def equations_at(model: DobbyModel, rigid: RigidState, q, qdot):
    """Generalised mass matrix (k, k) and force (k,) of the coupled system at a state."""
    m = model.machine
    gravity = jnp.stack([0.0 * m.gravity, -m.gravity])
    a = rotation_matrix(rigid.frame.angle)
    forces = jnp.zeros((2, 2)).at[LINK].set(a @ rigid.link_force)
    if m.coupling == "one-way":
        mass, force = kane_terms(model.body, rigid.frame, q, qdot, point_forces=forces,
                                 gravity=gravity)
    else:
        mass, force = kane_terms(model.body, rigid.frame, q, qdot, preload_forces=forces,
                                 gravity=gravity)
        c, g_q, _, h, _ = chain_kinematics(model, rigid, q, qdot)
        d = chain_inertia(model)
        mass = mass + g_q.T @ (d[:, None] * g_q)
        force = force + g_q.T @ (generalised_chain_forces(model, rigid.time, c[1]) - d * h)
    return mass, force + _ring_correction(model, rigid, q)


def vector_field(t, y, model: DobbyModel):
    """diffrax vector field of the state y = (q, q̇), rigid quantities computed at t."""
    q, qdot = y
    mass, force = equations_at(model, rigid_state(model, t), q, qdot)
    return qdot, jnp.linalg.solve(mass, force)
