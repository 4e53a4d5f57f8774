"""Motion laws against literature values and textbook formulas (jaxdobby.motion_laws)."""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby.motion_laws import MOTION_LAWS, motion_law

NAMES = sorted(MOTION_LAWS)

# Literature characteristic values, as printed (3 decimals): Rothbart, Cam Design Handbook
# (2004) table 3.5; Norton, Cam Design and Manufacturing Handbook (2009) table 3-2; VDI 2143.
LITERATURE = {
    "modified_sine": (1.760, 5.528),
    "cycloidal": (2.000, 6.283),
    "polynomial_345": (1.875, 5.774),
    "modified_trapezoid": (2.000, 4.888),
}

# Grid containing every segment join (multiples of 1/8) exactly: peaks of modified sine and
# modified trapezoid acceleration sit on joins, the others at 1/2 or 1/2 ± 1/(2√3).
TAU = jnp.linspace(0.0, 1.0, 80_001)


@functools.cache
def _jitted_derivatives(f):
    # One compiled function per law (eager op-by-op autodiff is ~10x slower here).
    return jax.jit(lambda tau: (jax.vmap(jax.grad(f))(tau), jax.vmap(jax.grad(jax.grad(f)))(tau)))


def _derivatives(f, tau):
    """(s'(τ), s''(τ)) elementwise by reverse-mode autodiff."""
    return _jitted_derivatives(f)(tau)


@pytest.mark.parametrize("name", NAMES)
def test_characteristic_values_match_literature(name):
    law = motion_law(name)
    d1, d2 = _derivatives(law.displacement, TAU)
    cv, ca = float(d1.max()), float(jnp.abs(d2).max())
    lit_cv, lit_ca = LITERATURE[name]
    # The literature prints 3 decimals: agreement to half a unit of the last digit (+ 1e-9 for
    # the grid, whose spacing 1.25e-5 misses the 3-4-5 acceleration peak by < 1e-9 relative).
    assert abs(cv - lit_cv) <= 5e-4 + 1e-9
    assert abs(ca - lit_ca) <= 5e-4 + 1e-9
    # The registry's closed forms agree with the autodiff peaks to grid accuracy.
    assert cv == pytest.approx(law.peak_velocity, rel=1e-9)
    assert ca == pytest.approx(law.peak_acceleration, rel=1e-9)


@pytest.mark.parametrize("name", NAMES)
def test_dwell_rise_dwell_boundary_conditions(name):
    f = motion_law(name).displacement
    d1, d2 = _derivatives(f, jnp.array([0.0, 1.0]))
    # Exact by construction (closed forms at 0, symmetry at 1): round-off only.
    np.testing.assert_allclose(f(jnp.array([0.0, 0.5, 1.0])), [0.0, 0.5, 1.0], atol=1e-15)
    np.testing.assert_allclose(d1, 0.0, atol=1e-14)
    np.testing.assert_allclose(d2, 0.0, atol=1e-12)
    # Point symmetry s(τ) + s(1 − τ) = 1 and monotone rise.
    s = f(TAU)
    np.testing.assert_allclose(s + s[::-1], 1.0, atol=1e-15)
    assert bool(jnp.all(jnp.diff(s) >= 0.0))


@pytest.mark.parametrize("name", NAMES)
def test_clipped_outside_unit_interval(name):
    f = motion_law(name).displacement
    tau = jnp.array([-1.0, -1e-3, 1.0 + 1e-3, 3.0])
    d1, d2 = _derivatives(f, tau)
    # Clipping makes the dwells exact: value 0 or 1, derivatives exactly zero.
    np.testing.assert_array_equal(f(tau), [0.0, 0.0, 1.0, 1.0])
    np.testing.assert_array_equal(d1, 0.0)
    np.testing.assert_array_equal(d2, 0.0)


@pytest.mark.parametrize("name", NAMES)
def test_autodiff_continuous_across_joins_and_matches_finite_differences(name):
    f = motion_law(name).displacement
    joins = jnp.array([0.125, 0.375, 0.5, 0.625, 0.875])
    eps = 1e-9
    lo, hi = _derivatives(f, joins - eps), _derivatives(f, joins + eps)
    # Velocity and acceleration are continuous (C²): across the 2e-9 gap they can change only by
    # Ca·2e-9 ≤ 1.3e-8 and |jerk|max·2e-9 ≤ 16π³/(4+π)·2e-9 ≈ 1.4e-7 (modified sine has the
    # largest jerk, 69.5); a jump at a badly joined segment would be O(1).
    np.testing.assert_allclose(lo[0], hi[0], rtol=0, atol=2e-8)
    np.testing.assert_allclose(lo[1], hi[1], rtol=0, atol=2e-7)
    # jax.jvp agrees with central differences everywhere (h = 1e-5: truncation h²/6·|s'''|
    # ≤ 1e-10·300/6 = 5e-9, round-off 1e-16/1e-5 = 1e-11).
    tau = jnp.linspace(0.01, 0.99, 37)
    _, tangent = jax.jvp(f, (tau,), (jnp.ones_like(tau),))
    h = 1e-5
    np.testing.assert_allclose(tangent, (f(tau + h) - f(tau - h)) / (2 * h), atol=1e-8)


def test_laws_against_textbook_formulas():
    tau = jnp.linspace(0.0, 1.0, 1001)
    t = np.asarray(tau)
    # Cycloidal and 3-4-5 as every cam text writes them (e.g. Rothbart 2004, ch. 3).
    np.testing.assert_allclose(
        motion_law("cycloidal").displacement(tau), t - np.sin(2 * np.pi * t) / (2 * np.pi),
        atol=1e-15,
    )
    np.testing.assert_allclose(
        motion_law("polynomial_345").displacement(tau), 10 * t**3 - 15 * t**4 + 6 * t**5,
        atol=1e-15,
    )
    # Modified sine and modified trapezoid with the 8-digit coefficients published by Saltire
    # Software ("Different cam functions", saltire.com/CamDesign), segment by segment (the module
    # instead builds the second half by symmetry): agreement to the coefficients' precision.
    np.testing.assert_allclose(
        motion_law("modified_sine").displacement(tau),
        np.select(
            [t < 0.125, t < 0.875],
            [
                0.43990085 * t - 0.0350062 * np.sin(4 * np.pi * t),
                0.28004957 + 0.43990085 * t - 0.31505577 * np.cos(4 * np.pi * t / 3 - np.pi / 6),
            ],
            0.56009915 + 0.43990085 * t - 0.0350062 * np.sin(4 * np.pi * t - 2 * np.pi),
        ),
        rtol=0,
        atol=3e-8,
    )
    a, b = 0.38898448, 0.0309544
    trapezoid = motion_law("modified_trapezoid").displacement(tau)
    segments = np.select(
        [t < 0.125, t < 0.375, t < 0.625, t < 0.875],
        [
            a * t - b * np.sin(4 * np.pi * t),
            2.44406184 * t**2 - 0.22203097 * t + 0.00723407,
            1.6110154 * t - b * np.sin(4 * np.pi * t - np.pi) - 0.3055077,
            -2.44406184 * t**2 + 4.6660917 * t - 1.2292648,
        ],
        0.6110154 + a * t + b * np.sin(4 * np.pi * t - 3 * np.pi),
    )
    late = t >= 0.625
    np.testing.assert_allclose(trapezoid[~late], segments[~late], rtol=0, atol=5e-8)
    # In the last two segments the published constants are off in the 7th digit: mirroring the
    # first two, 1 − s(1 − τ), gives 4.66609271 and −1.22926494 (published 4.6660917,
    # −1.2292648) and 1 − 0.38898448 = 0.61101552 (published 0.6110154) — up to 7.5e-7 over
    # the segment. Compare at 1e-6 there, and against the mirrored first-half coefficients at
    # their own precision.
    np.testing.assert_allclose(trapezoid[late], segments[late], rtol=0, atol=1e-6)
    u = 1.0 - t
    mirrored = 1.0 - np.where(
        u < 0.125,
        a * u - b * np.sin(4 * np.pi * u),
        2.44406184 * u**2 - 0.22203097 * u + 0.00723407,
    )
    np.testing.assert_allclose(trapezoid[late], mirrored[late], rtol=0, atol=5e-8)

def test_unknown_law_names_the_choices():
    with pytest.raises(ValueError, match="modified_sine"):
        motion_law("harmonic")
    assert math.isclose(MOTION_LAWS["cycloidal"].peak_acceleration, 2 * math.pi)
