"""Normal stress at the in-plane edges of a beam from its nodal displacements.

Each straight Euler–Bernoulli element (:mod:`jaxdobby.elements`) has the axial strain u' (constant
along it: linear axial interpolation) and the curvature change v'' (linear: cubic Hermite
deflection) of its own strain–displacement relations. The element's section forces are those of
its finite-element section (depth d_e at its mid arc length, A_e = t·d_e, I_e = t·d_e³/12, the
section the stiffness matrix uses):

    N = E A_e u',     M = E I_e v''     (M > 0 turns the beam towards its left, +y of the element),

and the normal stress at the fibre y across the *actual* section at the recovery point s, of depth
d(s) (piecewise linear between the control points), is Navier's (Timoshenko & Gere, *Mechanics of
Materials*, §5.4 and §11.2 for members of slowly varying depth)

    σ(s, y) = N / A(s) − M y / I(s),      y = ±d(s)/2,

which for a uniform depth is σ = E(u' ∓ (d/2) v'') = E(ε ± (d/2)Δκ) of DESIGN.md §7. Edge 0 is
the *left* edge (y = +d/2, to the left looking towards increasing arc length), edge 1 the *right*
edge (y = −d/2). Taking the section forces from the element and the stress from the section at the
point keeps the recovery exact wherever the element's section forces are (point loads at nodes
of a statically determinate beam), also on a tapered beam.

Stress is linear in the nodal displacements, so the recovery is one matrix: ``σ = S @ u`` with
``S`` of :func:`stress_operator`, shape (n_elements · points_per_element · 2, n_dofs).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .. import elements
from ..beam import Beam

EDGES = ("left", "right")
"""Names of the two in-plane edges: left (y = +d/2) and right (y = −d/2) of the centre line,
looking towards increasing arc length."""


def recovery_xi(points_per_element: int) -> np.ndarray:
    """Positions ξ ∈ [0, 1] of the recovery points in each element: both ends and evenly in
    between (the curvature of an element is linear, so its extremes are at the ends; interior
    points resolve distributed loads in the envelope)."""
    if points_per_element < 2:
        raise ValueError(f"points_per_element = {points_per_element}: use 2 or more")
    return np.linspace(0.0, 1.0, points_per_element)


class StressOperator(eqx.Module):
    """Edge stresses of a beam as a linear map of its nodal displacements.

    Attributes:
        matrix: S, stress per unit nodal displacement [Pa/m, Pa/rad], shape (P, n_dofs) with
            P = n_elements · n_points · 2, ordered (element, point, edge).
        arc_lengths: arc length of each recovery point [m], shape (n_elements, n_points).
        depth: section depth d(s) at each recovery point [m], shape (n_elements, n_points).
    """

    matrix: Array
    arc_lengths: Array
    depth: Array

    @property
    def shape(self) -> tuple[int, int]:
        """(n_elements, n_points) of the recovery grid."""
        return self.arc_lengths.shape

    def stresses(self, displacements: Array) -> Array:
        """Edge stresses [Pa], shape (..., n_elements, n_points, 2), for displacements
        (..., n_dofs) [m, rad]."""
        sigma = displacements @ self.matrix.T
        return sigma.reshape(sigma.shape[:-1] + self.shape + (2,))


def stress_operator(beam: Beam, points_per_element: int = 5) -> StressOperator:
    """The recovery matrix S of ``beam`` with ``points_per_element`` points per element.

    Args:
        beam: the beam (chain mesh, body-frame DOFs (u_x, u_y, r) per node).
        points_per_element: recovery points per element (static, ≥ 2), ends included.
    """
    xi = recovery_xi(points_per_element)
    length, angle, _ = beam.element_geometry()
    area_e, inertia_e = beam.element_sections()
    e_mod = beam.youngs_modulus
    nodes = np.asarray(beam.elements, dtype=np.int32).reshape(-1, 2)
    s = beam.node_arc_lengths
    s_points = s[nodes[:, :1]] + (s[nodes[:, 1:]] - s[nodes[:, :1]]) * jnp.asarray(xi)[None, :]
    depth = jnp.interp(s_points, beam.depth_arc_lengths, beam.depth)
    area_s, inertia_s = beam.thickness * depth, beam.thickness * depth**3 / 12.0
    half = 0.5 * depth

    def element(length_e, angle_e, a_e, i_e, a_pts, i_pts, half_pts):
        t = elements.rotation(angle_e)
        strain = jnp.array([-1.0, 0.0, 0.0, 1.0, 0.0, 0.0]) / length_e
        curvature = jax.vmap(lambda x: elements._curvature_shape(x, length_e))(jnp.asarray(xi))
        normal = (e_mod * a_e * strain)[None, :] / a_pts[:, None]          # N/A(s), (n_pts, 6)
        bending = (e_mod * i_e * curvature) * (half_pts / i_pts)[:, None]  # M c/I(s)
        rows = jnp.stack([normal - bending, normal + bending], axis=1)      # (n_pts, 2, 6)
        return rows @ t

    rows = jax.vmap(element)(length, angle, area_e, inertia_e, area_s, inertia_s, half)
    dofs = beam.element_dofs()  # (n_el, 6)
    n_el, n_pts = rows.shape[:2]
    p = np.arange(n_el * n_pts * 2).reshape(n_el, n_pts, 2)
    matrix = jnp.zeros((n_el * n_pts * 2, beam.n_dofs), dtype=rows.dtype)
    matrix = matrix.at[p[:, :, :, None], dofs[:, None, None, :]].add(rows)
    return StressOperator(matrix=matrix, arc_lengths=s_points, depth=depth)


def edge_points(beam: Beam, operator: StressOperator) -> Array:
    """Body-frame positions [m] of the two edges at each recovery point, shape (n_el, n_pts, 2, 2)
    (last axis x, y): the centre line offset by ±d(s)/2 along its left normal (for figures)."""
    s = operator.arc_lengths
    centre = beam.centreline.point(s)
    heading = beam.centreline.heading(s)
    normal = jnp.stack([-jnp.sin(heading), jnp.cos(heading)], axis=-1)
    half = 0.5 * operator.depth[..., None]
    return jnp.stack([centre + half * normal, centre - half * normal], axis=-2)
