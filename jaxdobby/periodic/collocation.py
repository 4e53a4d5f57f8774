"""Three-stage Gauss–Legendre collocation for M(q) q̈ = F(t, q, q̇), and its stage solver.

The method (order 6, A-stable, symmetric: no numerical damping of resolved modes; Hairer &
Wanner, *Solving ODEs II*, §IV.5) applied to the second-order system through its stage
accelerations Aᵢ ≈ q̈(t_n + cᵢh):

    Vᵢ = v_n + h Σⱼ aᵢⱼ Aⱼ,   Qᵢ = q_n + cᵢ h v_n + h² Σⱼ (a²)ᵢⱼ Aⱼ,
    M(Qᵢ) Aᵢ = F(t_n + cᵢh, Qᵢ, Vᵢ),
    q_{n+1} = q_n + h v_n + h² Σⱼ (bᵀa)ⱼ Aⱼ,   v_{n+1} = v_n + h Σⱼ bⱼ Aⱼ.

The stage equations are solved by simplified Newton iterations with one matrix per step,
M̄ + h a⊗C̄ + h² a²⊗K̄ (3k × 3k). Diagonalising the Butcher matrix a = T Λ T⁻¹ (one real
eigenvalue, one complex pair) splits it into a real k × k system M̄ + hγC̄ + h²γ²K̄ and a
complex one (Butcher 1976; Hairer & Wanner §IV.8), both inverted here by Gauss–Jordan elimination
without pivoting (once per step, see :class:`StageSolver`): their real parts are M̄ plus small
multiples of C̄ and K̄, symmetric positive definite up to the small gyroscopic terms, for which
Gaussian elimination without pivoting is stable (Higham, *Accuracy and Stability of Numerical
Algorithms*, §10.4). Complex numbers are carried as (real, imaginary)
pairs of float64 arrays (faster on a CPU than complex128 here).
"""

from __future__ import annotations

import math
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

_R15 = math.sqrt(15.0)
NODES = np.array([0.5 - _R15 / 10.0, 0.5, 0.5 + _R15 / 10.0])
"""cᵢ, the Gauss points on [0, 1]."""
MATRIX = np.array([[5 / 36, 2 / 9 - _R15 / 15, 5 / 36 - _R15 / 30],
                   [5 / 36 + _R15 / 24, 2 / 9, 5 / 36 - _R15 / 24],
                   [5 / 36 + _R15 / 30, 2 / 9 + _R15 / 15, 5 / 36]])
"""aᵢⱼ."""
WEIGHTS = np.array([5 / 18, 4 / 9, 5 / 18])
"""bⱼ."""


def exact_product(a, b) -> np.ndarray:
    """a @ b for small real or complex NumPy arrays (1-D or 2-D), each entry the correctly
    rounded value of the exact sum of the exact products of the float64 inputs.

    The method's constants enter the traced programs as literals, and ``np.matmul`` calls BLAS,
    whose kernels round differently on different CPUs (fused multiply-adds, summation order):
    the same source would trace different programs on an Intel and an AMD machine, and a
    compiled program shipped for one would no longer match the other's key
    (:mod:`jaxdobby.programs`). Rational arithmetic makes every constant a function of the
    source alone.
    """
    a, b = np.asarray(a), np.asarray(b)
    left = a if a.ndim == 2 else a[None]
    right = b if b.ndim == 2 else b[:, None]
    cplx = np.iscomplexobj(left) or np.iscomplexobj(right)

    def parts(x):
        z = complex(x)
        return Fraction(z.real), Fraction(z.imag)

    out = np.zeros((left.shape[0], right.shape[1]), dtype=complex if cplx else float)
    for i in range(left.shape[0]):
        for j in range(right.shape[1]):
            re = im = Fraction(0)
            for m in range(left.shape[1]):
                (ar, ai), (br, bi) = parts(left[i, m]), parts(right[m, j])
                re += ar * br - ai * bi
                im += ar * bi + ai * br
            out[i, j] = complex(float(re), float(im)) if cplx else float(re)
    if b.ndim == 1:
        out = out[:, 0]
    return out[0] if a.ndim == 1 else out


MATRIX2 = exact_product(MATRIX, MATRIX)
"""(a²)ᵢⱼ: the stage displacements' weights."""
WEIGHTS2 = exact_product(WEIGHTS, MATRIX)
"""(bᵀa)ⱼ: the end displacement's weights."""

GAMMA = 0.21531442311611218
LAMBDA = complex(0.14234278844194392, 0.1357999257081538)
T = np.array([[0.07215185205520017, complex(-0.08224123057363067, -0.0601207386193085),
               complex(-0.08224123057363067, 0.0601207386193085)],
              [0.11883257874127781, complex(0.053065090742061394, 0.3162050511322916),
               complex(0.053065090742061394, -0.3162050511322916)],
              [1.0, 1.0, 1.0]], dtype=complex)
T_INV = np.array([[5.991698084937801, 1.1392142951557354, 0.43231211378385836],
                  [complex(-2.9958490424689006, 0.6231066367931157),
                   complex(-0.5696071475778677, -1.4627798230961568),
                   complex(0.2838439431080708, 0.12886760063671623)],
                  [complex(-2.9958490424689006, -0.6231066367931157),
                   complex(-0.5696071475778677, 1.4627798230961568),
                   complex(0.2838439431080708, -0.12886760063671623)]], dtype=complex)
"""a = T diag(γ, λ, λ̄) T⁻¹: real eigenvalue γ, complex λ (Im > 0); T's columns are the
eigenvectors scaled so that their largest component is 1 (column 0 real, column 2 the conjugate
of column 1). The exact eigen-decomposition of the exact Butcher matrix (γ = 1/z₀ and
λ = 1/z̄₁ for the roots z of z³ − 12z² + 60z − 120, the Padé denominator; Hairer & Wanner §IV.8),
evaluated at 50 digits with mpmath (``mpmath.eig`` and ``T**-1``) and rounded to float64: written
out rather than computed by LAPACK at import, whose last digits differ between CPUs (see
:func:`exact_product`). ``tests/test_collocation_constants.py`` holds them against
``numpy.linalg.eig``."""


def _lagrange(x) -> np.ndarray:
    """ℓᵢ(x), the Lagrange basis on the nodes, in rational arithmetic (see :func:`exact_product`)."""
    x, c = Fraction(float(x)), [Fraction(float(n)) for n in NODES]
    return np.array([float(math.prod((x - c[m]) / (c[i] - c[m]) for m in range(3) if m != i))
                     for i in range(3)])


def dense_weights(theta) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the collocation polynomial inside a step, at fractions θ ∈ [0, 1] of it.

    Within a step the collocation solution is the cubic whose acceleration is the quadratic
    interpolant Σᵢ ℓᵢ(θ) Aᵢ of the stage accelerations (ℓᵢ the Lagrange basis on the nodes):

        v(t_n + θh) = v_n + h Σᵢ W1ᵢ(θ) Aᵢ,   W1ᵢ(θ) = ∫₀^θ ℓᵢ(s) ds,
        q(t_n + θh) = q_n + θh v_n + h² Σₖ W2ₖ(θ) Aₖ,   W2ₖ(θ) = Σᵢ W1ᵢ(θ) aᵢₖ

    (q̇ of the polynomial interpolates the stage velocities Vᵢ; Hairer, Nørsett & Wanner,
    *Solving ODEs I*, §II.7, eq. 7.17). At θ = cⱼ they are the rows of a and a², at θ = 1 the
    weights b and bᵀa of :func:`advance`.

    Returns:
        (W1, W2), each of shape (len(θ), 3).
    """
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    c = [Fraction(float(n)) for n in NODES]
    w1 = np.zeros((theta.size, 3))
    for i in range(3):
        a, b = (c[m] for m in range(3) if m != i)
        scale = (c[i] - a) * (c[i] - b)  # ℓᵢ(s) = (s − a)(s − b) / scale, integrated exactly
        for n, th in enumerate(theta.tolist()):
            th = Fraction(th)
            w1[n, i] = float((th**3 / 3 - (a + b) * th**2 / 2 + a * b * th) / scale)
    return w1, exact_product(w1, MATRIX)


EXTRAPOLATE = np.stack([_lagrange(1.0 + c) for c in NODES])
"""Predictor: the quadratic through the previous step's Aᵢ, evaluated at this step's nodes."""


def stage_states(q, v, acc, h):
    """(Qᵢ, Vᵢ), each (3, k), from q_n, v_n (k,) and the stage accelerations (3, k)."""
    vel = v[None] + h * weigh(MATRIX, acc)
    pos = q[None] + h * weigh(NODES[:, None], v[None]) + h**2 * weigh(MATRIX2, acc)
    return pos, vel


def advance(q, v, acc, h):
    """(q_{n+1}, v_{n+1}) from the converged stage accelerations."""
    return q + h * v + h**2 * weigh(WEIGHTS2, acc), v + h * weigh(WEIGHTS, acc)


def stored(tree, key):
    """``tree``, computed once and kept in memory: passed through a ``lax.cond`` on a run-time
    scalar ``key`` ≥ 0 (always true), whose result XLA must materialise.

    The products of a step are unrolled into elementwise arithmetic (:func:`matmul`), and
    without these boundaries XLA's CPU backend fuses the chain's terms into each of their many
    small consumers and recomputes them per output element (fusions of ~300 instructions;
    measured: two passes of 256 samples 40 % slower than with the batched dots they replace).
    With them the batch evaluator's :func:`~jaxdobby.periodic.steady.steady_state_metrics` ran in
    7.2 ms per sample against 11.7 ms with batched dots (256 samples, one core). ``lax.optimization_barrier`` does not
    survive to the CPU backend's fusion passes, a conditional does.
    """
    return jax.lax.cond(key >= 0, lambda t: t, lambda t: jax.tree.map(jnp.zeros_like, t), tree)


# -- small dense linear algebra, unrolled up to UNROLL_MAX modes -------------------------------
# Why unrolled: the batch evaluator runs the passes under jax.vmap, where a product of per-sample
# matrices becomes a dot with a batch dimension, which XLA's CPU backend runs as one tiny matrix
# product per sample. Measured on 256 samples, a (3, 4)·(4, 4) product: 99 µs as a batched dot,
# 5 µs as the unrolled elementwise sum below.
UNROLL_MAX = 8
"""Largest k whose products and inversions are unrolled (a Python loop over k); above it they
are a dot (``jnp.einsum``) and a ``lax.fori_loop`` over the pivots. Unrolled, the k
eliminations of an inversion form one chain of k rank-one updates of k × k arrays, which XLA
fuses into kernels of ~1000 instructions and copies into each consumer: the 30-mode simulate
program held 180 000 instructions after fusion and took 30 s to compile. Measured on 2 cores
(AMD EPYC, 2026-12-06), simulate's steady-state program, compile / warm run: k = 16 10.6 s /
129 ms unrolled, 4.9 s / 74 ms with the loops; k = 30 29.8 s / 546 ms against 5.9 s / 175 ms;
k = 8 6.4 s / 37 ms against 4.5 s / 27 ms. Under vmap (64 samples) the loops cost more per
sample at k = 8 (4.5 against 3.9 ms) and less at k = 16 (13.7 against 21.4 ms): 8 is where they
start to pay. The default 4 modes (its shipped programs, the Sobol batch) stay unrolled."""
def weigh(w, x) -> Array:
    """Σⱼ w[..., j] x[j]: constant weights w (numpy, (n,) or (m, n)) on the leading axis of x."""
    w = np.asarray(w)
    return jnp.tensordot(jnp.asarray(w), x, axes=(w.ndim - 1, 0))


def matmul(a, b) -> Array:
    """The matrix product of a (m, n, …) and b (n, p, …) or b (n, …) over their leading axes,
    unrolled over n up to :data:`UNROLL_MAX` (see the note above), a dot beyond."""
    if a.shape[1] > UNROLL_MAX:
        return jnp.einsum("mn...,n...->m..." if b.ndim == a.ndim - 1 else "mn...,np...->mp...",
                          a, b)
    if b.ndim == a.ndim - 1:  # matrix-vector
        return sum(a[:, j] * b[j] for j in range(a.shape[1]))
    return sum(a[:, j, None] * b[j][None] for j in range(a.shape[1]))


def identity_like(a) -> Array:
    """The identity matrix of a (k, k, …) stack of matrices, shape (k, k) plus one axis of
    length one for each of a's trailing axes (to broadcast against it)."""
    k = a.shape[0]
    return jnp.eye(k, dtype=a.dtype).reshape((k, k) + (1,) * (a.ndim - 2))


def transpose(a) -> Array:
    """A (m, n, …) matrix's transpose (n, m, …)."""
    return jnp.swapaxes(a, 0, 1)


def inverse(a: Array, key=None) -> Array:
    """The inverse of a real (k, k, …) matrix (any trailing lane axes) by Gauss–Jordan
    elimination without pivoting (see the module docstring for why no pivoting is needed).

    Each of the k eliminations is one rank-one update of the whole matrix and of the growing
    inverse, M ← M − c ⊗ r with r the pivot row divided by the pivot and c the pivot column
    less the unit vector (which turns the pivot row into r): k array operations on k × k
    arrays, so the traced program grows linearly with k (an elimination unrolled into scalar
    operations grows as k³: 16 modes did not compile in 400 s); above :data:`UNROLL_MAX` they
    are a loop.

    ``key``: a run-time integer ≥ 0 (a step index): each elimination's result is then kept in
    memory (:func:`stored`). Without it XLA fuses the k eliminations into one kernel that
    computes every entry of the inverse from the matrix anew, the earlier eliminations'
    entries recomputed for each. Measured in the batch evaluator's linearisation
    (:func:`jaxdobby.periodic.linear.linearise`, 4 modes, 64 rows of the default design, one
    pinned core, Intel Xeon, 2026-12-07): the model, tables and linearisation alone at 432
    steps 0.70 against 0.545 ms per sample; the whole evaluation with steps by speed (the
    Sobol study's) 0.82–0.84 against 0.75–0.79; at a fixed 432 steps (a scan, whose fusions
    differ) 1.03–1.09 against 1.04–1.17, no gain. The metrics are the same to ~1e-12.
    """
    k = a.shape[0]
    if k > UNROLL_MAX:
        return _inverse_loop(a)
    eye = jnp.broadcast_to(identity_like(a), a.shape)
    m, inv = a, eye
    for p in range(k):
        scale = 1.0 / m[p, p]
        column = m[:, p] - eye[:, p]
        row, inv_row = m[p] * scale, inv[p] * scale
        m = m - column[:, None] * row[None]
        inv = inv - column[:, None] * inv_row[None]
        if key is not None and p < k - 1:
            m, inv = stored((m, inv), key)
    return inv


def complex_inverse(re: Array, im: Array, key=None) -> tuple[Array, Array]:
    """:func:`inverse` of the complex matrix re + i·im, as (real, imaginary) parts; ``key``: as
    :func:`inverse`'s."""
    if re.shape[0] > UNROLL_MAX:
        return _complex_inverse_loop(re, im)
    eye = jnp.broadcast_to(identity_like(re), re.shape)
    mr, mi, ir, ii = re, im, eye, jnp.zeros_like(re)
    for p in range(re.shape[0]):
        norm = mr[p, p] ** 2 + mi[p, p] ** 2
        sr, si = mr[p, p] / norm, -mi[p, p] / norm  # 1 / pivot
        cr, ci = mr[:, p] - eye[:, p], mi[:, p]
        rows = []
        for ar, ai in ((mr[p], mi[p]), (ir[p], ii[p])):
            rows.append((ar * sr - ai * si, ar * si + ai * sr))
        (rr, ri), (jr, ji) = rows
        mr, mi = (mr - (cr[:, None] * rr[None] - ci[:, None] * ri[None]),
                  mi - (cr[:, None] * ri[None] + ci[:, None] * rr[None]))
        ir, ii = (ir - (cr[:, None] * jr[None] - ci[:, None] * ji[None]),
                  ii - (cr[:, None] * ji[None] + ci[:, None] * jr[None]))
        if key is not None and p < re.shape[0] - 1:
            mr, mi, ir, ii = stored((mr, mi, ir, ii), key)
    return ir, ii


def _inverse_loop(a: Array) -> Array:
    """:func:`inverse` with its eliminations a ``lax.fori_loop`` (the same arithmetic: pivot p
    a traced index)."""
    eye = jnp.broadcast_to(identity_like(a), a.shape)

    def eliminate(p, state):
        m, inv = state
        scale = 1.0 / _at(_at(m, p, 0), p, 0)
        column = _at(m, p, 1) - _at(eye, p, 1)
        row, inv_row = _at(m, p, 0) * scale, _at(inv, p, 0) * scale
        return m - column[:, None] * row[None], inv - column[:, None] * inv_row[None]

    return jax.lax.fori_loop(0, a.shape[0], eliminate, (a, eye))[1]


def _complex_inverse_loop(re: Array, im: Array) -> tuple[Array, Array]:
    """:func:`complex_inverse` with its eliminations a ``lax.fori_loop``."""
    eye = jnp.broadcast_to(identity_like(re), re.shape)

    def eliminate(p, state):
        mr, mi, ir, ii = state
        pr, pi = _at(_at(mr, p, 0), p, 0), _at(_at(mi, p, 0), p, 0)
        norm = pr ** 2 + pi ** 2
        sr, si = pr / norm, -pi / norm  # 1 / pivot
        cr, ci = _at(mr, p, 1) - _at(eye, p, 1), _at(mi, p, 1)
        (rr, ri), (jr, ji) = ((ar * sr - ai * si, ar * si + ai * sr) for ar, ai in
                              ((_at(mr, p, 0), _at(mi, p, 0)), (_at(ir, p, 0), _at(ii, p, 0))))
        return (mr - (cr[:, None] * rr[None] - ci[:, None] * ri[None]),
                mi - (cr[:, None] * ri[None] + ci[:, None] * rr[None]),
                ir - (cr[:, None] * jr[None] - ci[:, None] * ji[None]),
                ii - (cr[:, None] * ji[None] + ci[:, None] * jr[None]))

    state = jax.lax.fori_loop(0, re.shape[0], eliminate, (re, im, eye, jnp.zeros_like(re)))
    return state[2], state[3]


def _at(x: Array, p, axis: int) -> Array:
    """x's entry p along ``axis`` (that axis dropped), p traced."""
    return jax.lax.dynamic_index_in_dim(x, p, axis, keepdims=False)


def solve(a: Array, b: Array) -> Array:
    """Solve a x = b for a real (k, k) matrix and b (k,) or (k, m), by :func:`inverse`."""
    return matmul(inverse(a), b)


@jax.tree_util.register_pytree_node_class
class StageSolver:
    """The simplified-Newton matrix of one step, inverted: solves
    (I⊗M + h a⊗C + h² a²⊗K) x = r for stage right-hand sides r of shape (3, k) or (3, k, m).

    The real and the complex k × k blocks are inverted once per step (Gauss–Jordan
    elimination without pivoting, :func:`inverse`; ``key``: its ``key``) and every solve is then a
    product with the inverses: the step solves three or four right-hand sides with the same
    matrix, and a product is one short fused loop where a triangular substitution chains k
    dependent rows.
    """

    def __init__(self, mass, damping, stiffness, h, key=None):
        g, lam = GAMMA, LAMBDA
        self.real = inverse(mass + h * g * damping + (h * g) ** 2 * stiffness, key)
        l2 = lam * lam
        re = mass + h * lam.real * damping + h * h * l2.real * stiffness
        im = h * lam.imag * damping + h * h * l2.imag * stiffness
        self.cre, self.cim = complex_inverse(re, im, key)

    def tree_flatten(self):
        return (self.real, self.cre, self.cim), None

    @classmethod
    def tree_unflatten(cls, _, leaves):
        solver = object.__new__(cls)
        solver.real, solver.cre, solver.cim = leaves
        return solver

    def solve(self, r: Array) -> Array:
        ti = T_INV
        z0 = sum(float(ti[0, i].real) * r[i] for i in range(3))
        zr = sum(float(ti[1, i].real) * r[i] for i in range(3))
        zi = sum(float(ti[1, i].imag) * r[i] for i in range(3))
        w0 = matmul(self.real, z0)
        wr = matmul(self.cre, zr) - matmul(self.cim, zi)
        wi = matmul(self.cre, zi) + matmul(self.cim, zr)
        return jnp.stack([float(T[i, 0].real) * w0
                          + 2.0 * (float(T[i, 1].real) * wr - float(T[i, 1].imag) * wi)
                          for i in range(3)])
