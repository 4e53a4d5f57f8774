"""Figures of ``jaxdobby loom``: the lift plan as the weaver's grid coloured by each frame's
dwell vibration, and every frame's deviation over the repeat."""

from __future__ import annotations

import numpy as np

from ..plots import plt


def lift_plan_figure(rows: list[dict], title: str = ""):
    """Grid picks × frames: a filled cell where the frame is up, its colour the dwell
    vibration (peak to peak [mm]) of that frame in that pick; ``rows`` of
    :func:`jaxdobby.weave.loom.run_frames`."""
    frames = len(rows)
    picks = len(rows[0]["lift_plan"])
    vib = np.array([np.asarray(r["dwell_vibration"]) * 1e3 for r in rows]).T  # (picks, frames)
    up = np.array([[c == "1" for c in r["lift_plan"]] for r in rows]).T
    fig, ax = plt.subplots(figsize=(max(4.0, 0.45 * frames + 2.0), max(3.0, 0.4 * picks + 1.5)),
                           layout="constrained")
    image = ax.imshow(vib, cmap="viridis", origin="lower", aspect="equal",
                      extent=(0.5, frames + 0.5, 0.5, picks + 0.5))
    ks, fs = np.nonzero(up)
    ax.scatter(fs + 1, ks + 1, marker="s", s=60, facecolors="none", edgecolors="white",
               linewidths=1.5, label="frame up")
    ax.set_xlabel("frame (1 = nearest the fell)")
    ax.set_ylabel("pick")
    ax.set_xticks(range(1, frames + 1))
    ax.set_yticks(range(1, picks + 1))
    fig.colorbar(image, ax=ax, label="dwell vibration, peak to peak [mm]")
    ax.set_title(title or "lift plan (white squares: up) and dwell vibration", fontsize=9)
    return fig


def deviation_figure(rows: list[dict], title: str = ""):
    """Every frame's heald-frame deviation [mm] over the repeat, time in picks."""
    fig, ax = plt.subplots(figsize=(8.0, 4.5), layout="constrained")
    for r in rows:
        if r.get("deviation") is None:
            continue
        t = np.asarray(r["t"])
        ax.plot(len(r["lift_plan"]) * t / t[-1], np.asarray(r["deviation"]) * 1e3, lw=0.8,
                label=f"frame {r['frame']} ({r['lift_plan']})")
    ax.set_xlabel("main-shaft turns (picks) from the middle of the last pick's dwell")
    ax.set_ylabel("deviation [mm]")
    ax.grid(alpha=0.3)
    if len(rows) <= 12:
        ax.legend(fontsize=7, ncol=2)
    ax.set_title(title or "heald-frame deviation over the repeat")
    return fig
