"""Modal reduction of a supported beam.

The free vibration of the supported beam, K φ = ω² M φ on the unconstrained DOFs, is solved as
a standard symmetric eigenproblem through the Cholesky factor M = L Lᵀ:
(L⁻¹ K L⁻ᵀ) v = ω² v, φ = L⁻ᵀ v (Bathe, *Finite Element Procedures*, §10.2.5). The modes are
mass-normalised (Φᵀ M Φ = I), sorted by frequency, and expanded back to all DOFs with zeros at
the constrained ones; the first ``n_modes`` are kept.

Gradients of the frequencies and modes with respect to every float parameter of the beam flow
through ``eigh``; they are exact for distinct frequencies and undefined (1/(ωᵢ² − ωⱼ²)) for
repeated ones (e.g. the pairs of a free ring). The design-optimisation path keeps the
eigen-decomposition out of the differentiated path for that reason (see
:mod:`jaxdobby.flexible_body`).

Example::

    from jaxdobby.modal import modal_basis
    basis = modal_basis(beam, Supports(clamped=(0,)), n_modes=4)
    basis.frequencies / (2 * jnp.pi)   # [Hz]
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jax import Array

from .beam import Beam
from .supports import Supports, supported_stiffness


class ModalBasis(eqx.Module):
    """Mass-normalised modes of a supported beam.

    Attributes:
        frequencies: natural circular frequencies ω [rad/s], ascending, shape (n_modes,).
        shapes: mode shapes Φ on all DOFs, shape (n_dofs, n_modes), with Φᵀ M Φ = I
            (units: m/√kg on translations, rad/√kg on rotations).
    """

    frequencies: Array
    shapes: Array

    @property
    def frequencies_hz(self) -> Array:
        """Natural frequencies [Hz]."""
        return self.frequencies / (2.0 * jnp.pi)


def _solve_eigen(mass: Array, stiffness: Array):
    """Eigenvalues (ascending) and M-orthonormal eigenvectors of K φ = λ M φ."""
    chol = jnp.linalg.cholesky(mass)
    a = jsl.solve_triangular(chol, jsl.solve_triangular(chol, stiffness, lower=True).T, lower=True)
    lam, v = jnp.linalg.eigh(0.5 * (a + a.T))
    return lam, jsl.solve_triangular(chol.T, v, lower=False)


@functools.partial(jax.custom_jvp, nondiff_argnums=(2,))
def mode_subspace(mass: Array, stiffness: Array, n_modes: int) -> Array:
    """The first ``n_modes`` M-orthonormal modes of K φ = λ M φ, shape (n, n_modes), with the
    derivative of the *subspace* they span.

    A model reduced onto the first k modes depends only on their span (any M-orthonormal basis
    of it gives the same physics), so its derivative needs only the span's. Perturbing
    K φᵢ = λᵢ M φᵢ gives the components of dφᵢ along the discarded modes φⱼ (j > k),

        cⱼᵢ = φⱼᵀ (dK − λᵢ dM) φᵢ / (λᵢ − λⱼ),

    and within the span any dφ with Φₖᵀ M dΦₖ + dΦₖᵀ M Φₖ = −Φₖᵀ dM Φₖ keeps the basis
    M-orthonormal; the symmetric choice dΦₖ = −½ Φₖ (Φₖᵀ dM Φₖ) is taken (Nelson, AIAA J. 14,
    1976, for the eigenvector derivative; here without its kept–kept terms). So
    dΦₖ = −½ Φₖ (Φₖᵀ dM Φₖ) + Φᵣ C: the only divisors are the gaps λᵢ − λⱼ between a kept and
    a discarded mode. Two kept modes (or two discarded ones) may coincide without harm, where
    the eigenvector derivatives of ``eigh`` (1/(λᵢ − λⱼ) over every pair) are NaN; only a
    closing gap at the truncation itself — where the reduced model is not smooth — is
    ill-conditioned. Forward and reverse mode (the tangent is linear in dM, dK).
    """
    _, phi = _solve_eigen(mass, stiffness)
    return phi[:, :n_modes]


@mode_subspace.defjvp
def _mode_subspace_jvp(n_modes, primals, tangents):
    mass, stiffness = primals
    d_mass, d_stiffness = tangents
    lam, phi = _solve_eigen(mass, stiffness)
    kept, rest = phi[:, :n_modes], phi[:, n_modes:]
    lam_kept, lam_rest = lam[:n_modes], lam[n_modes:]
    within = -0.5 * kept.T @ d_mass @ kept
    coupling = rest.T @ (d_stiffness @ kept - (d_mass @ kept) * lam_kept[None, :])
    across = coupling / (lam_kept[None, :] - lam_rest[:, None])
    return kept, kept @ within + rest @ across


@eqx.filter_jit
def modal_basis(beam: Beam, supports: Supports, n_modes: int, *,
                mass: Array | None = None, stiffness: Array | None = None) -> ModalBasis:
    """The first ``n_modes`` mass-normalised modes of the supported beam.

    Args:
        beam: the beam.
        supports: its supports (clamps, pins, springs).
        n_modes: number of modes kept, 1 … number of free DOFs (static).
        mass, stiffness: optional pre-assembled global matrices (defaults: the beam's consistent
            mass, and its stiffness plus the supports' springs).

    Rigid-body modes of an unsupported beam come out with ω = 0 (negative round-off clipped).
    """
    free = supports.free_dofs(beam.n_nodes)
    if not 1 <= n_modes <= free.size:
        raise ValueError(f"n_modes = {n_modes} is outside the valid range 1…{free.size} "
                         f"(the number of free DOFs)")
    m = beam.mass_matrix() if mass is None else mass
    k = supported_stiffness(beam, supports) if stiffness is None else stiffness
    lam, phi = _solve_eigen(m[np.ix_(free, free)], k[np.ix_(free, free)])
    lam, phi = lam[:n_modes], phi[:, :n_modes]
    shapes = jnp.zeros((beam.n_dofs, n_modes), dtype=phi.dtype).at[free].set(phi)
    positive = lam > 0.0  # sqrt with a finite gradient at the rigid-body modes (ω = 0)
    omega = jnp.where(positive, jnp.sqrt(jnp.where(positive, lam, 1.0)), 0.0)
    return ModalBasis(frequencies=omega, shapes=shapes)
