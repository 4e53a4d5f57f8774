"""Independent reference: flapwise frequencies of a rotating uniform cantilever by shooting.

Nondimensional rotating Euler–Bernoulli beam (hub radius 0), ξ = x/L ∈ [0, 1]:

    w'''' − (T w')' = ω̄² w,   T(ξ) = (λ²/2)(1 − ξ²),

λ = Ω √(ρA L⁴/EI), ω̄ = ω √(ρA L⁴/EI); clamped at ξ = 0 (w = w' = 0), free at ξ = 1
(w'' = 0, w''' − T w' = 0, and T(1) = 0). (Hodges & Rutkowski, AIAA J. 19(11) 1981;
Wright, Smith, Thresher & Wang, J. Appl. Mech. 49 1982.)

The two solutions started with (w'', w''') = (1, 0) and (0, 1) at the root are integrated to
the tip with a tight-tolerance explicit Runge–Kutta (DOP853); ω̄ is a root of the 2×2
determinant of their tip boundary values. The in-plane (chordwise) frequencies of an
inextensible beam follow as ω̄_chord² = ω̄_flap² − λ² (the rotating frame's −Ω²v term).
"""

from __future__ import annotations

import numpy as np
import scipy.integrate
import scipy.optimize


def _tip_determinant(wbar, lam, rtol=1e-12):
    """det of the tip boundary conditions for trial frequency ω̄ (scaled to stay O(1))."""

    def rhs(xi, y):
        T = 0.5 * lam**2 * (1 - xi**2)
        dT = -(lam**2) * xi
        w, w1, w2, w3 = y.reshape(4, 2)
        w4 = wbar**2 * w + T * w2 + dT * w1
        return np.concatenate([w1, w2, w3, w4])

    y0 = np.array([0, 0, 0, 0, 1, 0, 0, 1], float)  # columns: the two starting solutions
    sol = scipy.integrate.solve_ivp(rhs, (0, 1), y0, method="DOP853", rtol=rtol,
                                    atol=rtol * 1e-2)
    w, w1, w2, w3 = sol.y[:, -1].reshape(4, 2)
    bc = np.array([w2, w3])  # T(1) = 0, so the shear condition is w''' = 0
    return np.linalg.det(bc) / np.exp(2 * np.sqrt(max(wbar, 1.0)))


def flapwise_frequencies(lam, n_modes=3, wbar_max=None, n_scan=150):
    """First ``n_modes`` nondimensional flapwise frequencies ω̄ of the rotating cantilever.

    Scans the determinant on a grid in ω̄ (at a looser tolerance: only its sign is used) for
    sign changes and refines each with Brent's method at rtol 1e-12.
    """
    if wbar_max is None:
        wbar_max = 1.3 * ((2 * n_modes - 1) * np.pi / 2) ** 2 + 2 * lam
    grid = np.linspace(0.5, wbar_max, n_scan)
    d = np.array([_tip_determinant(g, lam, 1e-8) for g in grid])
    roots = []
    for a, b, da, db in zip(grid[:-1], grid[1:], d[:-1], d[1:]):
        if da * db < 0:
            roots.append(scipy.optimize.brentq(_tip_determinant, a, b, args=(lam,), xtol=1e-12))
        if len(roots) == n_modes:
            break
    if len(roots) < n_modes:
        raise RuntimeError(f"found only {len(roots)} roots below {wbar_max}")
    return np.array(roots)


def chordwise_frequencies_inextensible(lam, n_modes=3):
    """ω̄_chord = √(ω̄_flap² − λ²) (inextensible beam, no Coriolis coupling to axial motion)."""
    return np.sqrt(flapwise_frequencies(lam, n_modes) ** 2 - lam**2)


def _series_determinant(wbar, lam, n_terms=300):
    """Tip-condition determinant from the Frobenius power series w = Σ aₖ ξᵏ (Wright et al.).

    Recurrence (k+4)(k+3)(k+2)(k+1) aₖ₊₄ = (λ²/2)[(k+2)(k+1) aₖ₊₂ − k(k+1) aₖ] + ω̄² aₖ,
    a₀ = a₁ = 0 (clamped); (a₂, a₃) = (1, 0) and (0, 1). The terms peak near e^√ω̄ ≈ 4e3 for
    ω̄ ≈ 70, so float64 keeps ~12 digits.
    """
    k = np.arange(n_terms + 4)
    cols = []
    for a2, a3 in ((1.0, 0.0), (0.0, 1.0)):
        a = np.zeros(n_terms + 4)
        a[2], a[3] = a2, a3
        for j in range(n_terms):
            a[j + 4] = (0.5 * lam**2 * ((j + 2) * (j + 1) * a[j + 2] - j * (j + 1) * a[j])
                        + wbar**2 * a[j]) / ((j + 4) * (j + 3) * (j + 2) * (j + 1))
        cols.append(((k * (k - 1) * a).sum(), (k * (k - 1) * (k - 2) * a).sum()))
    return cols[0][0] * cols[1][1] - cols[0][1] * cols[1][0]


def flapwise_frequencies_series(lam, brackets):
    """Flapwise ω̄ by the power series, one root of the determinant in each (lo, hi) bracket."""
    return np.array([scipy.optimize.brentq(_series_determinant, lo, hi, args=(lam,), xtol=1e-13)
                     for lo, hi in brackets])
