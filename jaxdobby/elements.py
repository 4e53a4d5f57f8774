"""Planar Euler–Bernoulli frame element: shape functions and element matrices.

One straight two-node element of length L with 3 degrees of freedom per node, ordered
``(u1, v1, r1, u2, v2, r2)`` in the element frame: axial displacement u [m], transverse
displacement v [m], rotation r [rad]. Axial displacement is interpolated linearly, transverse
displacement by cubic Hermite polynomials (the rotation is dv/dx), so the translation of the point
at ξ = x/L ∈ [0, 1] is ``N(ξ) @ d`` with the 2×6 matrix of :func:`translation_shape`.

Every matrix is the exact integral of its shape-function products (4-point Gauss–Legendre
quadrature, exact to polynomial degree 7; the highest degree here is 6), so one set of shape
functions defines them all:

* stiffness ``K = ∫ EA u'ᵀu' + EI v''ᵀv'' dx``                       (Przemieniecki 1968, §5.3)
* consistent mass ``M = ∫ ρA NᵀN dx``                                   (Przemieniecki §11.3;
  no rotary inertia of the section, as in Euler–Bernoulli theory)
* gyroscopic (skew) matrix ``G = ∫ ρA Nᵀ S N dx``, S = [[0, −1], [1, 0]], the matrix of the
  Coriolis and Euler terms of a body frame that rotates in the plane (Shabana, *Dynamics of
  Multibody Systems*, 3rd ed., §5.5)
* geometric (stress) stiffness per unit axial force ``Kσ = ∫ v'ᵀv' dx``  (Cook et al.,
  *Concepts and Applications of FEA*, 4th ed., §18.2), which with the element's axial force P
  [N, tension positive] adds ``P·Kσ`` to the stiffness.

Planar rotations commute with S, so every matrix rotates to the body frame as ``Tᵀ X T`` with
the 6×6 rotation ``T`` of :func:`rotation`.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)
GAUSS_POINTS = 0.5 * (_GAUSS_X + 1.0)
"""Gauss–Legendre points on [0, 1] (4 points)."""
GAUSS_WEIGHTS = 0.5 * _GAUSS_W
"""Gauss–Legendre weights on [0, 1], summing to 1."""

S = np.array([[0.0, -1.0], [1.0, 0.0]])  # numpy: importing must not start a JAX backend
"""Planar cross-product matrix: S @ r is r turned by +90°."""


def translation_shape(xi, length):
    """2×6 matrix mapping element DOFs to the (axial, transverse) translation at ξ = x/L.

    Args:
        xi: position along the element, 0 at node 1 and 1 at node 2 [-].
        length: element length L [m].
    """
    xi = jnp.asarray(xi, dtype=float)
    z = jnp.zeros_like(xi)
    h1 = 1.0 - 3.0 * xi**2 + 2.0 * xi**3
    h2 = length * (xi - 2.0 * xi**2 + xi**3)
    h3 = 3.0 * xi**2 - 2.0 * xi**3
    h4 = length * (-(xi**2) + xi**3)
    axial = jnp.stack([1.0 - xi, z, z, xi, z, z])
    transverse = jnp.stack([z, h1, h2, z, h3, h4])
    return jnp.stack([axial, transverse])


def rotation_shape(xi, length):
    """1×6 row mapping element DOFs to the cross-section rotation dv/dx at ξ = x/L [rad]."""
    xi = jnp.asarray(xi, dtype=float)
    z = jnp.zeros_like(xi)
    d1 = (-6.0 * xi + 6.0 * xi**2) / length
    d2 = 1.0 - 4.0 * xi + 3.0 * xi**2
    d3 = (6.0 * xi - 6.0 * xi**2) / length
    d4 = -2.0 * xi + 3.0 * xi**2
    return jnp.stack([z, d1, d2, z, d3, d4])


def _curvature_shape(xi, length):
    """Row mapping element DOFs to the curvature v'' at ξ [1/m]."""
    z = jnp.zeros_like(xi)
    l2 = length**2
    return jnp.stack(
        [z, (-6.0 + 12.0 * xi) / l2, (-4.0 + 6.0 * xi) / length, z, (6.0 - 12.0 * xi) / l2,
         (-2.0 + 6.0 * xi) / length]
    )


def _strain_shape(length):
    """Row mapping element DOFs to the axial strain u' [-] (constant along the element)."""
    return jnp.array([-1.0, 0.0, 0.0, 1.0, 0.0, 0.0]) / length


def _integrate(fn, length):
    """∫₀ᴸ fn(ξ) dx by 4-point Gauss–Legendre quadrature."""
    values = jnp.stack([fn(xi) for xi in GAUSS_POINTS])
    return length * jnp.tensordot(jnp.asarray(GAUSS_WEIGHTS), values, axes=1)


def stiffness(length, axial_rigidity, bending_rigidity):
    """Element stiffness matrix (6×6, element frame).

    Args:
        length: L [m]; axial_rigidity: EA [N]; bending_rigidity: EI [N·m²].
    """
    b = _strain_shape(length)
    axial = axial_rigidity * length * jnp.outer(b, b)
    def integrand(xi):
        c = _curvature_shape(xi, length)
        return jnp.outer(c, c)

    return axial + bending_rigidity * _integrate(integrand, length)


def mass(length, mass_per_length):
    """Consistent mass matrix (6×6, element frame); ``mass_per_length`` = ρA [kg/m]."""
    def integrand(xi):
        n = translation_shape(xi, length)
        return n.T @ n

    return mass_per_length * _integrate(integrand, length)


def gyroscopic(length, mass_per_length):
    """Skew-symmetric gyroscopic matrix ∫ ρA Nᵀ S N dx (6×6, element frame) [kg]."""
    def integrand(xi):
        n = translation_shape(xi, length)
        return n.T @ S @ n

    return mass_per_length * _integrate(integrand, length)


def geometric_stiffness(length):
    """Geometric stiffness per unit axial force, ∫ v'ᵀ v' dx (6×6, element frame) [1/m]."""
    def integrand(xi):
        r = rotation_shape(xi, length)
        return jnp.outer(r, r)

    return _integrate(integrand, length)


def rotation(angle):
    """6×6 matrix taking body-frame element DOFs to element-frame DOFs.

    ``angle`` [rad] is the direction of the element axis (node 1 → node 2) from the body x axis.
    """
    c, s = jnp.cos(angle), jnp.sin(angle)
    r = jnp.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    z = jnp.zeros((3, 3))
    return jnp.block([[r, z], [z, r]])


def axial_force(length, axial_rigidity, angle, displacements):
    """Axial force [N, tension positive] of an element from its body-frame nodal displacements."""
    local = rotation(angle) @ displacements
    return axial_rigidity * (local[3] - local[0]) / length
