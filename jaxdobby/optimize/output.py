"""What ``jaxdobby optimize`` writes: history (CSV + JSON), the optimised design (TOML), figures.

Files in the output directory, each written atomically:

* ``history.csv`` / ``history.json`` — one row per iteration: objective J, augmented Lagrangian,
  projected gradient, the design variables (users' units), the arm's mass and first coupled
  frequency, constraint values and multipliers, and per speed the true and smooth
  peak-to-peak deviation and the acceleration amplitude;
* ``result.json`` — the problem, the starting and optimised designs, their metrics at every
  speed on the modal model that ``jaxdobby simulate`` runs (the optimiser's own model), the
  improvement, the optimality conditions, timings;
* ``design.toml`` — the optimised machine, which ``jaxdobby simulate --config`` reads (the
  study's integrator and step count included, so the metric is reproduced exactly);
* ``history.png``, ``depth_profile.png``, ``deviation.png`` — objective and constraints over the
  iterations, the arm's depth along its length before/after, the heald-frame deviation over the
  cycle before/after.
"""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..io import write_json, write_text

MM = 1e3


def history_rows(history: list[dict]) -> str:
    """The history (list of flat dicts) as CSV text."""
    keys = list(history[0])
    buf = io.StringIO()
    buf.write(",".join(keys) + "\n")
    for row in history:
        buf.write(",".join(_cell(row[k]) for k in keys) + "\n")
    return buf.getvalue()


def _cell(v) -> str:
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return f"{float(v):.10g}"


def write_outputs(directory, history: list[dict], result: dict, design_toml: str,
                  figures: dict | None = None) -> list[Path]:
    """Write the files listed in the module docstring; ``figures`` as from :func:`figures`."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = [write_text(directory / "history.csv", history_rows(history)),
             write_json(directory / "history.json", history),
             write_json(directory / "result.json", result),
             write_text(directory / "design.toml", design_toml)]
    for stem, fig in (figures or {}).items():
        path = directory / f"{stem}.png"
        buf = io.BytesIO()
        fig.savefig(buf, dpi=120, format="png")
        plt.close(fig)
        from ..io import atomic_write

        data = buf.getvalue()
        paths.append(atomic_write(path, lambda f, data=data: f.write(data)))
    return paths


def figures(history: list[dict], constraint_names: list[str], profiles: dict,
            deviations: dict, variables: dict[str, tuple[float, float]] | None = None) -> dict:
    """The three figures.

    Args:
        history: the history rows (keys ``iteration``, ``objective``, ``c_<name>``).
        constraint_names: names of the constraints in the rows.
        variables: history column → (lower, upper) bound, drawn normalised to the box.
        profiles: label → (arc length [m], depth [m]) of the arm, e.g. before/after.
        deviations: speed label → {design label → (time [s], deviation [m])}.
    """
    out = {}
    it = [r["iteration"] for r in history]
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.8), sharex=True, layout="constrained")
    axes[0].plot(it, [r["objective"] for r in history], "o-", label="objective J")
    axes[0].plot(it, [r["lagrangian"] for r in history], "--", color="0.5",
                 label="augmented Lagrangian")
    axes[0].set_ylabel("J (1 = starting design)")
    axes[0].legend()
    axes[0].grid(alpha=0.3)
    for name in constraint_names:
        axes[1].plot(it, [r[f"c_{name}"] for r in history], "o-", label=_constraint_label(name))
    axes[1].axhline(0.0, color="k", lw=0.8)
    axes[1].set_ylabel("constraint c (feasible ≤ 0)")
    for key, (lo, hi) in (variables or {}).items():
        axes[2].plot(it, [(r[key] - lo) / (hi - lo) for r in history], "o-", ms=3, label=key)
    axes[2].set_ylim(-0.05, 1.05)
    axes[2].set_ylabel("design variable (0 = lower, 1 = upper bound)")
    axes[2].set_xlabel("iteration")
    axes[2].grid(alpha=0.3)
    if variables:
        axes[2].legend(fontsize=7, ncol=2)
    if constraint_names:
        axes[1].legend()
    else:
        axes[1].text(0.5, 0.5, "no constraints", transform=axes[1].transAxes, ha="center")
    axes[1].grid(alpha=0.3)
    fig.suptitle("Design optimisation history")
    out["history"] = fig

    fig, ax = plt.subplots(figsize=(7.0, 3.6), layout="constrained")
    for (label, (s, d)), style in zip(profiles.items(), ("k--", "C3-")):
        ax.plot(np.asarray(s) * MM, np.asarray(d) * MM, style, marker="o", label=label)
    ax.set_xlabel("arc length from the pivot [mm]")
    ax.set_ylabel("in-plane depth d [mm]")
    ax.set_title("Bending arm depth profile")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend()
    out["depth_profile"] = fig

    n = len(deviations)
    fig, axes = plt.subplots(n, 1, figsize=(7.0, 2.8 * n + 0.6), squeeze=False,
                             layout="constrained")
    for ax, (speed, runs) in zip(axes[:, 0], deviations.items()):
        for (label, (t, dev)), style in zip(runs.items(), ("k--", "C3-")):
            ax.plot(np.asarray(t) * 1e3, np.asarray(dev) * MM, style, lw=0.9, label=label)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(f"Heald-frame displacement deviation at {speed}")
        ax.set_ylabel("deviation [mm]")
        ax.grid(alpha=0.3)
        ax.legend()
    axes[-1, 0].set_xlabel("time in the cycle [ms]")
    out["deviation"] = fig
    return out


def _constraint_label(name: str) -> str:
    return {"mass": "arm mass / budget − 1", "frequency": "1 − f₁ / floor",
            "stress": "peak stress / limit − 1", "fatigue": "floor / fatigue factor − 1"}.get(
        name, name)
