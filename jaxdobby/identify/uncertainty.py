"""Estimates, standard errors and correlations from the Gauss–Newton covariance, and the
identifiability warnings (see :mod:`jaxdobby.identify.fit` for the formulas)."""

from __future__ import annotations

import numpy as np

from ..parameters import Setup, apply
from .measurement import Measurement
from .model import MM, Parameterisation

CONDITION_LIMIT = 1e12
"""JᵀJ (columns scaled to unit norm) more ill-conditioned than this is not inverted: the
standard errors are infinite and every parameter in the null direction is flagged."""


def covariance(jac: np.ndarray, r: np.ndarray, n: int) -> np.ndarray:
    """C = s²(JᵀJ)⁻¹, s² = ‖r‖²/(n − P), for J (rows: residuals, padded rows zero) with P
    columns and ``n`` real residuals; the columns are scaled to unit norm before the inverse
    (Jacobi preconditioning) and a (near-)singular JᵀJ gives infinite variances."""
    P = jac.shape[1]
    s2 = float(r @ r) / max(n - P, 1)
    norms = np.linalg.norm(jac, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    a = (jac / safe).T @ (jac / safe)
    w, v = np.linalg.eigh(a)
    if w[0] <= w[-1] / CONDITION_LIMIT or np.any(norms == 0):
        cov = np.full((P, P), np.inf)
        # the finite part: pseudo-inverse on the well-determined eigen-directions
        keep = w > w[-1] / CONDITION_LIMIT
        pinv = (v[:, keep] / w[keep]) @ v[:, keep].T
        null = np.abs(v[:, ~keep]).max(axis=1) > 1e-3 if np.any(~keep) else np.zeros(P, bool)
        null |= norms == 0
        good = ~null
        cov[np.ix_(good, good)] = pinv[np.ix_(good, good)]
    else:
        cov = (v / w) @ v.T
    return s2 * cov / np.outer(safe, safe)


def correlation(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance (NaN where a variance is infinite)."""
    sd = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr[~np.isfinite(corr)] = np.nan
    np.fill_diagonal(corr, 1.0)
    return corr


def summarise(setup: Setup, meas: Measurement, par: Parameterisation, u: np.ndarray,
              r: np.ndarray, jac: np.ndarray, sigma, size: int, converged: bool,
              costs: np.ndarray):
    """The :class:`~jaxdobby.identify.fit.Identified` of the estimate u (residuals r and their
    Jacobian ``jac`` there; ``size``: padded samples per channel)."""
    from .fit import UNIDENTIFIABLE_CORRELATION, UNIDENTIFIABLE_RELATIVE_ERROR, Identified

    p = len(par.names)
    z = np.clip(u[:p], par.lower, par.upper)
    theta = par.values(z)
    keys = par.keys
    has_position = meas.position is not None
    columns = list(range(p)) + [p] + ([p + 1] if has_position else [])
    names = list(keys) + ["phase"] + (["position_offset"] if has_position else [])
    n = meas.time.size * len(meas.channels)
    cov = covariance(jac[:, columns], r, n)
    se_z = np.sqrt(np.diag(cov))[:p]
    se = se_z * par.dtheta_dz(theta)
    corr = correlation(cov)[:p, :p]
    warnings = []
    at_bound = [k for k, zi, lo, hi in zip(keys, u[:p], par.lower, par.upper)
                if zi <= lo + 1e-9 or zi >= hi - 1e-9]
    for k in at_bound:
        warnings.append(f"{k} is on a bound of its range: its estimate and standard error are "
                        f"not those of an interior minimum")
    for i, k in enumerate(keys):
        loose = se_z[i] > 1.0 if par.log[i] else se[i] > UNIDENTIFIABLE_RELATIVE_ERROR * abs(
            theta[i])
        if not np.isfinite(se[i]) or loose:
            warnings.append(f"not identifiable: {k} (standard error {se[i]:.3g} against the "
                            f"estimate {theta[i]:.4g}) is not determined by this trace")
    for i in range(p):
        for j in range(i + 1, p):
            if abs(corr[i, j]) > UNIDENTIFIABLE_CORRELATION:
                warnings.append(f"not identifiable: {keys[i]} and {keys[j]} are correlated "
                                f"{corr[i, j]:+.4f}: this trace fixes a combination of the two, "
                                f"not each")
    if not converged:
        warnings.append("the optimiser did not converge: the estimates are its last iterate")
    n_t = meas.time.size
    fitted_acc = fitted_pos = None
    if meas.acceleration is not None:
        fitted_acc = meas.acceleration + r[:n_t] * sigma[0]
    if has_position:
        fitted_pos = meas.position / MM + r[size:size + n_t] * sigma[1]
    rms = {}
    if fitted_acc is not None:
        rms["acceleration_m_s2"] = float(np.sqrt(np.mean((fitted_acc - meas.acceleration) ** 2)))
    if fitted_pos is not None:
        rms["position_mm"] = float(np.sqrt(np.mean((fitted_pos - meas.position / MM) ** 2)))
    return Identified(
        keys=keys, estimates=dict(zip(keys, map(float, theta))),
        standard_errors=dict(zip(keys, map(float, se))), correlation=corr,
        phase=float(np.mod(u[p], 1.0)), phase_error=float(np.sqrt(cov[p, p])),
        position_offset=float(u[p + 1]) * MM if has_position else None, residual_rms=rms,
        converged=converged, at_bound=at_bound, warnings=warnings,
        setup=apply(setup, dict(zip(par.names, theta))), fitted=(fitted_acc, fitted_pos), jacobian=jac[:, columns],
        covariance=cov, unknowns=tuple(names), starts=np.asarray(costs),
        sigma=tuple(float(x) for x in sigma))

