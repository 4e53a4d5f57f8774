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

import equinox as eqx
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
