"""Reduction on a fixed basis: reduced frequencies and modal damping with no eigenvector derivatives.

The modes of a beam, from ``eigh``, have derivatives with the factors 1/(λᵢ − λⱼ): they are
NaN or huge when two frequencies come close (Giles, *Extended collection of matrix derivative
results*, 2008, §3.1; jax #669), although the reduced model itself — which depends only on the
*subspace* the kept modes span — is smooth there. A design optimiser therefore reduces on a
fixed basis Ψ (e.g. the modes of a reference design, constant with respect to the design): the
reduced matrices M_r = ΨᵀM(p)Ψ and K_r = ΨᵀK(p)Ψ are smooth in the design p, not diagonal, and
no eigen-decomposition lies on the differentiated path (Rayleigh–Ritz; Craig & Kurdila,
*Fundamentals of Structural Dynamics*, §16.2).

What the floating-frame equations still need from the modes is the modal damping, diag(2ζωᵢ) in
mass-normalised modal coordinates. In any basis the same damping is the congruence-invariant

    C_r = 2ζ M_r (M_r⁻¹K_r)^{1/2} = 2ζ L (L⁻¹ K_r L⁻ᵀ)^{1/2} Lᵀ,      M_r = L Lᵀ,

(for Ψ = mass-normalised modes it *is* diag(2ζωᵢ); for Ψ T it is Tᵀ C_r T), the classical
"stiffness-proportional to the square root" damping of Caughey & O'Kelly (J. Appl. Mech. 32,
1965). The symmetric positive definite square root S = A^{1/2} is computed by scaled
Denman–Beavers iterations (Higham, *Functions of Matrices*, 2008, §6.3, eq. 6.28), and its
derivative by the Sylvester equation S Ṡ + Ṡ S = Ȧ, solved as a k²×k² linear system whose matrix
I⊗S + S⊗I has eigenvalues √λᵢ + √λⱼ > 0: no 1/(λᵢ − λⱼ) anywhere, so it is well defined when
frequencies coincide.

Example::

    from jaxdobby.ritz import modal_damping
    C = modal_damping(M_r, K_r, 0.02)      # (k, k), symmetric
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jax import Array

_DB_ITERATIONS = 24
"""Denman–Beavers iterations: with determinant scaling they converge quadratically after a few
steps for any conditioning met here (λ_max/λ_min of the arm's modes ~1e4); 24 leave the iterate
at round-off (checked against the eigen-decomposition in the tests)."""


def _denman_beavers(a: Array) -> Array:
    n = a.shape[-1]
    eye = jnp.eye(n, dtype=a.dtype)

    def step(_, yz):
        y, z = yz
        # Determinant scaling (Higham eq. 6.29) from the LU factors, in logs (no overflow).
        _, logdet_y = jnp.linalg.slogdet(y)
        _, logdet_z = jnp.linalg.slogdet(z)
        mu = jnp.exp(-(logdet_y + logdet_z) / (2.0 * n))
        y_inv, z_inv = jnp.linalg.inv(y), jnp.linalg.inv(z)
        return 0.5 * (mu * y + z_inv / mu), 0.5 * (mu * z + y_inv / mu)

    y, _ = jax.lax.fori_loop(0, _DB_ITERATIONS, step, (a, eye))
    return 0.5 * (y + y.T)


@jax.custom_jvp
def spd_sqrt(a: Array) -> Array:
    """Symmetric positive definite square root S of a symmetric positive definite matrix A.

    Derivatives from S Ṡ + Ṡ S = Ȧ (see the module docstring): exact, finite for repeated
    eigenvalues, forward and reverse mode.
    """
    return _denman_beavers(a)


@spd_sqrt.defjvp
def _spd_sqrt_jvp(primals, tangents):
    (a,), (a_dot,) = primals, tangents
    s = spd_sqrt(a)
    n = a.shape[-1]
    eye = jnp.eye(n, dtype=a.dtype)
    sylvester = jnp.kron(eye, s) + jnp.kron(s, eye)  # vec(SX + XS) for row-major vec
    s_dot = jnp.linalg.solve(sylvester, a_dot.reshape(-1)).reshape(n, n)
    return s, 0.5 * (s_dot + s_dot.T)


def _whitened(mass: Array, stiffness: Array):
    """Cholesky factor L of M and the symmetric A = L⁻¹ K L⁻ᵀ."""
    chol = jnp.linalg.cholesky(mass)
    a = jsl.solve_triangular(chol, jsl.solve_triangular(chol, stiffness, lower=True).T,
                             lower=True)
    return chol, 0.5 * (a + a.T)


def modal_damping(mass: Array, stiffness: Array, damping_ratio) -> Array:
    """C = 2ζ L (L⁻¹KL⁻ᵀ)^{1/2} Lᵀ: modal damping ratio ζ [-] in every mode of (M, K), shape (k, k).

    Equals diag(2ζωᵢ) when M = I and K = diag(ωᵢ²); ``damping_ratio`` is one number (a per-mode
    ratio has no meaning without the modes).
    """
    chol, a = _whitened(mass, stiffness)
    return 2.0 * damping_ratio * chol @ spd_sqrt(a) @ chol.T


def reduced_frequencies(mass: Array, stiffness: Array) -> Array:
    """Natural circular frequencies ω [rad/s] of the reduced system (ascending), shape (k,).

    Eigenvalues only (``eigvalsh``): their derivatives are vᵢᵀ Ȧ vᵢ, free of 1/(λᵢ − λⱼ) terms.
    """
    _, a = _whitened(mass, stiffness)
    lam = jnp.linalg.eigvalsh(a)
    positive = lam > 0.0  # zero-frequency (rigid-body) modes: finite gradient of sqrt
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, lam, 1.0)), 0.0)
