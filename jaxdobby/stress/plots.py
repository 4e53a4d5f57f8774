"""Figure of the arm's stress envelope over the cycle, drawn on the arm's shape."""

from __future__ import annotations

import numpy as np

from ..plots import plt
from .recovery import EDGES


def envelope_figure(stress, summary: dict | None = None, label: str = ""):
    """Top: the arm in its body frame (pivot at the origin), each edge coloured by the largest
    |σ| it sees over the cycle, the critical point marked. Bottom: the envelope (max and min
    over the cycle) of both edges along the arc length, with the endurance limit and the yield
    strength when ``summary`` (``jaxdobby simulate``'s) gives them."""
    from matplotlib.collections import LineCollection

    sigma = np.asarray(stress.sigma) * 1e-6  # (n_t, n_el, n_pts, 2) [MPa]
    s = np.asarray(stress.arc_lengths).reshape(-1) * 1e3
    edges = np.asarray(stress.edges).reshape(-1, 2, 2) * 1e3  # (points, edge, xy) [mm]
    hi = sigma.max(axis=0).reshape(-1, 2)
    lo = sigma.min(axis=0).reshape(-1, 2)
    peak = np.maximum(hi, -lo)
    order = np.argsort(s, kind="stable")
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.5, 7.0), layout="constrained",
                                      height_ratios=[1.0, 1.1])
    suffix = f" — {label}" if label else ""
    top.set_title("Bending arm: largest |σ| over the cycle at each edge" + suffix)
    norm = plt.Normalize(0.0, peak.max())
    for e in range(2):
        xy = edges[order, e]
        segments = np.stack([xy[:-1], xy[1:]], axis=1)
        lc = LineCollection(segments, cmap="inferno_r", norm=norm, linewidths=4)
        lc.set_array(0.5 * (peak[order, e][:-1] + peak[order, e][1:]))
        top.add_collection(lc)
    centre = edges.mean(axis=1)[order]
    top.plot(centre[:, 0], centre[:, 1], "k:", lw=0.8)
    top.plot([0.0], [0.0], "ko", ms=6, label="pivot")
    i = np.unravel_index(np.argmax(peak), peak.shape)
    top.plot(*edges[i[0], i[1]], "c*", ms=14, label=f"critical point ({EDGES[i[1]]} edge)")
    top.set_aspect("equal")
    top.autoscale_view()
    top.set_xlabel("x in the arm's frame [mm]")
    top.set_ylabel("y [mm]")
    top.legend(loc="lower left", fontsize=8)
    fig.colorbar(lc, ax=top, label="max |σ| over the cycle [MPa]", shrink=0.8)

    bottom.set_title("Stress envelope along the arm (max and min over the cycle)")
    for e, colour in ((0, "C0"), (1, "C3")):
        bottom.plot(s[order], hi[order, e], color=colour, lw=1.2, label=f"{EDGES[e]} edge, max")
        bottom.plot(s[order], lo[order, e], color=colour, lw=1.2, ls="--",
                    label=f"{EDGES[e]} edge, min")
    if summary is not None:
        for key, text, style in (("endurance_limit_mpa", "± endurance limit", ":"),
                                 ("yield_strength_mpa", "± yield", "-.")):
            if key in summary:
                v = summary[key]
                bottom.axhline(v, color="k", ls=style, lw=0.8, label=text)
                bottom.axhline(-v, color="k", ls=style, lw=0.8)
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_xlabel("arc length from the pivot [mm]")
    bottom.set_ylabel("σ [MPa]")
    bottom.grid(alpha=0.3)
    bottom.legend(fontsize=7, ncol=2, loc="lower right")
    return fig
