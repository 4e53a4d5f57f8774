"""The cycle's equations linearised about the rigid motion: stage solvers, monodromy matrix and
the linear periodic response.

The collocation passes of :mod:`jaxdobby.periodic.stepper` solve each step's stage equations by
simplified Newton iterations with one matrix per step, and the periodic state of
:mod:`jaxdobby.periodic.steady` is found by chord iterations x ← x + (I − Φ)⁻¹(F(x) − x) with an
approximation Φ of the monodromy matrix. Both only need matrices *close* to the exact Jacobians
(the iterations converge to the same solution whatever matrices they use, only more or less
fast), and the elastic state is small (the joint of link 11 moves by ~1 mm on links of
~0.4 m), so both are taken about the rigid motion q = 0, where they do not depend on the elastic
state: built once per sample, before any cycle is integrated, and used by every pass.

At step n the frozen matrices are those of :func:`jaxdobby.dobby.equations_at` at the step's
middle node τ = (n + ½)/N, at q = q̇ = q̈ = 0:

    M̄ = M_b + μ g gᵀ,   C̄ = C_b + 2ωG − ∂(g φ)/∂u̇ Φ_P,   K̄ = K(τ) − ∂(g φ)/∂u Φ_P

(the chain's inertia, damping and stiffness through the joint's displacement u = Φ_P q,
:func:`jaxdobby.periodic.chain.chain_terms`; forward-mode derivatives). Their stage matrices
I⊗M̄ + h a⊗C̄ + h² a²⊗K̄ are inverted once (:class:`~jaxdobby.periodic.collocation.StageSolver`).
The same matrices define the linearised equations M̄ q̈ + C̄ q̇ + K̄ q = f + g φ (the forces
at the rigid motion, at every node), whose collocation step is affine,
x_{n+1} = Ψₙ xₙ + cₙ (:func:`step_map`). Carried through one cycle they give the monodromy
matrix Φ = Ψ_{N−1}⋯Ψ₀ and the end state d of the cycle started at rest, hence the periodic
state of the linearised equations, x_lin = (I − Φ)⁻¹ d: the start of the nonlinear iterations.

**How good** (32 samples of the default Sobol box, ad-hoc scripts, 2026-12-02): Φ is within
0.44 % (median; 2.1 % at most) of the exact monodromy matrix of the discrete cycle map at the
static equilibrium, as close as the tangents of the frozen Newton matrices carried along an
integrated cycle (0.35 %; 1.9 %), which cost a cycle of extra work. From x_lin, the nonlinear
cycle's relative periodicity residual (:func:`jaxdobby.steady_state.relative_residual`) is
3e-3 (median; 3 at most: the linearisation's unresolved stiff modes), then 3e-6, 4e-9 after
one and two chord steps (1e-4, 8e-7 at most); from the static equilibrium it takes a cycle
more to get there (1, 9e-4, 9e-7, 2e-9).

**What it costs** (256 samples of the default design, lanes last, one pinned core, ad hoc,
2026-12-07, with the chunk's compile options of :mod:`jaxdobby.sensitivity.batch` left at
their earlier value): ~0.61 ms per sample, of which the chain's frozen matrices and forces
~0.18; the product Φ ← ΨΦ and the step maps Ψ cost nothing measurable lanes last (~0.20 of
0.56 ms lanes first, 2026-12-05); the rest are the inversions, which the passes need anyway.
Without materialising the chain's terms (``key``) XLA recomputed them in each entry of the
matrices built from them: 1.03 ms per sample. A nonlinear cycle costs ~0.24 ms per sample
on the same machine.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from . import collocation as gl
from .chain import Downstream, chain_terms
from .cycle import ArmTerms, StageTables


class Linearisation(eqx.Module):
    """The frozen Newton matrices of every step and the linearised cycle of one sample.

    Attributes:
        solvers: the inverted stage matrices of the N steps
            (:class:`~jaxdobby.periodic.collocation.StageSolver`, leaves with leading axis N).
        monodromy: Φ, (2k, 2k).
        rest_response: d, the end state of the linearised cycle started at x = 0, (2k,).
    """

    solvers: gl.StageSolver
    monodromy: Array
    rest_response: Array


def chain_jacobian(ds: Downstream, frame, u, u_rate, acc):
    """∂(g φ − μ g gᵀ a)/∂u and ∂/∂u̇ of the chain's generalised force at one instant, each
    (k, 2) (forward-mode derivatives of :func:`~jaxdobby.periodic.chain.chain_terms`)."""
    def force(uu, uud):
        ct = chain_terms(ds, frame, uu, uud)
        return ct.g * ct.phi - ct.mu * ct.g * gl.matmul(ct.g[None], acc)[0]

    eye = jnp.eye(2)
    zero = jnp.zeros((2, 2))
    dirs_u = jnp.concatenate([eye, zero])
    dirs_ud = jnp.concatenate([zero, eye])
    cols = jax.vmap(lambda a, b: jax.jvp(force, (u, u_rate), (a, b))[1])(dirs_u, dirs_ud)
    return gl.transpose(cols[:2]), gl.transpose(cols[2:])


def frozen_matrices(arm: ArmTerms, ds: Downstream, mid, key=None):
    """(M̄, C̄, K̄) at the rigid motion for one step, from the tables ``mid`` of its middle node
    (see the module docstring); ``key``: the chain's terms kept in memory
    (:func:`~jaxdobby.periodic.collocation.stored`)."""
    k = arm.mass.shape[0]
    zero = jnp.zeros(2)
    ct = chain_terms(ds, mid.frame, zero, zero)
    ju, jud = chain_jacobian(ds, mid.frame, zero, zero, jnp.zeros(k))
    if key is not None:
        ct, ju, jud = gl.stored((ct, ju, jud), key)
    mass = arm.mass + ct.mu * ct.g[:, None] * ct.g[None, :]
    damp = arm.damping + 2.0 * mid.frame.omega * arm.gyroscopic - gl.matmul(jud, ds.rows)
    stiff = mid.stiffness - gl.matmul(ju, ds.rows)
    return mass, damp, stiff


def tangent_step(solver: gl.StageSolver, damp, stiff, tangents, h):
    """The linear step map of the frozen matrices applied to tangents (2k, m), stage by stage:
    the stage accelerations of M̄ δq̈ + C̄ δq̇ + K̄ δq = 0, then the end state."""
    k = tangents.shape[0] // 2
    dq, dv = tangents[:k], tangents[k:]
    kdq, kdv, cdv = gl.matmul(stiff, dq), gl.matmul(stiff, dv), gl.matmul(damp, dv)
    rhs = -(cdv + kdq)[None] - h * gl.weigh(gl.NODES[:, None], kdv[None])
    da = solver.solve(rhs)
    return jnp.concatenate([dq + h * dv + h**2 * gl.weigh(gl.WEIGHTS2, da),
                            dv + h * gl.weigh(gl.WEIGHTS, da)])


def _block_weights():
    """Weights of the eigen-blocks j of the Butcher matrix (a = T Λ T⁻¹) in the step map: the
    stage right-hand side −[K̄ δq + (C̄ + cᵢ h K̄) δv] enters block j as −[σⱼ(K̄δq + C̄δv) +
    h ρⱼ K̄δv], and block j's solution enters δq_{n+1} with h² αⱼ and δv_{n+1} with h βⱼ."""
    t, ti = gl.T, gl.T_INV
    sigma = gl.exact_product(ti, np.ones(3))  # exact: the same literals on every CPU
    rho = gl.exact_product(ti, gl.NODES)
    alpha = gl.exact_product(gl.WEIGHTS2, t)
    beta = gl.exact_product(gl.WEIGHTS, t)
    return sigma, rho, alpha, beta


_SIGMA, _RHO, _ALPHA, _BETA = _block_weights()


def step_map(solver: gl.StageSolver, damp, stiff, h):
    """Ψ, (2k, 2k): the step map of the frozen matrices, x_{n+1} = Ψ xₙ for the homogeneous
    linearised equations (what :func:`tangent_step` applies to tangents), from the inverted
    blocks B⁻¹ = (M̄ + hλC̄ + h²λ²K̄)⁻¹ by P = B⁻¹K̄ and Q = B⁻¹C̄:

        Ψ = I + [[0, hI], [0, 0]] − Σⱼ [h²αⱼ; hβⱼ] ⊗ [σⱼPⱼ, σⱼQⱼ + hρⱼPⱼ]

    (the real block j = 0 and twice the real part of the complex block j = 1; its conjugate
    j = 2 gives the conjugate). k matrix products of k × k per block instead of a 2k-column
    stage solve.
    """
    eye = gl.identity_like(stiff)
    p0, q0 = gl.matmul(solver.real, stiff), gl.matmul(solver.real, damp)
    pr = gl.matmul(solver.cre, stiff)
    pi = gl.matmul(solver.cim, stiff)
    qr = gl.matmul(solver.cre, damp)
    qi = gl.matmul(solver.cim, damp)

    def combine(w0, w1, a0, a1r, a1i):
        """w0·a0 + 2 Re(w1·(a1r + i a1i)) for real w0, complex w1."""
        return (float(w0) * a0 + 2.0 * (float(w1.real) * a1r - float(w1.imag) * a1i))

    s, r, al, be = _SIGMA, _RHO, _ALPHA, _BETA
    # columns acting on δq: σP; on δv: σQ + hρP (per block, complex for j = 1)
    on_q0 = s[0].real * p0
    c1 = s[1]
    on_q1r, on_q1i = c1.real * pr - c1.imag * pi, c1.real * pi + c1.imag * pr
    d1 = h * r[1]
    on_v0 = s[0].real * q0 + h * r[0].real * p0
    on_v1r = (c1.real * qr - c1.imag * qi) + (d1.real * pr - d1.imag * pi)
    on_v1i = (c1.real * qi + c1.imag * qr) + (d1.real * pi + d1.imag * pr)
    qq = eye - h**2 * combine(al[0].real, al[1], on_q0, on_q1r, on_q1i)
    qv = h * eye - h**2 * combine(al[0].real, al[1], on_v0, on_v1r, on_v1i)
    vq = -h * combine(be[0].real, be[1], on_q0, on_q1r, on_q1i)
    vv = eye - h * combine(be[0].real, be[1], on_v0, on_v1r, on_v1i)
    return jnp.concatenate([jnp.concatenate([qq, qv], axis=1),
                            jnp.concatenate([vq, vv], axis=1)])


def rest_forces(arm: ArmTerms, ds: Downstream, st, key=None) -> Array:
    """The stage forces of the linearised equations at the rigid motion, f + g φ at q = 0,
    (3, k) for a step's three nodes (tables ``st`` with leading axis 3); ``key``: as
    :func:`frozen_matrices`'."""
    zero = jnp.zeros(2)
    ct = jax.vmap(chain_terms, in_axes=(None, 0, None, None))(ds, st.frame, zero, zero)
    if key is not None:
        ct = gl.stored(ct, key)
    return st.force + ct.phi[:, None] * ct.g


def _frozen_step(carry, mass, damp, stiff, forces, h, key):
    """One step of the linearised cycle: the stage solver of the frozen matrices, Φ ← Ψ Φ and
    d ← Ψ d + c. Every array has its matrix axes first and any batch axes last (the unrolled
    products of :mod:`jaxdobby.periodic.collocation` then run over contiguous lanes)."""
    phi, d = carry
    solver = gl.stored(gl.StageSolver(mass, damp, stiff, h, key), key)
    psi = gl.stored(step_map(solver, damp, stiff, h), key)
    da = solver.solve(forces)
    c = jnp.concatenate([h**2 * gl.weigh(gl.WEIGHTS2, da), h * gl.weigh(gl.WEIGHTS, da)])
    return (gl.matmul(psi, phi), gl.matmul(psi, d) + c), solver


def linearise(arm: ArmTerms, ds: Downstream, tables: StageTables, period,
              steps=None) -> Linearisation:
    """:class:`Linearisation` of one sample's cycle (tables with leading axes (N, 3)).

    A batch with its lanes last (as :func:`jaxdobby.periodic.cycle.tables_at` builds its
    tables: ``period`` (B,), every leaf with a trailing lane axis) gives the same with the lanes
    last: the solvers' leaves (N, ..., B), Φ (2k, 2k, B) and d (2k, B).

    ``steps``: None, the cycle is the tables' N steps (a scan, differentiable); else the
    number of steps of the cycle, a run-time integer ≤ N (the tables' first ``steps`` rows,
    :func:`jaxdobby.periodic.cycle.node_phases` with a ``size``): a loop of that many steps,
    the solvers' rows beyond it left zero (not differentiable in reverse mode).
    """
    n_steps = tables.height.shape[0]
    h = period / (n_steps if steps is None else steps)
    k = arm.mass.shape[0]
    lanes = jnp.shape(period)

    def step(carry, index):
        st = jax.tree.map(lambda a: a[index], tables)
        mid = jax.tree.map(lambda a: a[1], st)
        mass, damp, stiff, forces = gl.stored((*frozen_matrices(arm, ds, mid, index),
                                               rest_forces(arm, ds, st, index)), index)
        return _frozen_step(carry, mass, damp, stiff, forces, h, index)

    eye = jnp.broadcast_to(jnp.eye(2 * k).reshape((2 * k, 2 * k) + (1,) * len(lanes)),
                           (2 * k, 2 * k) + lanes)
    start = (eye, jnp.zeros((2 * k,) + lanes))
    if steps is None:
        (phi, d), solvers = jax.lax.scan(step, start, jnp.arange(n_steps))
        return Linearisation(solvers, phi, d)

    def store(index, carry):
        carry, solvers = carry
        carry, solver = step(carry, index)
        return carry, jax.tree.map(lambda b, s: b.at[index].set(s), solvers, solver)

    shapes = jax.eval_shape(lambda c: step(c, jnp.asarray(0))[1], start)
    buffers = jax.tree.map(lambda a: jnp.zeros((n_steps,) + a.shape, a.dtype), shapes)
    (phi, d), solvers = jax.lax.fori_loop(0, steps, store, (start, buffers))
    return Linearisation(solvers, phi, d)
