"""The reduced flexible body: modal invariants for Kane's equations in a floating frame.

For a beam whose elastic displacement in its body frame is u = N Φ q (modal coordinates q), the
generalised inertia forces of Kane's method in a frame that turns at ω, α about its origin O
(which itself accelerates at a_O) need only a few integrals of the mass distribution, computed
once per parameter set (Shabana, *Dynamics of Multibody Systems*, 3rd ed., §5.5–5.6; Kane &
Levinson 1985; Banerjee & Dickens, J. Guid. Control Dyn. 13(2), 1990):

=====================  =====================================  ==================================
field                  definition                             role in the equations
=====================  =====================================  ==================================
``mass``               Φᵀ M Φ  (= I for modes)                 inertia of q̈
``stiffness``          Φᵀ K Φ  (= diag ω²)                     elastic force
``translational_mass`` Φᵀ M_t Φ (M without rotary inertias)    centrifugal softening −ω²
``gyroscopic``         Φᵀ (∫Nᵀ S N dm) Φ, skew                 Coriolis 2ω(·)q̇ and Euler α(·)q
``centrifugal``        Φᵀ ∫Nᵀ x dm                              centrifugal load ω²(·)
``euler``              Φᵀ ∫Nᵀ S x dm (+ rotary inertias)       Euler load −α(·)
``translation``        Φᵀ ∫Nᵀ dm, (n_modes, 2)                 gravity and pivot acceleration
``stiffening``         Φᵀ K_σ(P) Φ per unit load case          geometric stiffness K_g
``points``             Φ rows of attachment/output points      point forces and displacements
=====================  =====================================  ==================================

**Geometric stiffening.** The rigid-motion loads (centrifugal ω², Euler α, uniform accelerations
such as gravity) and the forces at attachment points put the beam in tension or compression; the
axial forces P of each unit load case come from a static solve of the supported beam, and the
modal geometric stiffness of that case is Φᵀ K_σ(P) Φ (Cook et al. §18.2). At run time
K_g = ω² K_ω − α K_α + a_x K_x + a_y K_y + Σ F K_F (linear in the loads). Without it a spinning
beam softens by −ω² and a cantilever spun faster than its first frequency diverges
(Kane, Ryan & Banerjee, J. Guid. Control Dyn. 10(2), 1987).

Example::

    body = flexible_body(beam, Supports(clamped=(0,)), n_modes=4, points=(beam_length,))
    body.frequencies, body.points.shape    # (4,), (1, 2, 4)
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from . import ritz
from .beam import Beam
from .modal import modal_basis, mode_subspace
from .supports import Supports, static_deflection, supported_stiffness

STIFFENING_CASES = ("centrifugal", "euler", "x", "y")
"""Unit load cases of the rigid motion: ω² field, α field, unit body-frame accelerations."""


class FlexibleBody(eqx.Module):
    """Modal invariants of a supported flexible beam (see the module docstring for each).

    Shapes: k = number of modes, p = number of points. ``stiffening`` holds the modal geometric
    stiffness of the rigid-motion cases ``centrifugal`` (per ω² [1/s²]), ``euler`` (per α, load
    −α∫NᵀSx dm counted with a + sign here, so K_g gets −α K_euler), ``x``/``y`` (per unit
    body-frame acceleration field [m/s²], i.e. gravity g gives +g K), each (k, k); and
    ``point_stiffening`` (p, 2, k, k), per unit body-frame force [N] at each point.
    """

    frequencies: Array
    damping_ratio: Array
    mass: Array
    translational_mass: Array
    stiffness: Array
    gyroscopic: Array
    centrifugal: Array
    euler: Array
    translation: Array
    stiffening: dict[str, Array]
    point_stiffening: Array
    points: Array
    point_arc_lengths: Array
    damping_matrix: Array | None = None

    @property
    def n_modes(self) -> int:
        return self.frequencies.shape[0]

    @property
    def frequencies_hz(self) -> Array:
        """Natural frequencies of the supported beam [Hz]."""
        return self.frequencies / (2.0 * jnp.pi)

    @property
    def damping(self) -> Array:
        """Modal damping matrix [kg/s per unit q]: diag(2ζωᵢ) for mass-normalised modes, or the
        stored ``damping_matrix`` of a reduction on a fixed basis (:func:`jaxdobby.ritz.modal_damping`)."""
        if self.damping_matrix is not None:
            return self.damping_matrix
        return jnp.diag(2.0 * self.damping_ratio * self.frequencies)


def _stiffening_matrix(beam, supports, stiffness, shapes, load):
    """Modal geometric stiffness Φᵀ K_σ(P) Φ of the axial forces P caused by ``load``."""
    u = static_deflection(beam, supports, load, stiffness=stiffness)
    kg = beam.geometric_stiffness_matrix(beam.element_axial_forces(u))
    return shapes.T @ kg @ shapes


@eqx.filter_jit
def flexible_body(beam: Beam, supports: Supports, n_modes: int, *,
                  points: Sequence[float] | Array = (), damping_ratio=0.0,
                  stiffening: bool = True, basis: Array | None = None) -> FlexibleBody:
    """Reduce a supported beam to its first ``n_modes`` modes (or a fixed basis) and invariants.

    Args:
        beam: the beam (body frame, origin = the frame's reference point O).
        supports: its supports in the body frame. Stiffening needs a statically determinate or
            indeterminate (not a mechanism) support; leave ``stiffening=False`` for free bodies.
        n_modes: modes kept (static), 1 … number of free DOFs.
        points: arc lengths [m] of points where forces act or displacements are wanted.
        damping_ratio: modal damping ratio ζ [-], scalar or per mode.
        stiffening: whether to compute the unit geometric-stiffness matrices (static).
        basis: optional fixed reduction basis Ψ, shape (n_dofs, n_modes), e.g. the mode shapes
            of a reference design. The beam's matrices are then projected onto Ψ (Ritz
            reduction, :mod:`jaxdobby.ritz`): ``mass`` and ``stiffness`` are full (k, k)
            matrices, ``frequencies`` those of the reduced system, the damping is
            :func:`~jaxdobby.ritz.modal_damping` (``damping_ratio`` must be one number), and Ψ
            is held constant (``stop_gradient``) so that no eigen-decomposition is
            differentiated. Rows of constrained DOFs are set to zero.
            ``"own"``: the beam's own first ``n_modes`` modes used the same way, with the
            derivative of the subspace they span (:func:`jaxdobby.modal.mode_subspace`): the
            modal model's values, and derivatives free of 1/(λᵢ − λⱼ) between kept modes.
    """
    m = beam.mass_matrix()
    k = supported_stiffness(beam, supports)
    damping = None
    if basis is None:
        modes = modal_basis(beam, supports, n_modes)
        phi, frequencies = modes.shapes, modes.frequencies
    elif isinstance(basis, str) and basis == "own":
        if jnp.ndim(damping_ratio) != 0:
            raise ValueError("basis='own' needs one damping ratio for all modes")
        free = supports.free_dofs(beam.n_nodes)
        sub = mode_subspace(m[np.ix_(free, free)], k[np.ix_(free, free)], n_modes)
        phi = jnp.zeros((beam.n_dofs, n_modes), dtype=sub.dtype).at[free].set(sub)
        mass_r, stiffness_r = phi.T @ m @ phi, phi.T @ k @ phi
        frequencies = ritz.reduced_frequencies(mass_r, stiffness_r)
        damping = ritz.modal_damping(mass_r, stiffness_r, jnp.asarray(damping_ratio, float))
    else:
        phi = jax.lax.stop_gradient(jnp.asarray(basis, dtype=float))
        if phi.shape != (beam.n_dofs, n_modes):
            raise ValueError(f"basis has shape {phi.shape}; expected (n_dofs, n_modes) = "
                             f"{(beam.n_dofs, n_modes)}")
        if jnp.ndim(damping_ratio) != 0:
            raise ValueError("a fixed basis needs one damping ratio for all modes")
        mask = np.zeros(beam.n_dofs)
        mask[supports.free_dofs(beam.n_nodes)] = 1.0
        phi = phi * mask[:, None]
        mass_r, stiffness_r = phi.T @ m @ phi, phi.T @ k @ phi
        frequencies = ritz.reduced_frequencies(mass_r, stiffness_r)
        damping = ritz.modal_damping(mass_r, stiffness_r, jnp.asarray(damping_ratio, float))
    m_t = beam.translational_mass_matrix()
    fields = beam.rigid_fields()
    s_points = jnp.asarray(points, dtype=float).reshape(-1)
    rows = jax.vmap(beam.point_rows)(s_points) if s_points.size else jnp.zeros((0, 2, beam.n_dofs))
    zeros = jnp.zeros((n_modes, n_modes))
    if stiffening:
        cases = {"centrifugal": m_t @ fields["position"], "euler": m @ fields["rotation"],
                 "x": m_t @ fields["x"], "y": m_t @ fields["y"]}
        kg = {name: _stiffening_matrix(beam, supports, k, phi, f) for name, f in cases.items()}
        point_kg = jax.vmap(jax.vmap(lambda row: _stiffening_matrix(beam, supports, k, phi, row)))(
            rows) if s_points.size else jnp.zeros((0, 2, n_modes, n_modes))
    else:
        kg = {name: zeros for name in STIFFENING_CASES}
        point_kg = jnp.zeros((s_points.size, 2, n_modes, n_modes))
    return FlexibleBody(
        frequencies=frequencies,
        damping_ratio=jnp.broadcast_to(jnp.asarray(damping_ratio, dtype=float), (n_modes,)),
        mass=phi.T @ m @ phi,
        translational_mass=phi.T @ m_t @ phi,
        stiffness=phi.T @ k @ phi,
        gyroscopic=phi.T @ beam.gyroscopic_matrix() @ phi,
        centrifugal=phi.T @ m_t @ fields["position"],
        euler=phi.T @ m @ fields["rotation"],
        translation=phi.T @ m_t @ jnp.stack([fields["x"], fields["y"]], axis=1),
        stiffening=kg,
        point_stiffening=point_kg,
        points=rows @ phi,
        point_arc_lengths=s_points,
        damping_matrix=damping,
    )
