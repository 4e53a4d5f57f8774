"""Figures of a run, like the source study's (heald-frame deviation, velocity, acceleration,
link-11 point deviation, link forces), drawn with matplotlib's non-interactive Agg backend."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

MM = 1e3


def show(fig, dpi: int = 80) -> None:
    """Display ``fig`` in a Jupyter notebook as a PNG at ``dpi`` and close it.

    This module selects matplotlib's Agg backend (figures are written to files from the command
    line), which switches a notebook's inline display off; the notebooks show figures with this.
    Needs IPython (present in any notebook kernel)."""
    import io

    from IPython.display import Image, display

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    display(Image(buf.getvalue()))


def _axes(title, ylabel, t_ms):
    fig, ax = plt.subplots(figsize=(7.0, 3.6), layout="constrained")
    ax.set_title(title)
    ax.set_xlabel("time in the cycle [ms]  (0: middle of the bottom dwell)")
    ax.set_ylabel(ylabel)
    ax.set_xlim(t_ms[0], t_ms[-1])
    ax.grid(alpha=0.3)
    return fig, ax


def figures(series, label: str = "") -> dict[str, plt.Figure]:
    """The run's figures by file stem, from a :class:`~jaxdobby.outputs.Timeseries`."""
    t = np.asarray(series.t) * 1e3
    s = {k: np.asarray(getattr(series, k)) for k in (
        "heald_rigid", "heald_flexible", "velocity_rigid", "velocity_flexible",
        "acceleration_rigid", "acceleration_flexible", "link_point_deviation", "ring_link_force",
        "link11_force")}
    suffix = f" — {label}" if label else ""
    out = {}

    fig, ax = _axes("Heald-frame displacement deviation (flexible − rigid)" + suffix,
                    "deviation [mm]", t)
    ax.plot(t, (s["heald_flexible"] - s["heald_rigid"]) * MM, color="C3")
    ax.axhline(0.0, color="k", lw=0.6)
    out["deviation"] = fig

    fig, ax = _axes("Heald-frame displacement" + suffix, "height [mm]", t)
    ax.plot(t, s["heald_rigid"] * MM, "k--", lw=1, label="rigid arm")
    ax.plot(t, s["heald_flexible"] * MM, color="C0", lw=1, label="flexible arm")
    ax.legend()
    out["displacement"] = fig

    for key, title, unit in (("velocity", "Heald-frame velocity", "m/s"),
                             ("acceleration", "Heald-frame acceleration", "m/s²")):
        fig, ax = _axes(title + suffix, f"{key} [{unit}]", t)
        ax.plot(t, s[f"{key}_flexible"], color="C0", lw=0.8, label="flexible arm")
        ax.plot(t, s[f"{key}_rigid"], "k--", lw=1, label="rigid arm")
        ax.legend()
        out[key] = fig

    fig, ax = _axes("Link-11 joint: deviation from the rigid arm (inertial)" + suffix,
                    "deviation [mm]", t)
    ax.plot(t, s["link_point_deviation"][:, 0] * MM, label="horizontal x")
    ax.plot(t, s["link_point_deviation"][:, 1] * MM, label="vertical y")
    ax.legend()
    out["link_point_deviation"] = fig

    fig, ax = _axes("Link forces on the bending arm" + suffix, "force [kN]", t)
    ax.plot(t, s["ring_link_force"] / 1e3, label="ring link 9 (tension +)")
    ax.plot(t, np.linalg.norm(s["link11_force"], axis=-1) / 1e3, label="link 11 (magnitude)")
    ax.legend()
    out["link_forces"] = fig
    return out


def save_figures(series, directory: str | Path, label: str = "", fmt: str = "png") -> list[Path]:
    """Write the figures of :func:`figures` into ``directory``; returns the paths."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for stem, fig in figures(series, label).items():
        path = directory / f"{stem}.{fmt}"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)
    return paths


def overlay_figure(runs: dict[str, object], quantity: str = "deviation", title: str = ""):
    """Overlay one quantity of several runs (label → Timeseries); returns the figure."""
    first = next(iter(runs.values()))
    t = np.asarray(first.t) * 1e3
    units = {"deviation": ("deviation [mm]", MM), "velocity_deviation": ("[m/s]", 1.0),
             "acceleration_flexible": ("acceleration [m/s²]", 1.0),
             "heald_flexible": ("height [mm]", MM)}
    ylabel, scale = units[quantity]
    fig, ax = _axes(title or quantity.replace("_", " "), ylabel, t)
    for label, series in runs.items():
        ax.plot(np.asarray(series.t) * 1e3, np.asarray(getattr(series, quantity)) * scale,
                lw=0.9, label=label)
    ax.legend()
    return fig
