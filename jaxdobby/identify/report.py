"""What ``jaxdobby identify`` prints and writes: the summary in the users' units (the keys of
``--json``), a readable table, ``identified.toml``, ``identify.json`` and the fit figure."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..config import RunOptions, to_toml
from ..io import write_json, write_text
from ..parameters import PARAMETERS
from .fit import Identified
from .measurement import Measurement

LOOM_DEGREES_PER_CYCLE = 720.0
"""One heald-frame cycle is two picks: two turns of the loom's main shaft."""


def _users(key: str) -> float:
    return next(p.scale for p in PARAMETERS.values() if p.key == key)


def _finite(x):
    return float(x) if math.isfinite(x) else None


FIT_WARNINGS = (("not identifiable", "not_identifiable"), ("on a bound", "at_bound"),
                ("did not converge", "fit_not_converged"))
"""(words of a fit warning, its code) of :func:`fit_warning_entries`."""


def fit_warning_entries(lines) -> list[dict]:
    """The fit's warnings (:attr:`Identified.warnings`, one line each) as entries of the
    ``warnings`` list (code, message, value, limit; :mod:`jaxdobby.validity`): codes
    ``not_identifiable``, ``at_bound``, ``fit_not_converged`` (``fit`` for another)."""
    return [{"code": next((c for words, c in FIT_WARNINGS if words in line), "fit"),
             "message": line, "value": None, "limit": None} for line in lines]


def summary(result: Identified, validity=()) -> dict:
    """The result in the users' units (TOML keys), JSON-ready (an infinite standard error or an
    undefined correlation is ``null``). ``warnings``: the fit's (:func:`fit_warning_entries`)
    and ``validity``, the identified machine's validity warnings
    (:func:`jaxdobby.validity.setup_warnings`, as ``jaxdobby simulate`` gives them)."""
    est = {k: v / _users(k) for k, v in result.estimates.items()}
    se = {k: _finite(v / _users(k)) for k, v in result.standard_errors.items()}
    corr = [[_finite(c) if np.isfinite(c) else None for c in row] for row in result.correlation]
    out = {"estimates": est, "standard_errors": se, "correlation": corr,
           "residual_rms": result.residual_rms,
           "phase_deg": result.phase * LOOM_DEGREES_PER_CYCLE,
           "phase_error_deg": _finite(result.phase_error * LOOM_DEGREES_PER_CYCLE),
           "converged": result.converged,
           "warnings": fit_warning_entries(result.warnings) + list(validity),
           "at_bound": result.at_bound}
    if result.position_offset is not None:
        out["position_offset_mm"] = result.position_offset * 1e3
    return out


def text(summ: dict) -> str:
    """A readable table of :func:`summary`."""
    lines = ["jaxdobby identify: least squares through the periodic steady state", "",
             f"  {'parameter':<28} {'estimate':>14} {'std. error':>12}"]
    for k, v in summ["estimates"].items():
        se = summ["standard_errors"][k]
        lines.append(f"  {k:<28} {v:>14.6g} {'inf' if se is None else f'{se:.3g}':>12}")
    lines.append("")
    keys = list(summ["estimates"])
    if len(keys) > 1:
        lines.append("  correlation: " + "  ".join(f"{i + 1}={k}" for i, k in enumerate(keys)))
        for i, row in enumerate(summ["correlation"]):
            lines.append(f"    {i + 1}: " + " ".join(
                "   nan" if c is None else f"{c:+.3f}" for c in row))
        lines.append("")
    lines.append(f"  phase of the first sample: {summ['phase_deg']:.3f}° loom angle "
                 f"(0: middle of the bottom dwell; 720° per heald-frame cycle)")
    if "position_offset_mm" in summ:
        lines.append(f"  position channel offset: {summ['position_offset_mm']:.4f} mm")
    for k, v in summ["residual_rms"].items():
        lines.append(f"  residual RMS, {k}: {v:.4g}")
    lines.append(f"  converged: {'yes' if summ['converged'] else 'NO'}")
    if summ["warnings"]:
        from ..validity import warning_lines

        lines.append(warning_lines(summ["warnings"]))
    return "\n".join(lines)


def figure(meas: Measurement, result: Identified):
    """Measured and fitted channels against time, with the residuals below each."""
    from ..plots import plt

    chans = [(meas.acceleration, result.fitted[0], "acceleration [m/s²]"),
             (None if meas.position is None else meas.position * 1e3, result.fitted[1],
              "position [mm]")]
    chans = [c for c in chans if c[0] is not None]
    fig, axes = plt.subplots(2 * len(chans), 1, figsize=(8.0, 2.6 * 2 * len(chans)),
                             sharex=True, layout="constrained",
                             gridspec_kw={"height_ratios": [2, 1] * len(chans)})
    t = meas.time - meas.time[0]
    for i, (y, fit, label) in enumerate(chans):
        ax, axr = axes[2 * i], axes[2 * i + 1]
        ax.plot(t, y, ".", ms=1.5, color="0.55", label="measured")
        ax.plot(t, fit, "-", lw=1.0, color="C3", label="fitted model")
        ax.set_ylabel(label)
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
        axr.plot(t, y - fit, ".", ms=1.5, color="C0")
        axr.set_ylabel("residual")
        axr.grid(alpha=0.3)
    axes[0].set_title("heald-frame motion: measured and identified model")
    axes[-1].set_xlabel("time from the first sample [s]")
    return fig


def write(directory: str | Path, meas: Measurement, result: Identified, summ: dict,
          options: RunOptions | None = None, figures: bool = True) -> list[Path]:
    """``identified.toml`` (the machine with the estimates; ``jaxdobby simulate --config``),
    ``identify.json`` (:func:`summary` plus the covariance of all unknowns) and
    ``identify_fit.png``."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    header = "# identified by jaxdobby identify; estimates ± standard error:\n" + "".join(
        f"#   {k} = {v:.6g} ± {summ['standard_errors'][k]}\n" for k, v in summ["estimates"].items())
    paths = [write_text(out / "identified.toml", header + to_toml(result.setup, options))]
    cov = [[_finite(c) for c in row] for row in result.covariance]
    paths.append(write_json(out / "identify.json", dict(
        summ, unknowns=list(result.unknowns), covariance_fitted_space=cov,
        start_costs=[_finite(c) for c in result.starts])))
    if figures:
        from ..plots import plt

        fig = figure(meas, result)
        paths.append(out / "identify_fit.png")
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)
    return paths
