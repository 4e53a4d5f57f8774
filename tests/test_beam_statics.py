"""Static verification of the planar frame element against Euler–Bernoulli closed forms.

References: Timoshenko & Gere, *Mechanics of Materials*, Appendix G (cantilever deflections);
Roark's *Formulas for Stress and Strain*, 8th ed., Table 9.2 (curved beams) / Castigliano's
theorem for the quarter circle. Hermite-cubic Euler–Bernoulli elements with consistent loads are
*nodally exact* for straight beams under these loads, so those tolerances are round-off
(1e-9 relative), not discretisation error.
"""

import jax.numpy as jnp
import numpy as np

from jaxdobby.beam import Beam
from jaxdobby.centreline import CentreLine
from jaxdobby.loads import distributed_load, gravity_load, point_load
from jaxdobby.supports import Supports, static_deflection

L, E, T, D = 1.2, 2.07e11, 0.006, 0.04
A, I = T * D, T * D**3 / 12
CLAMP = Supports(clamped=(0,))


def cantilever(n=8, angle=0.0):
    line = CentreLine.from_segments([("line", L)], start_angle=angle)
    return Beam.uniform_mesh(line, n, thickness=T, depth=D, youngs_modulus=E, density=7800.0)


def tip(u):
    return np.asarray(u[-3:])


def test_tip_force():
    p = 150.0
    u = tip(static_deflection(cantilever(), CLAMP, point_load(cantilever(), L, force=(0.0, p))))
    np.testing.assert_allclose(u[1], p * L**3 / (3 * E * I), rtol=1e-9)
    np.testing.assert_allclose(u[2], p * L**2 / (2 * E * I), rtol=1e-9)


def test_tip_moment():
    m = 40.0
    u = tip(static_deflection(cantilever(), CLAMP, point_load(cantilever(), L, moment=m)))
    np.testing.assert_allclose(u[1], m * L**2 / (2 * E * I), rtol=1e-9)
    np.testing.assert_allclose(u[2], m * L / (E * I), rtol=1e-9)


def test_axial_force_on_rotated_beam():
    # The same beam turned by 30°: the axial force along the beam axis stretches it by PL/EA.
    phi = np.radians(30.0)
    b = cantilever(angle=phi)
    p = 5e4
    u = tip(static_deflection(b, CLAMP, point_load(b, L, force=(p * np.cos(phi), p * np.sin(phi)))))
    np.testing.assert_allclose(u[:2], p * L / (E * A) * np.array([np.cos(phi), np.sin(phi)]),
                               rtol=1e-9)
    # No bending: the rotation is round-off against the strain scale PL/EA / L.
    assert abs(u[2]) < 1e-9 * p / (E * A)


def test_uniform_load():
    w = 300.0
    b = cantilever()
    u = tip(static_deflection(b, CLAMP, distributed_load(b, lambda s: jnp.array([0.0, w]))))
    np.testing.assert_allclose(u[1], w * L**4 / (8 * E * I), rtol=1e-9)
    np.testing.assert_allclose(u[2], w * L**3 / (6 * E * I), rtol=1e-9)


def test_linearly_varying_load():
    # w(x) = w0 x/L, rising towards the tip: tip deflection 11 w0 L^4/(120 EI), slope w0 L^3/(8 EI).
    w0 = 300.0
    b = cantilever()
    u = tip(static_deflection(b, CLAMP, distributed_load(b, lambda s: jnp.array([0.0, w0 * s / L]))))
    np.testing.assert_allclose(u[1], 11 * w0 * L**4 / (120 * E * I), rtol=1e-9)
    np.testing.assert_allclose(u[2], w0 * L**3 / (8 * E * I), rtol=1e-9)


def test_gravity_equals_uniform_load():
    # Gravity on the distributed mass is a uniform load of rho*A*g per metre.
    b = cantilever()
    g = 9.81
    u = tip(static_deflection(b, CLAMP, gravity_load(b, (0.0, -g))))
    np.testing.assert_allclose(u[1], -7800.0 * A * g * L**4 / (8 * E * I), rtol=1e-9)


def test_point_between_nodes_is_exact_at_nodes():
    # A force at a point inside an element (a = 0.37 L) of a 5-element mesh: the nodal values stay
    # exact, v(x) = P x^2 (3a - x)/(6EI) for x <= a and P a^2 (3x - a)/(6EI) beyond, while the
    # interpolation inside the loaded element is not (the exact curve has a jump in v''').
    b = cantilever(n=5)
    a, p = 0.37 * L, 120.0
    u = static_deflection(b, CLAMP, point_load(b, a, force=(0.0, p)))
    x = np.asarray(b.node_positions[:, 0])
    exact = np.where(x <= a, p * x**2 * (3 * a - x), p * a**2 * (3 * x - a)) / (6 * E * I)
    np.testing.assert_allclose(np.asarray(u[1::3]), exact, rtol=1e-9, atol=1e-18)
    # Inside the element the cubic interpolation is within 1e-3 of the exact P a^3/(3EI).
    np.testing.assert_allclose((b.point_rows(a) @ u)[1], p * a**3 / (3 * E * I), rtol=1e-3)


def quarter_circle(n, radius=0.3):
    arc = CentreLine.from_segments([("arc", radius, np.pi / 2)])
    return Beam.uniform_mesh(arc, n, thickness=T, depth=D, youngs_modulus=E, density=7800.0)


def quarter_circle_compliance(n, radius=0.3, p=100.0):
    """Tip displacement of a quarter circle clamped at s = 0 under a radial tip load.

    The arc starts at the origin heading +x and turns to heading +y: its centre is (0, R) and the
    tip (R, R); a radial (−x, towards the centre) load P there.
    """
    b = quarter_circle(n, radius)
    u = static_deflection(b, CLAMP, point_load(b, b.centreline.total_length, force=(-p, 0.0)))
    return tip(u)


def castigliano(radius=0.3, p=100.0):
    """Castigliano for the quarter circle, tip load P towards the centre, bending + extension.

    With ϕ measured from the tip, M = P R sinϕ and N = −P cosϕ (compression along the tangent):
    δ_load = πPR³/(4EI) + πPR/(4EA) along the load; the other component, along +y (away from
    the clamp's tangent), δ_perp = PR³/(2EI) − PR/(2EA) (Roark Table 9.2 with the axial term).
    """
    along = np.pi * p * radius**3 / (4 * E * I) + np.pi * p * radius / (4 * E * A)
    perp = p * radius**3 / (2 * E * I) - p * radius / (2 * E * A)
    return along, perp


def test_quarter_circle_castigliano_converges_as_h2():
    along, perp = castigliano()
    errors = []
    for n in (8, 16, 32, 64):
        u = quarter_circle_compliance(n)
        # Load along −x: the displacement along the load is −u_x; the tip also moves +y.
        errors.append(abs(-u[0] - along) / along)
        np.testing.assert_allclose(u[1], perp, rtol=2.0 / n**2)
    rate = -np.polyfit(np.log([8, 16, 32, 64]), np.log(errors), 1)[0]
    # Chords replacing the arc make the error O(h^2): the fitted order must be 2 within 0.1.
    assert abs(rate - 2.0) < 0.1, (errors, rate)
    assert errors[-1] < 2e-4
