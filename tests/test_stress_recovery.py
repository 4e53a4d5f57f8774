"""Edge stresses of the beam recovery (jaxdobby.stress.recovery) against closed forms.

References: Navier's σ = N/A − M·y/I (Timoshenko & Gere, *Mechanics of Materials*, §5.4, §11.2);
the quarter-circle cantilever's section forces by statics (the moment Castigliano's theorem
integrates, Roark 8th ed. Table 9.2); the rotating bar's centrifugal axial stress
σ(x) = ρω²(L² − x²)/2 (Timoshenko & Goodier, *Theory of Elasticity*, §134, the bar limit).
Hermite-cubic elements with consistent loads are nodally exact for straight beams under point
loads, so there the tolerance is round-off (1e-9 relative); where the element's constant axial
strain or chord geometry approximates a smooth field the discretisation error is stated and its
rate checked.
"""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby.beam import Beam
from jaxdobby.centreline import CentreLine
from jaxdobby.loads import point_load, rigid_motion_load
from jaxdobby.stress.recovery import edge_points, stress_operator
from jaxdobby.supports import Supports, static_deflection

E, RHO, T, D, P = 2.07e11, 7800.0, 0.006, 0.04, 150.0
CLAMP = Supports(clamped=(0,))


def beam_on(line, n, depth=D, depth_at=None):
    return Beam.uniform_mesh(line, n, thickness=T, depth=depth, youngs_modulus=E, density=RHO,
                             depth_arc_lengths=depth_at)


@pytest.mark.parametrize("angle", [0.0, 0.7])
def test_cantilever_tip_force_is_m_c_over_i(angle):
    """σ = ∓M·(d/2)/I with M = P(L − s) at every recovery point (nodally exact: 1e-9); the beam
    turned by 0.7 rad checks the element rotation; the load's left normal gives M > 0, so the
    left edge is in compression."""
    length = 0.3
    line = CentreLine.from_segments([("line", length)], start_angle=angle)
    beam = beam_on(line, 6)
    normal = np.array([-np.sin(angle), np.cos(angle)])
    u = static_deflection(beam, CLAMP, point_load(beam, length, force=P * normal))
    op = stress_operator(beam, 4)
    sigma = np.asarray(op.stresses(u))
    bending = P * (length - np.asarray(op.arc_lengths)) * (D / 2) / (T * D**3 / 12)
    scale = bending.max()
    np.testing.assert_allclose(sigma[..., 0], -bending, atol=1e-9 * scale)
    np.testing.assert_allclose(sigma[..., 1], bending, atol=1e-9 * scale)


def test_tapered_cantilever_uses_the_local_depth():
    """A depth tapering 40 → 20 mm: σ(s) = 6P(L − s)/(t d(s)²) exactly at every point (the
    element's section forces are exact, the stress is taken across the actual section). Using
    the element's mid depth instead would be off by up to 30 % here (checked, so the test can
    fail)."""
    length = 0.3
    line = CentreLine.from_segments([("line", length)])
    beam = beam_on(line, 6, depth=[0.04, 0.02], depth_at=[0.0, length])
    u = static_deflection(beam, CLAMP, point_load(beam, length, force=(0.0, P)))
    op = stress_operator(beam, 5)
    s = np.asarray(op.arc_lengths)
    d = 0.04 - 0.02 * s / length
    exact = 6 * P * (length - s) / (T * d**2)
    sigma = np.asarray(op.stresses(u))
    np.testing.assert_allclose(sigma[..., 1], exact, atol=1e-9 * exact.max())
    d_mid = np.repeat(0.04 - 0.02 * s.mean(axis=1, keepdims=True) / length, s.shape[1], axis=1)
    naive = 6 * P * (length - s) / (T * d_mid**2)
    assert np.max(np.abs(naive - exact) / exact.max()) > 0.05


def test_quarter_circle_section_forces():
    """Quarter circle R = 0.2 m clamped at (R, 0) heading +y, tip force (0, −P) at (0, R): by
    statics M(φ) = P·R·cos φ (counter-clockwise, the arc curls: left = inner edge compressed)
    and N(φ) = −P cos φ. The nodes lie on the arc, so the moment there is exact (1e-9); the
    element's constant axial force is N at the element's mid angle, exact there (1e-9); the
    stress at the ends of an element differs by the axial term over half an element, O(h):
    halving h halves the error (ratio 1.8…2.2)."""
    r = 0.2
    line = CentreLine.from_segments([("arc", r, np.pi / 2)], start=(r, 0.0), start_angle=np.pi / 2)
    a, i_sec = T * D, T * D**3 / 12
    errors = []
    for n in (8, 16):
        beam = beam_on(line, n)
        u = static_deflection(beam, CLAMP, point_load(beam, r * np.pi / 2, force=(0.0, -P)))
        op = stress_operator(beam, 3)
        sigma = np.asarray(op.stresses(u))
        phi = np.asarray(op.arc_lengths) / r
        moment = (sigma[..., 1] - sigma[..., 0]) / 2 * i_sec / (D / 2)
        axial = (sigma[..., 1] + sigma[..., 0]) / 2 * a
        np.testing.assert_allclose(moment[:, [0, -1]], P * r * np.cos(phi[:, [0, -1]]),
                                   atol=1e-9 * P * r)
        np.testing.assert_allclose(axial[:, 1], -P * np.cos(phi[:, 1]), atol=1e-9 * P)
        exact_left = -P * np.cos(phi) / a - P * r * np.cos(phi) * (D / 2) / i_sec
        errors.append(np.max(np.abs(sigma[:, [0, -1], 0] - exact_left[:, [0, -1]])))
    assert 1.8 < errors[0] / errors[1] < 2.2


def test_rotating_bar_centrifugal_stress():
    """A bar clamped at the hub spun at ω (centrifugal load alone): σ(x) = ρω²(L² − x²)/2. The
    linear axial interpolation gives nodally exact displacements, so each element's (constant)
    stress is the exact one averaged over it, ρω²(L² − (a² + ab + b²)/3)/2, to 1e-9; at the
    element's middle that is ρω²h²/24 below the closed form (checked to 1e-9 too)."""
    length, omega, n = 0.5, 300.0, 8
    beam = beam_on(CentreLine.from_segments([("line", length)]), n)
    u = static_deflection(beam, CLAMP, rigid_motion_load(beam, omega, 0.0))
    op = stress_operator(beam, 3)
    sigma = np.asarray(op.stresses(u))
    h = length / n
    a = np.arange(n) * h
    b = a + h
    averaged = RHO * omega**2 * (length**2 - (a**2 + a * b + b**2) / 3) / 2
    scale = RHO * omega**2 * length**2 / 2
    for edge in (0, 1):
        for point in range(3):
            np.testing.assert_allclose(sigma[:, point, edge], averaged, atol=1e-9 * scale)
    mid = (a + b) / 2
    closed = RHO * omega**2 * (length**2 - mid**2) / 2
    np.testing.assert_allclose(sigma[:, 1, 0] - closed, -RHO * omega**2 * h**2 / 24,
                               atol=1e-9 * scale)


def test_edge_points_lie_half_a_depth_off_the_centre_line():
    line = CentreLine.from_segments([("line", 0.1), ("arc", 0.4, -0.24), ("line", 0.02)])
    beam = beam_on(line, 10)
    op = stress_operator(beam, 3)
    pts = np.asarray(edge_points(beam, op))
    np.testing.assert_allclose(np.linalg.norm(pts[..., 0, :] - pts[..., 1, :], axis=-1), D,
                               rtol=1e-12)
    # the left edge of a line heading +x is above it
    assert np.all(pts[0, :, 0, 1] > 0) and np.all(pts[0, :, 1, 1] < 0)
