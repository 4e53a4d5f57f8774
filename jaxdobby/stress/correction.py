"""Stress of the dobby's bending arm over its cycle, with static correction of the truncated modes.

The arm's elastic displacement is reduced onto k modes, u ≈ Φq (*mode displacement*). Stress is
a derivative of u, and the loads that bend the arm most — the link-11 force at its joint, the
ring-link reaction, the inertia of the rigid swing — excite every mode quasi-statically; the k
modes kept miss that part of the response. The *mode-acceleration* (static correction) method
adds it back: with the full equations written K u = g − M ü (g: every load but the elastic
force and the modal inertia, evaluated on the modal solution),

    u = Φq + R (g − MΦq̈),     R = K⁻¹ − Φ (ΦᵀKΦ)⁻¹ Φᵀ

(Craig & Kurdila, *Fundamentals of Structural Dynamics*, 2nd ed., §14.3; Dickens, Nakagawa &
Wittbrodt, Comput. Struct. 62(6), 1997): R is the residual flexibility of the discarded modes;
R M Φ = 0 for the beam's own modes, so the −MΦq̈ term matters only for a fixed (Ritz) basis.
The loads g are those of :func:`jaxdobby.floating_frame.kane_terms` in full DOFs, in the arm's
body frame:

    g = ω² M_t x − α M Sx + M_t (Aᵀg_grav)·(e_x, e_y)                   rigid-motion inertia
        + P_linkᵀ F_link + P_ringᵀ F_ring                             link 11, ring-link correction
        + (ω² M_t − α G − K_g) Φq − 2ω G Φq̇                           rotating-frame terms on Φq

with F_link the force of link 11 on the arm (two-way: the chain's reaction, its inertia included;
one-way: rigid inverse dynamics), F_ring = −k₉(n nᵀ − n₀n₀ᵀ) u_ring the change of the ring link's
direction, and K_g = ω²K_ω − αK_α + Σ_c field_c K_c + F_link,rigid·K_link the full geometric
stiffness (the modal damping, diagonal in the modes, drops out under R). Stress σ = S u with the
recovery matrix S of :mod:`jaxdobby.stress.recovery`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..arm import arm_beam, arm_supports
from ..dobby import DobbyModel
from ..modal import modal_basis, mode_subspace
from ..outputs import ArmMotion, arm_motion
from ..supports import static_deflection, supported_stiffness
from .recovery import StressOperator, stress_operator

POINTS_PER_ELEMENT = 5
"""Recovery points per element (both ends and three between)."""


class ArmStress(eqx.Module):
    """What the stress recovery of one model needs, computed once per parameter set.

    Attributes:
        operator: the recovery S (P = n_elements · n_points · 2 rows).
        shapes: the reduction basis Φ, shape (n_dofs, k).
        modal: S Φ [Pa per unit q], shape (P, k).
        residual: S R [Pa per unit nodal load], shape (P, n_dofs).
        mass, translational_mass, gyroscopic: full M, M_t, G of the arm [kg…], (n_dofs, n_dofs).
        rigid_loads: nodal loads per unit ω², α, field_x, field_y (n_dofs, 4).
        stiffening: full unit geometric stiffness of ω², α (K_α counted with + sign, used as
            −α K_α), field_x, field_y, link force x, y, shape (6, n_dofs, n_dofs).
        link_rows, ring_rows: body-frame translation rows of the link-11 and ring-link joints
            (2, n_dofs).
    """

    operator: StressOperator
    shapes: Array
    modal: Array
    residual: Array
    mass: Array
    translational_mass: Array
    gyroscopic: Array
    rigid_loads: Array
    stiffening: Array
    link_rows: Array
    ring_rows: Array


def reduction_basis(beam, supports, n_modes: int, basis=None) -> Array:
    """Φ as :func:`jaxdobby.flexible_body.flexible_body` builds it (same values, same derivative
    rule): own modes (``None``), own modes with the subspace derivative (``"own"``), or a fixed
    basis with the constrained rows zeroed."""
    free = supports.free_dofs(beam.n_nodes)
    if basis is None:
        return modal_basis(beam, supports, n_modes).shapes
    if isinstance(basis, str):
        m, k = beam.mass_matrix(), supported_stiffness(beam, supports)
        sub = mode_subspace(m[np.ix_(free, free)], k[np.ix_(free, free)], n_modes)
        return jnp.zeros((beam.n_dofs, n_modes), dtype=sub.dtype).at[free].set(sub)
    mask = np.zeros(beam.n_dofs)
    mask[free] = 1.0
    return jax.lax.stop_gradient(jnp.asarray(basis, dtype=float)) * mask[:, None]


def residual_flexibility(stiffness: Array, free: np.ndarray, phi: Array) -> Array:
    """R = K⁻¹ − Φ(ΦᵀKΦ)⁻¹Φᵀ [m/N…], (n_dofs, n_dofs), zero on constrained DOFs: the static
    flexibility of everything the basis Φ (n_dofs, k) leaves out."""
    n = stiffness.shape[0]
    flex = jnp.zeros((n, n)).at[np.ix_(free, free)].set(
        jnp.linalg.inv(stiffness[np.ix_(free, free)]))
    return flex - phi @ jnp.linalg.solve(phi.T @ stiffness @ phi, phi.T)


def arm_stress(model: DobbyModel, basis=None, points_per_element: int = POINTS_PER_ELEMENT,
               n_modes: int | None = None) -> ArmStress:
    """The stress recovery of ``model``'s arm (``basis`` as given to ``build_model``; ``n_modes``
    other than the model's only for truncation studies)."""
    machine = model.machine
    beam = arm_beam(machine.arm)
    supports = arm_supports(model.ring_direction_ref, machine.ring_link_stiffness,
                            machine.arm.ring_joint_node)
    phi = reduction_basis(beam, supports, model.n_modes if n_modes is None else n_modes, basis)
    k = supported_stiffness(beam, supports)
    residual = residual_flexibility(k, supports.free_dofs(beam.n_nodes), phi)
    op = stress_operator(beam, points_per_element)
    m, m_t = beam.mass_matrix(), beam.translational_mass_matrix()
    fields = beam.rigid_fields()
    rigid_loads = jnp.stack([m_t @ fields["position"], m @ fields["rotation"],
                             m_t @ fields["x"], m_t @ fields["y"]], axis=1)
    link_rows = beam.point_rows(model.chain.link11_arc_length)
    ring_rows = beam.point_rows(machine.arm.ring_joint_arc_length)
    cases = jnp.concatenate([rigid_loads.T, link_rows], axis=0)  # (6, n_dofs)

    def unit_stiffening(load):
        u = static_deflection(beam, supports, load, stiffness=k)
        return beam.geometric_stiffness_matrix(beam.element_axial_forces(u))

    return ArmStress(operator=op, shapes=phi, modal=op.matrix @ phi,
                     residual=op.matrix @ residual, mass=m, translational_mass=m_t,
                     gyroscopic=beam.gyroscopic_matrix(), rigid_loads=rigid_loads,
                     stiffening=jax.vmap(unit_stiffening)(cases), link_rows=link_rows,
                     ring_rows=ring_rows)


def arm_loads(model: DobbyModel, stress: ArmStress, motion: ArmMotion, q, qdot,
              link_force) -> Array:
    """The load vector g − MΦq̈ (n_dofs,) of the static correction at one saved time (module
    docstring): pure linear algebra on the run's state and the arm's motion there.

    Args:
        motion: the arm's rigid motion and q̈ at that time (one row of
            :class:`~jaxdobby.outputs.ArmMotion`); q, qdot: modal state (k,); link_force:
            force of link 11 on the arm, inertial components [N] (``Timeseries.link11_force``).
    """
    omega, alpha = motion.rate, motion.acceleration
    c, s = motion.cos, motion.sin
    a_t = jnp.stack([jnp.stack([c, s]), jnp.stack([-s, c])])  # A(θ)ᵀ
    field = a_t @ jnp.stack([0.0 * model.machine.gravity, -model.machine.gravity])
    phi = stress.shapes
    u, v = phi @ q, phi @ qdot
    coeff = jnp.stack([omega**2, -alpha, field[0], field[1]])
    loads = stress.rigid_loads @ coeff
    link_body = a_t @ link_force
    n, n0 = motion.ring_direction, model.ring_direction_ref
    u_ring = stress.ring_rows @ u
    ring = -model.machine.ring_link_stiffness * (n * (n @ u_ring) - n0 * (n0 @ u_ring))
    loads = loads + stress.link_rows.T @ link_body + stress.ring_rows.T @ ring
    k_geo = jnp.einsum("c,cij->ij", jnp.concatenate([coeff, motion.link_force]),
                       stress.stiffening)
    rotating = (omega**2 * stress.translational_mass @ u - alpha * stress.gyroscopic @ u
                - k_geo @ u - 2.0 * omega * stress.gyroscopic @ v)
    return loads + rotating - stress.mass @ (phi @ motion.modal_acceleration)


def cycle_stress(model: DobbyModel, series, stress: ArmStress | None = None, *,
                 correction: bool = True, motion: ArmMotion | None = None) -> Array:
    """Edge stresses [Pa] over the saved cycle, shape (n_t, n_elements, n_points, 2).

    Args:
        model: the run's model; series: its :class:`~jaxdobby.outputs.Timeseries`.
        stress: :func:`arm_stress` of the model (built here when not given).
        correction: mode acceleration (static correction, default) or plain mode displacement.
        motion: the arm's motion at the saved times (:class:`~jaxdobby.outputs.ArmMotion`;
            ``Simulation.arm_motion``); None: computed by the autodiff kinematics
            (:func:`jaxdobby.outputs.arm_motion`).
    """
    stress = arm_stress(model) if stress is None else stress
    sigma = series.modal @ stress.modal.T
    if correction:
        motion = arm_motion(model, series) if motion is None else motion
        loads = jax.vmap(lambda m, q, qd, fl: arm_loads(model, stress, m, q, qd, fl))(
            motion, series.modal, series.modal_rate, series.link11_force)
        sigma = sigma + loads @ stress.residual.T
    return sigma.reshape(sigma.shape[:1] + stress.operator.shape + (2,))
