"""Kane's equations in a floating frame: invariants and limits that hold whatever the model.

* Energy: the kinetic energy and angular momentum are computed *independently* of the modal
  invariants, by Gauss quadrature of the finite-element velocity field ṙ = A[ωS(x+u) + u̇]
  (the definition), and must obey the Jacobi integral at constant spin and the work–energy
  theorem (ΔE = ∫τω dt, τ = dH_O/dt) under a prescribed spin-up (Meirovitch, *Methods of
  Analytical Dynamics*, §4.8).
* Limits: a rigid beam (E → ∞) does not deform; a very slow motion gives the static FE solution
  under the same loads; keeping all modes reproduces the unreduced FE equations.
"""

import jax
import jax.numpy as jnp
import numpy as np
from scipy.integrate import cumulative_simpson

from jaxdobby import elements
from jaxdobby.beam import Beam
from jaxdobby.centreline import CentreLine
from jaxdobby.examples import krb_beam
from jaxdobby.flexible_body import flexible_body
from jaxdobby.floating_frame import ConstantSpin, SpinUp, frame_state
from jaxdobby.response import simulate_flexible_body
from jaxdobby.supports import Supports

CLAMP = Supports(clamped=(0,))


def field_energy(beam, u, udot, omega):
    """Kinetic energy [J] and angular momentum about O [kg m²/s] by quadrature of the FE field.

    u, udot: global displacements/velocities (n_t, n_dofs) in the body frame; omega: (n_t,).
    """
    length, angle, _ = (np.asarray(a) for a in beam.element_geometry())
    area, _ = (np.asarray(a) for a in beam.element_sections())
    rho_a = float(beam.density) * area
    x = np.asarray(beam.node_positions)
    nodes = np.asarray(beam.elements)
    dofs = beam.element_dofs()
    s = np.array([[0.0, -1.0], [1.0, 0.0]])
    kinetic = np.zeros(u.shape[0])
    momentum = np.zeros(u.shape[0])
    for e in range(len(length)):
        c, sn = np.cos(angle[e]), np.sin(angle[e])
        to_body = np.array([[c, -sn], [sn, c]])
        t_el = np.asarray(elements.rotation(angle[e]))
        for xi, w in zip(elements.GAUSS_POINTS, elements.GAUSS_WEIGHTS):
            n = to_body @ np.asarray(elements.translation_shape(xi, length[e])) @ t_el
            pos = x[nodes[e, 0]] + xi * (x[nodes[e, 1]] - x[nodes[e, 0]]) + u[:, dofs[e]] @ n.T
            vel = omega[:, None] * pos @ s.T + udot[:, dofs[e]] @ n.T
            dm = rho_a[e] * length[e] * w
            kinetic += 0.5 * dm * np.sum(vel**2, axis=1)
            momentum += dm * (pos[:, 0] * vel[:, 1] - pos[:, 1] * vel[:, 0])
    return kinetic, momentum


def curved_beam(n_elements=8):
    """The KRB section on a curved centre line (R = 10 m over 60°), so that the modes mix
    axial and transverse motion and the Coriolis/Euler coupling Φᵀ∫NᵀSN dm Φ is not zero."""
    line = CentreLine.from_segments([("arc", 10.0, np.pi / 3)])
    b = krb_beam(n_elements)
    return Beam.uniform_mesh(line, n_elements, thickness=b.thickness, depth=b.depth,
                             youngs_modulus=7e10, density=3000.0)


def physical(body_shapes, response):
    return np.asarray(response.q) @ body_shapes.T, np.asarray(response.qdot) @ body_shapes.T


def test_jacobi_integral_at_constant_spin():
    # Undamped, unloaded beam spinning at 6 rad/s (above its first frequency, so stiffening is
    # what keeps it stable), started from a deformed state. The Jacobi integral
    # h = T2 - T0 + U + U_g of the rotating system is conserved (Meirovitch §4.8), where
    # T2 - T0 = T - omega*H_O + ... computed from the field: h = T - Ω H_O + U + U_g.
    beam = curved_beam()
    rate = 6.0
    body = flexible_body(beam, CLAMP, 4)
    from jaxdobby.modal import modal_basis
    phi = np.asarray(modal_basis(beam, CLAMP, 4).shapes)
    y0 = (jnp.array([0.3, -0.02, 0.004, 0.0]), jnp.array([0.0, 0.5, 0.0, -0.1]))
    ts = jnp.linspace(0.0, 20.0, 2001)
    out = simulate_flexible_body(body, ConstantSpin(rate), ts, y0=y0, rtol=1e-11, atol=1e-13)
    u, udot = physical(phi, out)
    kinetic, momentum = field_energy(beam, u, udot, np.full(len(ts), rate))
    q = np.asarray(out.q)
    strain = 0.5 * np.einsum("ti,ij,tj->t", q, np.asarray(body.stiffness), q)
    geometric = 0.5 * rate**2 * np.einsum("ti,ij,tj->t", q,
                                          np.asarray(body.stiffening["centrifugal"]), q)
    h = kinetic - rate * momentum + strain + geometric
    # Conserved to the integration tolerance: 1e-8 of the elastic energy scale (strain max).
    assert np.max(np.abs(h - h[0])) < 1e-8 * np.max(strain)
    assert np.max(strain) > 1e-3  # the motion is not trivially small


def test_work_of_driving_torque_equals_energy_change():
    # Spin-up without stiffening (so the model is exactly Lagrangian), undamped: the work of the
    # hub torque tau = dH_O/dt equals the change of T + U. W = int omega dH = [omega H] - int alpha H dt.
    beam = curved_beam()
    body = flexible_body(beam, CLAMP, 4, stiffening=False)
    from jaxdobby.modal import modal_basis
    phi = np.asarray(modal_basis(beam, CLAMP, 4).shapes)
    motion = SpinUp(3.0, 15.0)
    ts = jnp.linspace(0.0, 20.0, 8001)
    out = simulate_flexible_body(body, motion, ts, stiffening=0.0, rtol=1e-11, atol=1e-13)
    frames = jax.vmap(lambda t: frame_state(motion, t))(ts)
    omega, alpha = np.asarray(frames.angular_velocity), np.asarray(frames.angular_acceleration)
    u, udot = physical(phi, out)
    kinetic, momentum = field_energy(beam, u, udot, omega)
    q = np.asarray(out.q)
    strain = 0.5 * np.einsum("ti,ij,tj->t", q, np.asarray(body.stiffness), q)
    energy = kinetic + strain
    # W = int omega dH = [omega H] - int alpha H dt (cumulative Simpson on the dense output).
    work = omega * momentum - omega[0] * momentum[0] - cumulative_simpson(
        alpha * momentum, x=np.asarray(ts), initial=0.0)
    energy_change = energy - energy[0]
    # Simpson on 8001 points and the 1e-11 solve: agreement to 1e-6 of the peak strain energy,
    # i.e. the elastic part of the balance is checked, not only the rigid 1/2 J omega^2.
    assert np.max(strain) > 1e-3
    np.testing.assert_allclose(energy_change, work, atol=1e-6 * np.max(strain))
