"""Reduction on a fixed basis (jaxdobby.ritz, flexible_body(basis=...)): no eigenvector
derivatives on the gradient path, and what goes wrong without it when two modes meet."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby import Machine, OperatingPoint
from jaxdobby.arm import ArmDesign
from jaxdobby.dobby import LINK, arm_modes, build_model
from jaxdobby.outputs import coupled_frequencies
from jaxdobby.ritz import modal_damping, reduced_frequencies, spd_sqrt

RNG = np.random.default_rng(7)


def spd(n=4, spread=1e4, rng=RNG):
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return jnp.asarray(q @ np.diag(np.geomspace(1.0, spread, n)) @ q.T)


def eig_sqrt(a):
    w, v = np.linalg.eigh(np.asarray(a))
    return (v * np.sqrt(w)) @ v.T


def test_spd_sqrt_value_and_derivative():
    a = spd()
    # Denman-Beavers to round-off: ~1e-15 relative to the largest entry.
    np.testing.assert_allclose(spd_sqrt(a), eig_sqrt(a), atol=1e-13 * np.abs(eig_sqrt(a)).max())
    da = spd() / 1e4  # direction of norm ~1
    h = 1e-5
    fd = (eig_sqrt(a + h * da) - eig_sqrt(a - h * da)) / (2 * h)
    fwd = jax.jvp(spd_sqrt, (a,), (da,))[1]
    rev = jax.vjp(spd_sqrt, a)[1](jnp.eye(4))[0]  # cotangent I: d tr(S) = tr(Sdot)
    # Central differences, step 1e-5 against the smallest eigenvalue 1: truncation
    # ~(1e-5)² = 1e-10, round-off ~1e-16·1e2/1e-5 = 1e-9 relative to the largest entry.
    np.testing.assert_allclose(fwd, fd, rtol=1e-6, atol=1e-7 * np.abs(fd).max())
    np.testing.assert_allclose(jnp.sum(rev * da), jnp.trace(fwd), rtol=1e-10)


def test_spd_sqrt_derivative_finite_at_repeated_eigenvalues():
    a = jnp.diag(jnp.array([1.0, 4.0, 4.0, 9.0]))
    da = jnp.asarray(RNG.normal(size=(4, 4)))
    da = da + da.T
    fwd = jax.jvp(spd_sqrt, (a,), (da,))[1]
    # Exact: Sdot_ij = Adot_ij / (sqrt(l_i) + sqrt(l_j)) in the eigenbasis (here the identity),
    # finite although l_2 = l_3 (eigh's derivative would divide by l_2 - l_3 = 0).
    exact = da / (jnp.sqrt(jnp.diag(a))[:, None] + jnp.sqrt(jnp.diag(a))[None, :])
    np.testing.assert_allclose(fwd, exact, rtol=1e-12)


def test_modal_damping_is_invariant_and_modal():
    m, k = spd(spread=10.0), spd(spread=1e3)
    c = modal_damping(m, k, 0.02)
    # In mass-normalised modes (Φᵀ M Φ = I, Φᵀ K Φ = diag ω²) it is diag(2ζω).
    w2, phi = np.linalg.eigh(np.linalg.solve(np.linalg.cholesky(m), np.linalg.solve(
        np.linalg.cholesky(m), k).T))
    lt = np.linalg.cholesky(m).T
    phi = np.linalg.solve(lt, phi)
    np.testing.assert_allclose(phi.T @ c @ phi, np.diag(0.04 * np.sqrt(w2)), atol=1e-12 * 0.04
                               * np.sqrt(w2.max()))
    np.testing.assert_allclose(reduced_frequencies(m, k), np.sqrt(w2), rtol=1e-12)
    # Congruence: basis T gives Tᵀ C T.
    t = jnp.asarray(RNG.normal(size=(4, 4)))
    np.testing.assert_allclose(modal_damping(t.T @ m @ t, t.T @ k @ t, 0.02), t.T @ c @ t,
                               rtol=1e-9, atol=1e-12 * np.abs(t.T @ c @ t).max())


@pytest.fixture(scope="module")
def build():
    return eqx.filter_jit(build_model)


def test_fixed_basis_on_own_modes_is_the_modal_model(build):
    machine, op = Machine.default(), OperatingPoint()
    modal = build(machine, op).body
    fixed = build(machine, op, arm_modes(machine).shapes).body
    for name in ("frequencies", "mass", "stiffness", "damping", "gyroscopic", "centrifugal",
                 "euler", "translation", "points", "point_stiffening"):
        a, b = np.asarray(getattr(modal, name)), np.asarray(getattr(fixed, name))
        # Same numbers by another route (projection vs eigenvalues): round-off of the
        # ~1e4-conditioned reduced problem, 1e-10 relative to the largest entry.
        np.testing.assert_allclose(b, a, atol=1e-10 * np.abs(a).max(), err_msg=name)
    for name, a in modal.stiffening.items():
        np.testing.assert_allclose(fixed.stiffening[name], a, atol=1e-10 * np.abs(a).max())


# A tapered arm on which the 3rd and 4th modes coincide (both ≈ 7628.67 Hz): a conical
# intersection found by minimising the gap over the four control depths (Nelder-Mead, gap
# 7e-15 relative). It is an ordinary design in the optimiser's box (57 → 16 mm taper).
DEGENERATE_POSITIONS = jnp.array([0.0, 0.08, 0.15, 0.226])
DEGENERATE_DEPTHS = jnp.array([0.05662295325013276, 0.03948774645425766, 0.019891889070076767,
                               0.015963829061350403])


def tapered(depth):
    return Machine.default().replace(arm=ArmDesign(depth=depth,
                                                   depth_arc_lengths=DEGENERATE_POSITIONS))


def smooth_outputs(depth, basis):
    """Smooth, basis-invariant functions of the design: the static compliance of the reduced
    arm at the link-11 joint, tr(Φ_P K_r⁻¹ Φ_Pᵀ) [m/N], and the first two coupled natural
    frequencies [Hz] (well separated: 106 and 4200 Hz). Scaled to order 1."""
    model = build_model(tapered(depth), OperatingPoint(), basis)
    rows = model.body.points[LINK]
    compliance = jnp.trace(rows @ jnp.linalg.solve(model.body.stiffness, rows.T))
    return jnp.concatenate([1e8 * compliance[None], coupled_frequencies(model)[:2] / 1e3])


def central_difference(fn, x, h):
    fn = jax.jit(fn)
    cols = [(fn(x.at[i].add(h)) - fn(x.at[i].add(-h))) / (2 * h) for i in range(x.shape[0])]
    return np.stack([np.asarray(c) for c in cols], axis=-1)


def test_near_degenerate_modes_eigh_gradients_blow_up_fixed_basis_does_not():
    d0 = DEGENERATE_DEPTHS
    f = np.asarray(eqx.filter_jit(arm_modes)(tapered(d0)).frequencies)
    assert abs(f[3] - f[2]) / f[2] < 1e-9  # the two modes coincide

    # eigh path: the mode shapes' derivatives carry 1/(λ4 − λ3): huge (measured 4e14 m/√kg per
    # m against shape entries of order 4).
    shapes = lambda d: build_model(tapered(d), OperatingPoint()).body.points[LINK]
    assert np.abs(np.asarray(jax.jit(jax.jacfwd(shapes))(d0))).max() > 1e8
    # ... and smooth, basis-invariant outputs inherit the cancellation error: forward and
    # reverse mode disagree and neither matches the central difference, where the fixed basis
    # below gets 1e-8 (and forward = reverse to 1e-10). The size of that error is round-off
    # amplified by 1/(λ4 − λ3), so it depends on XLA's order of operations: forward against
    # the differences 1.2e-3 with XLA's MLIR fusion emitters, 1.3e-4 with the loop emitters the
    # command line and the tests compile with (2026-12-03); forward against reverse 2.4e-4, and
    # 6.9e-5 since the beam's geometry is computed once per model rather than in every matrix
    # (forward against the differences 1.1e-4; 2026-12-08): the same amplification, rounded
    # elsewhere. The claim is the contrast: > 1e-5 both, a thousand times the fixed basis's
    # error and 1e5 times its forward-reverse agreement.
    eigh = lambda d: smooth_outputs(d, None)
    eigh_fwd = np.asarray(jax.jit(jax.jacfwd(eigh))(d0))
    eigh_rev = np.asarray(jax.jit(jax.jacrev(eigh))(d0))
    eigh_fd = central_difference(eigh, d0, 1e-6)
    assert np.max(np.abs(eigh_fwd - eigh_rev) / np.abs(eigh_fd)) > 1e-5
    assert np.max(np.abs(eigh_fwd - eigh_fd) / np.abs(eigh_fd)) > 1e-5

    # Fixed basis (the modes at d0, held constant): finite, forward = reverse, = differences.
    basis = eqx.filter_jit(arm_modes)(tapered(d0)).shapes
    fixed = lambda d: smooth_outputs(d, basis)
    fwd = np.asarray(jax.jit(jax.jacfwd(fixed))(d0))
    rev = np.asarray(jax.jit(jax.jacrev(fixed))(d0))
    fd = central_difference(fixed, d0, 1e-6)
    assert np.all(np.isfinite(fwd))
    np.testing.assert_allclose(rev, fwd, rtol=1e-10, atol=1e-12 * np.abs(fwd).max())
    # h = 1e-6 m on depths of 2e-2…6e-2 m: truncation ~(h/d)² ~1e-9, round-off
    # ~1e-15/1e-6 ~1e-9 relative → 1e-6 is a safe claim (measured 1e-8).
    np.testing.assert_allclose(fwd, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_near_degenerate_modes_subspace_derivative_is_exact():
    # basis="own" (the design optimiser's model): the design's own modes, differentiated as the
    # subspace they span (jaxdobby.modal.mode_subspace). Modes 3 and 4 are both kept, so their
    # vanishing gap never divides (only kept-vs-discarded gaps do: mode 4 vs 5 is 20 % here).
    d0 = DEGENERATE_DEPTHS
    own = lambda d: smooth_outputs(d, "own")
    eigh = lambda d: smooth_outputs(d, None)
    # the same model as the modal one (projection onto its own modes): round-off
    np.testing.assert_allclose(np.asarray(jax.jit(own)(d0)), np.asarray(jax.jit(eigh)(d0)),
                               rtol=1e-10)
    fwd = np.asarray(jax.jit(jax.jacfwd(own))(d0))
    rev = np.asarray(jax.jit(jax.jacrev(own))(d0))
    fd = central_difference(own, d0, 1e-6)
    assert np.all(np.isfinite(fwd)) and np.all(np.isfinite(rev))
    np.testing.assert_allclose(rev, fwd, rtol=1e-10, atol=1e-12 * np.abs(fwd).max())
    # the derivative of the own-mode model itself (the differences re-solve the eigenproblem
    # at every step); the same claim as the fixed basis above, 1e-6
    np.testing.assert_allclose(fwd, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_subspace_derivative_matches_differences_of_a_random_pencil():
    # mode_subspace on a random symmetric pencil (K, M SPD, 8 DOFs, 3 modes kept): the
    # derivative of a basis-invariant function, the projector P = Φ Φᵀ M onto the span, against
    # central differences of numpy's eigh (an independent eigensolver). Step 1e-6 with the
    # truncation gap λ₄/λ₃ − 1 > 0.1 (asserted): truncation error ~h²/gap², round-off
    # ~1e-16/h → 1e-6 relative to the largest entry.
    from jaxdobby.modal import mode_subspace

    rng = np.random.default_rng(11)  # this test's own matrices, whatever ran before
    n, k = 8, 3
    m0, k0 = spd(n, 10.0, rng), spd(n, 1e3, rng)
    dm, dk = spd(n, 10.0, rng) / 10.0, spd(n, 1e3, rng) / 1e3
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(np.asarray(m0), np.asarray(k0))).real)
    assert lam[k] / lam[k - 1] - 1.0 > 0.1

    def projector(t):
        mass, stiff = m0 + t * dm, k0 + t * dk
        phi = mode_subspace(mass, stiff, k)
        return phi @ phi.T @ mass

    def projector_np(t):
        mass, stiff = np.asarray(m0 + t * dm), np.asarray(k0 + t * dk)
        chol = np.linalg.cholesky(mass)
        li = np.linalg.inv(chol)
        _, v = np.linalg.eigh(li @ stiff @ li.T)
        phi = li.T @ v[:, :k]
        return phi @ phi.T @ mass

    fwd = np.asarray(jax.jacfwd(projector)(0.0))
    rev = np.asarray(jax.jacrev(projector)(0.0))
    h = 1e-6
    fd = (projector_np(h) - projector_np(-h)) / (2 * h)
    np.testing.assert_allclose(fwd, fd, atol=1e-6 * np.abs(fd).max())
    np.testing.assert_allclose(rev, fwd, atol=1e-12 * np.abs(fwd).max())
