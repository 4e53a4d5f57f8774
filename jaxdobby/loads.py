"""Consistent nodal loads on a beam: point forces, distributed loads, gravity, rigid-motion inertia.

Every function returns a vector of nodal loads (n_dofs,) in the body frame — forces [N] on the
translation DOFs and moments [N·m] on the rotation DOFs — that does the same virtual work as the
load it represents on the element interpolation (consistent loads; Przemieniecki 1968, §11).
For Euler–Bernoulli elements these give nodally exact static deflections.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from . import elements
from .beam import Beam


@eqx.filter_jit
def distributed_load(beam: Beam, intensity) -> Array:
    """Consistent nodal loads of a distributed force ``intensity(s)`` [N/m] along the centre line.

    ``intensity`` maps arc length s [m] to a body-frame force per unit length, shape (2,). It is
    integrated exactly for loads up to cubic in s (4-point Gauss–Legendre on each element).
    """
    length, angle, _ = beam.element_geometry()
    nodes = jnp.asarray(beam.elements)
    s = beam.node_arc_lengths

    def element_load(l, a, s0, s1):
        c, sn = jnp.cos(a), jnp.sin(a)
        to_local = jnp.array([[c, sn], [-sn, c]])

        def at(xi):
            n = elements.translation_shape(xi, l)
            return n.T @ to_local @ intensity(s0 + xi * (s1 - s0))

        local = l * sum(w * at(xi) for xi, w in zip(elements.GAUSS_POINTS, elements.GAUSS_WEIGHTS))
        return elements.rotation(a).T @ local

    per_element = jax.vmap(element_load)(length, angle, s[nodes[:, 0]], s[nodes[:, 1]])
    return jnp.zeros(beam.n_dofs).at[jnp.asarray(beam.element_dofs())].add(per_element)


@eqx.filter_jit
def point_load(beam: Beam, arc_length, force=(0.0, 0.0), moment=0.0) -> Array:
    """Consistent nodal loads (n_dofs,) of a body-frame force [N] and moment [N·m] at a point.

    The point sits at ``arc_length`` [m] along the centre line, on a node or inside an element.
    """
    return (beam.point_rows(arc_length).T @ jnp.asarray(force, dtype=float)
            + beam.rotation_row(arc_length) * moment)


@eqx.filter_jit
def gravity_load(beam: Beam, gravity) -> Array:
    """Nodal loads (n_dofs,) of a uniform body-frame acceleration field ``gravity`` [m/s²]."""
    f = beam.rigid_fields()
    g = jnp.asarray(gravity, dtype=float)
    return beam.translational_mass_matrix() @ (g[0] * f["x"] + g[1] * f["y"])


@eqx.filter_jit
def rigid_motion_load(beam: Beam, angular_velocity, angular_acceleration) -> Array:
    """Nodal inertia loads (n_dofs,) of a rigid rotation about the body origin.

    The d'Alembert load of the acceleration field α S x − ω² x of a body turning at ω [rad/s]
    with angular acceleration α [rad/s²]: ω² ∫ Nᵀ x dm − α ∫ Nᵀ S x dm (including the
    rotary inertia of point inertias under α).
    """
    f = beam.rigid_fields()
    return (angular_velocity**2 * beam.translational_mass_matrix() @ f["position"]
            - angular_acceleration * beam.mass_matrix() @ f["rotation"])
