"""Natural frequencies of straight and curved beams against closed forms and published tables.

References:
* clamped-free Euler–Bernoulli beam, roots of 1 + cos βL cosh βL = 0 (Blevins, *Formulas for
  Natural Frequency and Mode Shape*, Table 8-1);
* free circular ring, inextensional in-plane modes ω_n = n(n²−1)/√(n²+1) √(EI/(ρA R⁴))
  (Love, *Mathematical Theory of Elasticity*, §293);
* clamped-free and clamped-clamped 90° circular arcs at slenderness S/r = 100, converged
  λ = ωR²√(ρA/EI) (Chidamparam & Leissa, Appl. Mech. Rev. 46(9), 1993, and the FE/DQ tables
  collected there).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby.beam import Beam
from jaxdobby.centreline import CentreLine
from jaxdobby.modal import modal_basis
from jaxdobby.supports import Supports

BETA_L = np.array([1.875104068711961, 4.694091132974175, 7.854757438237613, 10.995540734875467,
                   14.137168391046471, 17.278759532088237, 20.420352251041251,
                   23.561944901923448])
# Relative frequency error of a 10-element consistent-mass cantilever (the figures).
EXPECTED_ERROR_10 = np.array([8.6e-7, 3.3e-5, 2.5e-4, 9.5e-4, 2.5e-3, 5.4e-3, 1.0e-2, 1.6e-2])


def slender_cantilever(n):
    # EI = rhoA = 1/12e6 ... scaled so that sqrt(EI/(rhoA L^4)) = d/sqrt(12); axial modes far above.
    line = CentreLine.from_segments([("line", 1.0)])
    return Beam.uniform_mesh(line, n, thickness=1e-3, depth=1e-3, youngs_modulus=1.0, density=1.0)


def bending_errors(beam, lumped=False):
    """Relative errors of the first 8 bending frequencies (axial modes filtered by energy)."""
    n = beam.n_nodes - 1
    m = beam.mass_matrix()
    if lumped:
        m = jnp.diag(jnp.where(jnp.arange(m.shape[0]) % 3 == 2, 1e-12, jnp.sum(m, axis=1)))
    basis = modal_basis(beam, Supports(clamped=(0,)), 12, mass=m)
    phi = np.asarray(basis.shapes)
    axial = np.zeros(3 * (n + 1), bool)
    axial[0::3] = True
    axial_energy = np.einsum("ik,ij,jk->k", phi * axial[:, None], np.asarray(m),
                             phi * axial[:, None])
    omega = np.asarray(basis.frequencies)[axial_energy < 0.5][:8]
    exact = BETA_L**2 * np.sqrt(1e-6 / 12.0)
    return (omega - exact) / exact


def test_cantilever_consistent_mass_errors():
    err10 = bending_errors(slender_cantilever(10))
    # Consistent mass gives upper bounds (Rayleigh-Ritz); the errors must match the reference
    # figures to their two significant digits (rtol 6 % covers their rounding).
    assert np.all(err10 > 0)
    np.testing.assert_allclose(err10, EXPECTED_ERROR_10, rtol=0.06)
    # Halving h divides the error by ~16 (O(h^4) for frequencies of cubic elements); the higher
    # modes are still pre-asymptotic at 10 elements, hence the band 12...17. The first mode's
    # rate is taken from 5 to 10 elements: its error at 20 (5.8e-8) is within a few times the
    # round-off floor of its frequency (axial over bending stiffness ~1e7 in this 1 mm beam: the
    # error at 20 elements moved 5.8e-8 -> 4.5e-8, its ratio 14.8 -> 19.1, with XLA's LLVM
    # optimisation level alone), whereas 5 -> 10 gives 15.81 at either level.
    ratio = err10 / bending_errors(slender_cantilever(20))
    ratio[0] = bending_errors(slender_cantilever(5))[0] / err10[0]
    assert np.all((ratio > 12) & (ratio < 17)), ratio


def test_lumped_mass_would_fail():
    # The same check with a row-sum lumped mass: the errors are negative and far larger, which is
    # what the consistent-mass test above is able to detect.
    err = bending_errors(slender_cantilever(10), lumped=True)
    assert np.all(err[1:] < 0) and abs(err[3]) > 10 * EXPECTED_ERROR_10[3]


def free_ring(n_elements, radius=1.0, depth=0.01):
    ring = CentreLine.from_segments([("arc", radius, 2 * np.pi)])
    s = jnp.arange(n_elements) * ring.total_length / n_elements
    return Beam(ring, s, thickness=0.01, depth=depth, youngs_modulus=2e11, density=7800.0,
                elements=[(i, (i + 1) % n_elements) for i in range(n_elements)])


def ring_frequencies(n_elements):
    beam = free_ring(n_elements)
    basis = modal_basis(beam, Supports(), 13)
    a, i = 0.01 * 0.01, 0.01 * 0.01**3 / 12
    return np.asarray(basis.frequencies) / np.sqrt(2e11 * i / (7800.0 * a))


def test_free_ring_love():
    love = np.array([n * (n * n - 1) / np.sqrt(n * n + 1) for n in range(2, 7)])
    errors = []
    for n_el in (32, 64):
        w = ring_frequencies(n_el)
        # Three rigid-body modes: zero up to the round-off of the eigen-solve (1e-3 of ω_2).
        assert np.all(w[:3] < 1e-3 * w[3])
        pairs = w[3:].reshape(5, 2)
        # Modes come in pairs (the ring is symmetric): equal to 1e-8.
        np.testing.assert_allclose(pairs[:, 0], pairs[:, 1], rtol=1e-8)
        errors.append((pairs[:, 0] - love) / love)
    errors = np.array(errors)
    # Chords replace the arc: error O(h^2), so 4x smaller for 2x the elements for n = 2, 3; the
    # higher modes also carry the (mesh-independent) extensional correction, which makes the
    # ratio larger than 4. At 64 elements every pair n = 2…6 is within 1.5e-3 of Love.
    assert np.all(np.abs(errors[1]) < 1.5e-3)
    np.testing.assert_allclose(errors[0, :2] / errors[1, :2], 4.0, rtol=0.05)
    assert np.all(errors[0] / errors[1] > 3.9)


def arc_lambdas(clamped_both, n_elements):
    # Square section t = d = 1: r = 1/sqrt(12); S/r = 100 fixes R = S/(pi/2).
    r = 1.0 / np.sqrt(12.0)
    radius = 100 * r / (np.pi / 2)
    arc = CentreLine.from_segments([("arc", radius, np.pi / 2)])
    beam = Beam.uniform_mesh(arc, n_elements, thickness=1.0, depth=1.0, youngs_modulus=1.0,
                             density=1.0)
    supports = Supports(clamped=(0, n_elements) if clamped_both else (0,))
    w = np.asarray(modal_basis(beam, supports, 3).frequencies)
    return w * radius**2 * np.sqrt(12.0)


@pytest.mark.parametrize("clamped_both, reference", [
    (False, [1.4981, 7.213, 22.732]),
    (True, [22.574, 39.390, 63.271]),
])
def test_circular_arc_frequencies(clamped_both, reference):
    l32, l64 = arc_lambdas(clamped_both, 32), arc_lambdas(clamped_both, 64)
    # Richardson extrapolation of the O(h^2) chord error, then agreement to the reference's last
    # printed digit (5e-5 relative covers rounding of 4-5 significant digits).
    extrapolated = (4 * l64 - l32) / 3
    np.testing.assert_allclose(extrapolated, reference, rtol=5e-5)
    # The unextrapolated 64-element values are within 2e-4 already.
    np.testing.assert_allclose(l64, reference, rtol=2e-4)


def supported_arm(thickness, depth):
    """A curved arm pinned at its pivot, held by a spring at 80 mm, with a 0.3 kg end mass."""
    arm = CentreLine.from_segments([("line", 0.105), ("arc", 0.4, -0.24), ("line", 0.025)])
    s = jnp.array([0.0, 0.0267, 0.0533, 0.08, 0.105, 0.124, 0.143, 0.162, 0.182, 0.201, 0.226])
    masses = jnp.zeros(11).at[9].set(0.3)
    beam = Beam(arm, s, thickness=thickness, depth=depth, youngs_modulus=2.07e11,
                density=7800.0, point_masses=masses)
    supports = Supports(pinned=(0,), spring_nodes=(3,), spring_directions=[[0.6, 0.8]],
                        spring_stiffness=[1.38e8])
    return beam, supports


def test_frequency_gradients_match_finite_differences():
    def freqs(t, d):
        beam, supports = supported_arm(t, d)
        return modal_basis(beam, supports, 4).frequencies

    def participation(t, d):
        # A sign-invariant modal quantity: (modal mass of a unit body-x acceleration)^2.
        beam, supports = supported_arm(t, d)
        phi = modal_basis(beam, supports, 4).shapes
        f = phi.T @ beam.mass_matrix() @ beam.rigid_fields()["x"]
        return f**2

    t0, d0 = 0.006, 0.04
    for fn in (freqs, participation):
        jac_t, jac_d = jax.jacfwd(fn, argnums=(0, 1))(t0, d0)
        h_t, h_d = 1e-4 * t0, 1e-4 * d0
        fd_t = (fn(t0 + h_t, d0) - fn(t0 - h_t, d0)) / (2 * h_t)
        fd_d = (fn(t0, d0 + h_d) - fn(t0, d0 - h_d)) / (2 * h_d)
        # Central differences at h = 1e-4 relative: truncation ~h^2 = 1e-8 and round-off of the
        # eigen-solve ~1e-13/h = 1e-9 relative (smaller h is dominated by round-off: measured),
        # so agreement to 1e-6 relative of the largest component is a safe claim.
        for ad, fd in ((jac_t, fd_t), (jac_d, fd_d)):
            np.testing.assert_allclose(ad, fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd)))
    # Thickness matters here only through the end mass and the spring (uniform t scales M and K
    # together): check the gradient is not trivially zero.
    assert np.all(np.abs(jax.jacfwd(freqs)(t0, d0)) > 1.0)


def test_examples_module():
    # The documented examples are claims too: the tip deflection equals F L^3/(3 E I) exactly,
    # and the curved arm's modes are positive and ascending.
    from jaxdobby import examples

    i = 0.006 * 0.04**3 / 12
    np.testing.assert_allclose(examples.cantilever_tip_deflection(100.0),
                               100.0 / (3 * 2.07e11 * i), rtol=1e-9)
    f = np.asarray(examples.curved_arm_modes(4))
    assert np.all(np.diff(f) > 0) and 500.0 < f[0] < 2000.0
