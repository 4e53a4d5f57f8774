"""Planar curved beams: mesh, section, material, and the assembled finite-element matrices.

A :class:`Beam` is a centre line (:mod:`jaxdobby.centreline`) meshed at given arc lengths into
straight two-node Euler–Bernoulli frame elements (:mod:`jaxdobby.elements`), with a rectangular
section of plate thickness t (out of the plane of motion) × in-plane depth d(s) (piecewise linear
between control points, evaluated at each element's mid arc length): A = t·d, I = t·d³/12.
Point masses and rotary inertias sit at nodes. Curved segments are represented by chords, which
converges as O(h²) in the element size h.

Global DOFs are ordered ``(u_x, u_y, r)`` per node in the *body frame*. Everything is a pure,
jittable, differentiable function of the float fields; the number of nodes and the element
connectivity are static.

Example::

    import jax; jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    from jaxdobby.centreline import CentreLine
    from jaxdobby.beam import Beam
    line = CentreLine.from_segments([("line", 1.0)])
    beam = Beam.uniform_mesh(line, n_elements=10, thickness=0.01, depth=0.02,
                             youngs_modulus=2.1e11, density=7800.0)
    M, K = beam.mass_matrix(), beam.stiffness_matrix()   # (33, 33) each
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from . import elements
from .centreline import CentreLine

DOFS_PER_NODE = 3


def _chain(n_nodes: int) -> tuple[tuple[int, int], ...]:
    return tuple((i, i + 1) for i in range(n_nodes - 1))


class Beam(eqx.Module):
    """A planar beam of straight Euler–Bernoulli frame elements along a centre line.

    Attributes:
        centreline: the centre line in the body frame.
        node_arc_lengths: arc length of each node along the centre line [m], shape (n_nodes,).
        thickness: plate thickness t, out of the plane of motion [m] (scalar).
        depth_arc_lengths: arc lengths of the depth control points [m], shape (n_ctrl,).
        depth: in-plane depth d at the control points [m], shape (n_ctrl,); linear in between,
            constant beyond the ends (one control point = uniform depth).
        youngs_modulus: E [Pa].
        density: ρ [kg/m³].
        point_masses: point mass at each node [kg], shape (n_nodes,).
        point_inertias: rotary inertia about the out-of-plane axis at each node [kg·m²],
            shape (n_nodes,).
        elements: static node pairs (i, j) of each element; default a chain 0-1-2-…
        node_positions: body-frame positions of the nodes [m], shape (n_nodes, 2): the points
            of ``centreline`` at ``node_arc_lengths``.
        element_lengths, element_angles, element_mid_arc_lengths: each element's length [m],
            axis angle from the body x axis [rad] and arc length of its middle [m], shape
            (n_elements,).

    The last four are found once, when the beam is made, from ``centreline``,
    ``node_arc_lengths`` and ``elements``: every matrix needs them, and computed in each they
    made up half of the traced model (:func:`jaxdobby.dobby.build_model`: 10,100 equations,
    5,000 without), hence of what XLA compiles. A new centre line or mesh is a new ``Beam``.
    """

    centreline: CentreLine
    node_arc_lengths: Array
    thickness: Array
    depth_arc_lengths: Array
    depth: Array
    youngs_modulus: Array
    density: Array
    point_masses: Array
    point_inertias: Array
    elements: tuple[tuple[int, int], ...] = eqx.field(static=True)
    node_positions: Array
    element_lengths: Array
    element_angles: Array
    element_mid_arc_lengths: Array

    def __init__(self, centreline, node_arc_lengths, thickness, depth, youngs_modulus, density,
                 *, depth_arc_lengths=None, point_masses=None, point_inertias=None, elements=None):
        self.centreline = centreline
        self.node_arc_lengths = jnp.asarray(node_arc_lengths, dtype=float)
        n = self.node_arc_lengths.shape[0]
        self.thickness = jnp.asarray(thickness, dtype=float)
        self.depth = jnp.atleast_1d(jnp.asarray(depth, dtype=float))
        self.depth_arc_lengths = (jnp.zeros(self.depth.shape) if depth_arc_lengths is None
                                  else jnp.atleast_1d(jnp.asarray(depth_arc_lengths, dtype=float)))
        self.youngs_modulus = jnp.asarray(youngs_modulus, dtype=float)
        self.density = jnp.asarray(density, dtype=float)
        self.point_masses = jnp.zeros(n) if point_masses is None else jnp.asarray(point_masses,
                                                                                   dtype=float)
        self.point_inertias = (jnp.zeros(n) if point_inertias is None
                               else jnp.asarray(point_inertias, dtype=float))
        self.elements = _chain(n) if elements is None else tuple(tuple(e) for e in elements)
        self.node_positions = centreline.point(self.node_arc_lengths)
        nodes = self._element_nodes()
        d = self.node_positions[nodes[:, 1]] - self.node_positions[nodes[:, 0]]
        self.element_lengths = jnp.linalg.norm(d, axis=1)
        self.element_angles = jnp.arctan2(d[:, 1], d[:, 0])
        s = self.node_arc_lengths
        self.element_mid_arc_lengths = 0.5 * (s[nodes[:, 0]] + s[nodes[:, 1]])

    @classmethod
    def uniform_mesh(cls, centreline: CentreLine, n_elements: int, **kwargs) -> "Beam":
        """Mesh the whole centre line into ``n_elements`` elements of equal arc length."""
        s = jnp.linspace(0.0, 1.0, n_elements + 1) * centreline.total_length
        return cls(centreline, s, **kwargs)

    # -- geometry -------------------------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return self.node_arc_lengths.shape[0]

    @property
    def n_dofs(self) -> int:
        return DOFS_PER_NODE * self.n_nodes

    def _element_nodes(self) -> np.ndarray:
        return np.asarray(self.elements, dtype=np.int32).reshape(-1, 2)

    def element_dofs(self) -> np.ndarray:
        """Global DOF indices of each element, static, shape (n_elements, 6)."""
        nodes = self._element_nodes()
        base = DOFS_PER_NODE * nodes
        return np.concatenate([base[:, :1] + np.arange(3), base[:, 1:] + np.arange(3)], axis=1)

    def element_geometry(self):
        """Lengths [m], axis angles [rad] and mid arc lengths [m] of the elements."""
        return self.element_lengths, self.element_angles, self.element_mid_arc_lengths

    def element_sections(self):
        """Area A [m²] and second moment I [m⁴] of each element's rectangular section."""
        _, _, s_mid = self.element_geometry()
        d = jnp.interp(s_mid, self.depth_arc_lengths, self.depth)
        return self.thickness * d, self.thickness * d**3 / 12.0

    # -- assembly ------------------------------------------------------------------------------
    def _assemble(self, element_matrices: Array) -> Array:
        """Scatter-add element matrices (n_el, 6, 6) in the body frame into a global matrix."""
        dofs = self.element_dofs()
        out = jnp.zeros((self.n_dofs, self.n_dofs), dtype=element_matrices.dtype)
        return out.at[dofs[:, :, None], dofs[:, None, :]].add(element_matrices)

    def _rotated(self, local: Array) -> Array:
        """Rotate element-frame matrices (n_el, 6, 6) to the body frame: Tᵀ X T."""
        _, angle, _ = self.element_geometry()
        t = jax.vmap(elements.rotation)(angle)
        return jnp.einsum("eji,ejk,ekl->eil", t, local, t)

    @eqx.filter_jit
    def stiffness_matrix(self) -> Array:
        """Global elastic stiffness matrix K [N/m, N, N·m], shape (n_dofs, n_dofs)."""
        length, _, _ = self.element_geometry()
        area, inertia = self.element_sections()
        e = self.youngs_modulus
        local = jax.vmap(elements.stiffness)(length, e * area, e * inertia)
        return self._assemble(self._rotated(local))

    def _distributed_mass(self, fn) -> Array:
        length, _, _ = self.element_geometry()
        area, _ = self.element_sections()
        return self._assemble(self._rotated(jax.vmap(fn)(length, self.density * area)))

    @eqx.filter_jit
    def translational_mass_matrix(self) -> Array:
        """Mass matrix of the translational inertia alone (distributed + point masses) [kg]."""
        point = jnp.stack([self.point_masses, self.point_masses, jnp.zeros(self.n_nodes)], axis=1)
        return self._distributed_mass(elements.mass) + jnp.diag(point.reshape(-1))

    @eqx.filter_jit
    def mass_matrix(self) -> Array:
        """Global consistent mass matrix M [kg, kg·m, kg·m²], shape (n_dofs, n_dofs)."""
        rotary = jnp.zeros((self.n_nodes, 3)).at[:, 2].set(self.point_inertias)
        return self.translational_mass_matrix() + jnp.diag(rotary.reshape(-1))

    @eqx.filter_jit
    def gyroscopic_matrix(self) -> Array:
        """Skew-symmetric matrix ∫ Nᵀ S N dm of the rotating-frame terms [kg]."""
        s = elements.S
        point = jnp.kron(jnp.diag(self.point_masses), jnp.zeros((3, 3)).at[:2, :2].set(s))
        return self._distributed_mass(elements.gyroscopic) + point

    @eqx.filter_jit
    def element_axial_forces(self, displacements: Array) -> Array:
        """Axial force of each element [N, tension positive] for global displacements (n_dofs,)."""
        length, angle, _ = self.element_geometry()
        area, _ = self.element_sections()
        d = displacements[self.element_dofs()]
        return jax.vmap(elements.axial_force)(length, self.youngs_modulus * area, angle, d)

    @eqx.filter_jit
    def geometric_stiffness_matrix(self, axial_forces: Array) -> Array:
        """Geometric stiffness Σₑ Pₑ Kσₑ for element axial forces ``axial_forces`` [N]."""
        length, _, _ = self.element_geometry()
        local = jax.vmap(elements.geometric_stiffness)(length) * axial_forces[:, None, None]
        return self._assemble(self._rotated(local))

    # -- rigid-motion fields -----------------------------------------------------------------
    @eqx.filter_jit
    def rigid_fields(self) -> dict[str, Array]:
        """Nodal vectors (n_dofs,) that interpolate rigid-body fields exactly on every element.

        ``position``: the position field x (translations = node positions, rotations 0);
        ``rotation``: S·x, the velocity field of a unit rotation about the body origin
        (translations S xᵢ, rotations 1); ``x``/``y``: unit translations. Since the element shape
        functions reproduce these fields exactly, ``M @ field`` is the exact consistent load of
        the corresponding distributed inertia (e.g. ∫ Nᵀ x dm).
        """
        x = self.node_positions
        n = self.n_nodes
        zeros, ones = jnp.zeros(n), jnp.ones(n)
        as_dofs = lambda a, b, c: jnp.stack([a, b, c], axis=1).reshape(-1)  # noqa: E731
        return {
            "position": as_dofs(x[:, 0], x[:, 1], zeros),
            "rotation": as_dofs(-x[:, 1], x[:, 0], ones),
            "x": as_dofs(ones, zeros, zeros),
            "y": as_dofs(zeros, ones, zeros),
        }

    # -- points on the centre line -----------------------------------------------------------
    def _locate(self, arc_length):
        """Element index and ξ of the point at arc length ``arc_length`` (chain meshes)."""
        s = self.node_arc_lengths  # a dozen nodes: compared with each, no search loop
        e = jnp.clip(jnp.searchsorted(s, arc_length, side="right", method="compare_all") - 1,
                     0, self.n_nodes - 2)
        xi = (arc_length - s[e]) / (s[e + 1] - s[e])
        return e, xi

    @eqx.filter_jit
    def point_rows(self, arc_length) -> Array:
        """Rows mapping global DOFs to the body-frame translation of the point at ``arc_length``.

        Uses the interpolation of the element that contains the point, so a point between nodes
        moves consistently with the finite-element field. Returns shape (2, n_dofs).
        """
        e, xi = self._locate(arc_length)
        length, angle, _ = self.element_geometry()
        c, s = jnp.cos(angle[e]), jnp.sin(angle[e])
        to_body = jnp.array([[c, -s], [s, c]])
        local = to_body @ elements.translation_shape(xi, length[e]) @ elements.rotation(angle[e])
        dofs = jnp.asarray(self.element_dofs())[e]
        return jnp.zeros((2, self.n_dofs)).at[:, dofs].add(local)

    @eqx.filter_jit
    def rotation_row(self, arc_length) -> Array:
        """Row mapping global DOFs to the section rotation at ``arc_length`` [rad], (n_dofs,)."""
        e, xi = self._locate(arc_length)
        length, angle, _ = self.element_geometry()
        local = elements.rotation_shape(xi, length[e]) @ elements.rotation(angle[e])
        dofs = jnp.asarray(self.element_dofs())[e]
        return jnp.zeros(self.n_dofs).at[dofs].add(local)

    def nearest_node(self, arc_length) -> int:
        """Index of the node closest to ``arc_length`` [m] (for concrete values only)."""
        return int(np.argmin(np.abs(np.asarray(self.node_arc_lengths) - float(arc_length))))
