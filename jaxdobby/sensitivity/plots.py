"""Figures of Sobol indices: S1/ST bar charts with intervals, and pie charts of total sensitivity.

Figures are drawn on ``matplotlib.figure.Figure`` objects directly (the Agg renderer, no pyplot),
so making them changes no global matplotlib state and needs no display. Each file is written
atomically.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .analysis import SobolResult
from .store import atomic_write


def _labels(result: SobolResult) -> list[str]:
    space = result.space
    return [f"{n}\n[{u}]" if u != "1" else n for n, u in zip(space.names, space.units)]


def bar_figure(result: SobolResult, metric: str) -> Figure:
    """S1 and ST of one metric as grouped bars with their confidence half-widths."""
    ix = result.metrics[metric]
    x = np.arange(result.space.dim)
    fig = Figure(figsize=(1.6 + 1.1 * result.space.dim, 3.6), layout="constrained")
    ax = fig.add_subplot()
    ax.bar(x - 0.18, ix.S1, 0.36, yerr=ix.S1_conf, capsize=3, label="first order S1")
    ax.bar(x + 0.18, ix.ST, 0.36, yerr=ix.ST_conf, capsize=3, label="total ST")
    ax.set_xticks(x, _labels(result))
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.set_ylabel("Sobol index [-]")
    ax.set_title(f"{metric}: Sobol indices ({result.conf_level:.0%} intervals, "
                 f"N = {result.failures.n_used})", fontsize=10)
    ax.legend(frameon=False, fontsize=8)
    return fig


def pie_figure(result: SobolResult, metric: str) -> Figure:
    """Total sensitivity of one metric as a pie: ST_i / Σ ST (negative estimates counted as 0).

    ST sums to more than 1 when parameters interact, so the slices are shares of Σ ST, not of
    the variance; the title says so.
    """
    st = np.clip(result.metrics[metric].ST, 0.0, None)
    fig = Figure(figsize=(4.2, 4.2), layout="constrained")
    ax = fig.add_subplot()
    if st.sum() > 0:
        ax.pie(st / st.sum(), labels=result.space.names, autopct="%1.0f%%", startangle=90,
               counterclock=False)
    else:
        ax.text(0.5, 0.5, "no total sensitivity (constant metric)", ha="center", va="center")
        ax.set_axis_off()
    ax.set_title(f"{metric}: share of total sensitivity ST / ΣST", fontsize=10)
    return fig


def save_figures(result: SobolResult, directory: str | Path, fmt: str = "png") -> list[Path]:
    """Write a bar chart and a pie chart per metric into ``directory`` (created if missing).

    Returns:
        The written paths: ``sobol-<metric>-bars.<fmt>`` and ``sobol-<metric>-pie.<fmt>``.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for metric in result.metrics:
        safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", metric)
        for kind, make in (("bars", bar_figure), ("pie", pie_figure)):
            buf = io.BytesIO()
            make(result, metric).savefig(buf, format=fmt, dpi=120)
            paths.append(atomic_write(directory / f"sobol-{safe}-{kind}.{fmt}",
                                      lambda f, data=buf.getvalue(): f.write(data)))
    return paths
