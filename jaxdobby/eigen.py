"""Eigenvalues of small symmetric-definite problems K v = λ M v in elementwise operations.

A batch of samples (a Sobol chunk) needs the coupled natural frequencies of every sample at
24 phases of the cycle (:func:`jaxdobby.validity.phase_frequencies`): thousands of k × k
problems with k the number of modes (4 by default). LAPACK solves one matrix per call, with
about a microsecond of overhead per call, and must not be handed a batch on a 2-core CPU
(:func:`jaxdobby.periodic.steady.model_terms`). Here the matrices are unrolled into their
k² entries, each an array over the batch, so every operation runs over the whole batch at once:

* Cholesky factorisation M = L Lᵀ and A = L⁻¹ K L⁻ᵀ by forward substitution;
* the eigenvalues of the symmetric A by the cyclic Jacobi method (Golub & Van Loan, *Matrix
  Computations*, 4th ed., §8.5.2–8.5.3: each rotation zeroes one off-diagonal pair, with the
  stable choice of the rotation of Algorithm 8.5.1), a fixed number of sweeps. The
  off-diagonal norm converges quadratically once the sweeps have separated the eigenvalues
  (§8.5.3), and Jacobi's eigenvalues are accurate to round-off relative to the matrix's
  norm (Demmel & Veselić 1992 show better).

One sweep is unrolled (k(k−1)/2 rotations of O(k) operations each: the program grows as k³,
so this is for small k only, :data:`MAX_MODES`); the sweeps are a loop over it. Unrolled
sweeps gave the same numbers bit for bit, but LLVM's time grew much faster than the program:
compiling k = 6 alone took 36 s on 2 cores, against 1.7 s with the loop (k = 4: 2.3 against
0.2 s), and a batch of 3000 ran no slower in the loop (14 against 15 ms).
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
from jax import Array

MAX_MODES = 6
"""Largest k for which :func:`eigvalsh_small` is meant (larger: use LAPACK)."""

SWEEPS = 8
"""Jacobi sweeps (each rotates every off-diagonal pair once). With k ≤ 6 the off-diagonal
entries are at round-off after 5–6 (``tests/test_eigen.py``); 8 leave a margin."""


def generalized_eigvalsh_small(mass: Array, stiffness: Array) -> Array:
    """Eigenvalues of stiffness · v = λ mass · v, ascending, for symmetric positive-definite
    ``mass`` and symmetric ``stiffness`` of shape (..., k, k) with k ≤ :data:`MAX_MODES`:
    shape (..., k). Batch axes in front, any number."""
    return _jacobi(_congruence(_cholesky(_entries(mass)), _entries(stiffness)))


def eigvalsh_small(a: Array) -> Array:
    """Eigenvalues of the symmetric matrices ``a`` (..., k, k), ascending, (..., k)."""
    return _jacobi(_entries(a))


def _entries(a: Array) -> list[list[Array]]:
    """The k² entries of the matrices ``a`` (..., k, k), each an array over the batch axes;
    refuses k > :data:`MAX_MODES` before anything is unrolled."""
    k = a.shape[-1]
    if k > MAX_MODES:
        raise ValueError(f"eigvalsh_small is for k <= {MAX_MODES}; got k = {k}")
    return [[a[..., i, j] for j in range(k)] for i in range(k)]


def _jacobi(a: list[list[Array]]) -> Array:
    """Eigenvalues, ascending, of a symmetric matrix given as its entries (the upper triangle
    is read), by :data:`SWEEPS` cyclic Jacobi sweeps (a loop over one unrolled sweep)."""
    k = len(a)
    a = [[a[min(i, j)][max(i, j)] for j in range(k)] for i in range(k)]

    def sweep(_, a):
        for p, q in itertools.combinations(range(k), 2):
            a = _rotate(a, p, q)
        return a

    a = jax.lax.fori_loop(0, SWEEPS, sweep, a)
    return jnp.sort(jnp.stack([a[i][i] for i in range(k)], axis=-1), axis=-1)


def _rotate(a, p, q):
    """Jᵀ a J for the Jacobi rotation J(p, q) that zeroes a[p][q] (Golub & Van Loan,
    Algorithm 8.5.1): a list-of-entries matrix, a new one."""
    apq = a[p][q]
    zero = apq == 0.0
    tau = (a[q][q] - a[p][p]) / (2.0 * jnp.where(zero, 1.0, apq))
    t = jnp.where(tau >= 0.0, 1.0, -1.0) / (jnp.abs(tau) + jnp.sqrt(1.0 + tau * tau))
    t = jnp.where(zero, 0.0, t)
    c = 1.0 / jnp.sqrt(1.0 + t * t)
    s = t * c
    k = len(a)
    a = [row[:] for row in a]
    for j in range(k):  # rows p, q of Jᵀ a
        ap, aq = a[p][j], a[q][j]
        a[p][j], a[q][j] = c * ap - s * aq, s * ap + c * aq
    for i in range(k):  # columns p, q of (Jᵀ a) J
        ap, aq = a[i][p], a[i][q]
        a[i][p], a[i][q] = c * ap - s * aq, s * ap + c * aq
    a[p][q] = a[q][p] = jnp.zeros_like(apq)
    return a


def _cholesky(m):
    """Lower L with L Lᵀ = m (entries), L as entries (zeros above the diagonal not kept)."""
    k = len(m)
    low = [[None] * k for _ in range(k)]
    for j in range(k):
        d = m[j][j] - sum((low[j][i] ** 2 for i in range(j)), start=jnp.zeros_like(m[j][j]))
        low[j][j] = jnp.sqrt(d)
        for r in range(j + 1, k):
            v = m[r][j] - sum((low[r][i] * low[j][i] for i in range(j)),
                              start=jnp.zeros_like(m[r][j]))
            low[r][j] = v / low[j][j]
    return low


def _congruence(low, s):
    """L⁻¹ s L⁻ᵀ (entries) by forward substitution, for symmetric s."""
    k = len(s)

    def forward(b):  # L⁻¹ b for the columns of b (entries b[row][col])
        x = [[None] * k for _ in range(k)]
        for col in range(k):
            for r in range(k):
                v = b[r][col] - sum((low[r][i] * x[i][col] for i in range(r)),
                                    start=jnp.zeros_like(b[r][col]))
                x[r][col] = v / low[r][r]
        return x

    y = forward(s)  # L⁻¹ s
    yt = [[y[j][i] for j in range(k)] for i in range(k)]  # (L⁻¹ s)ᵀ = s L⁻ᵀ
    return forward(yt)  # L⁻¹ s L⁻ᵀ
