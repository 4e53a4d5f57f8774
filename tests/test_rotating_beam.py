"""Small vibrations of a uniform cantilever spinning at constant rate in its own plane.

Reference: the flapwise frequencies of the rotating uniform cantilever (Wright, Smith, Thresher &
Wang, J. Appl. Mech. 49, 1982; Hodges & Rutkowski, AIAA J. 19(11), 1981), in the
nondimensional form λ = Ω√(ρA L⁴/EI), ω̄ = ω√(ρA L⁴/EI). For an inextensible beam the in-plane
(chordwise) frequencies follow from them as ω̄² = ω̄_flap² − λ²: the centrifugal tension
stiffens both, and in the plane of rotation the centrifugal softening −Ω² subtracts. Only with
geometric stiffening does the model reproduce this; without it the first mode goes unstable
once λ > 3.516.
"""

import jax
import numpy as np
import pytest

from jaxdobby.beam import Beam
from jaxdobby.centreline import CentreLine
from jaxdobby.flexible_body import flexible_body
from jaxdobby.supports import Supports

FLAP = {
    0.0: [3.5160, 22.0345, 61.6972],
    6.0: [7.3604, 26.8091, 66.6840],
    12.0: [13.1702, 37.6031],
}


def linearised_frequencies(body, rate, stiffening=1.0):
    """Frequencies of M q̈ + 2ΩG q̇ + (K − Ω²M_t + sΩ²K_ω) q = 0 (state-space eigenvalues)."""
    k = body.n_modes
    stiff = np.asarray(body.stiffness - rate**2 * body.translational_mass
                       + stiffening * rate**2 * body.stiffening["centrifugal"])
    gyro = np.asarray(2.0 * rate * body.gyroscopic)
    m_inv = np.linalg.inv(np.asarray(body.mass))
    a = np.block([[np.zeros((k, k)), np.eye(k)], [-m_inv @ stiff, -m_inv @ gyro]])
    ev = np.linalg.eigvals(a)
    return ev


@pytest.fixture(scope="module")
def slender_body():
    # EI = 1e-6, rhoA = 1, L = 1: time scale sqrt(rhoA L^4/EI) = 1e3; EA/EI = 1.2e7, so the
    # axial modes (Coriolis coupling) sit ~1500x above the first bending mode.
    line = CentreLine.from_segments([("line", 1.0)])
    beam = Beam.uniform_mesh(line, 40, thickness=1e-3, depth=1e-3, youngs_modulus=1.2e7,
                             density=1e6)
    return jax.jit(lambda b: flexible_body(b, Supports(clamped=(0,)), 8))(beam)


@pytest.mark.parametrize("lam", sorted(FLAP))
def test_in_plane_frequencies_with_stiffening(slender_body, lam):
    scale = 1e3
    ev = linearised_frequencies(slender_body, lam / scale)
    assert np.max(ev.real) < 1e-9 * np.max(np.abs(ev.imag))  # neutrally stable
    omega = np.sort(np.abs(ev.imag))[::2] * scale
    expected = np.sqrt(np.array(FLAP[lam]) ** 2 - lam**2)
    # 40 elements with the element-averaged axial force: O(h^2) error ~3e-4 at lambda = 12
    # (measured: 1.1e-4 / 9.5e-5 / 4.6e-5 at lambda = 6, halving h quarters it) -> 5e-4.
    np.testing.assert_allclose(omega[: len(expected)], expected, rtol=5e-4)


def test_without_stiffening_the_spinning_beam_is_unstable(slender_body):
    # lambda = 6 > 3.516: K - Omega^2 M_t has a negative eigenvalue without the geometric term.
    ev = linearised_frequencies(slender_body, 6.0 / 1e3, stiffening=0.0)
    assert np.max(ev.real) > 1e-3 * 1e-3  # a growth rate of order 1 in nondimensional time
