"""Independent references for the dobby tests: the quasi-static response from the full FE
statics (no modal reduction, no time integration)."""

import jax
import jax.numpy as jnp

from jaxdobby.arm import arm_beam, arm_supports
from jaxdobby.dobby import chain_from_joint, rigid_joint_position, rigid_state
from jaxdobby.floating_frame import rotation_matrix
from jaxdobby.loads import gravity_load, point_load, rigid_motion_load
from jaxdobby.supports import static_deflection, supported_stiffness


def quasi_static_deviation(model, ts):
    """Heald-frame deviation [m] if the arm deflected statically under the loads of the rigid
    mechanism at each time: its weight and the d'Alembert loads of its rigid rotation
    (ω², α), and the link-11 force of rigid inverse dynamics (chain inertia, frame weight and
    warp force), the arm pinned at the pivot and held by the ring link along its actual
    direction; full finite-element statics (all 31 DOFs) with the geometric stiffness of the same
    loads, mapped to the heald frame through the exact linkage closure."""
    beam = arm_beam(model.machine.arm)
    s_link = model.chain.link11_arc_length

    def at(t):
        r = rigid_state(model, t)
        f = r.frame
        supports = arm_supports(r.ring_direction, model.machine.ring_link_stiffness)
        g_body = rotation_matrix(f.angle).T @ jnp.array([0.0, -model.machine.gravity])
        load = (gravity_load(beam, g_body)
                + rigid_motion_load(beam, f.angular_velocity, f.angular_acceleration)
                + point_load(beam, s_link, force=r.link_force))
        k = supported_stiffness(beam, supports)
        u = static_deflection(beam, supports, load, stiffness=k)
        k_geo = beam.geometric_stiffness_matrix(beam.element_axial_forces(u))
        u = static_deflection(beam, supports, load, stiffness=k + k_geo)
        p0 = rigid_joint_position(model, t)
        dp = rotation_matrix(f.angle) @ (beam.point_rows(s_link) @ u)
        return chain_from_joint(model, p0 + dp)[1] - chain_from_joint(model, p0)[1]

    return jax.jit(jax.vmap(at))(ts)
