"""Resonance map (Campbell diagram): the coupled natural frequencies against the loom speed.

The arm's natural frequencies *in the mechanism* (coupled to the blade and heald-frame inertia
through the linkage, :func:`jaxdobby.outputs.coupled_frequencies`) change with the configuration,
so over one heald-frame cycle each sweeps a band. The linearisation is speed-free and the
configuration at a given loom angle ψ is the same at every speed (the modulator is a law in ψ),
so the band is one horizontal strip in the (speed, frequency) plane: it is computed once, at
``n_phases`` evenly spaced loom angles over the cycle plus the mid-stroke instant of the lift.

The mechanism is excited at the pick rate f_pick = n/60 [Hz] (one pick per main-shaft turn at
n r/min) and its harmonics k·f_pick, straight rays from the origin. Where a ray passes through
the first coupled band — at speeds n ∈ [60 f_min/k, 60 f_max/k] — a harmonic of the motion
drives the frame-on-arm mode, and the heald-frame deviation (from a vmapped speed sweep,
:mod:`jaxdobby.sweep`) shows a peak; the map draws the two on a shared speed axis.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..dobby import DobbyModel
from ..outputs import coupled_frequencies, mid_lift_time
from ..plots import plt

N_PHASES = 48


class FrequencyBand(NamedTuple):
    """Coupled natural frequencies over one cycle.

    Attributes:
        loom_angle: loom angles of the samples [deg], (n,), 0…720 (the last is mid-lift).
        frequencies: coupled natural frequencies at each [Hz], (n, k).
        mid_stroke: those at mid-stroke of the lift [Hz], (k,) (:func:`coupled_frequencies`).
    """

    loom_angle: np.ndarray
    frequencies: np.ndarray
    mid_stroke: np.ndarray

    @property
    def low(self) -> np.ndarray:
        """Lowest value of each mode over the cycle [Hz], (k,)."""
        return self.frequencies.min(axis=0)

    @property
    def high(self) -> np.ndarray:
        """Highest value of each mode over the cycle [Hz], (k,)."""
        return self.frequencies.max(axis=0)


@eqx.filter_jit
def _frequencies_at(model: DobbyModel, t):
    return jax.vmap(coupled_frequencies, in_axes=(None, 0))(model, t)


def frequency_band(model: DobbyModel, n_phases: int = N_PHASES) -> FrequencyBand:
    """Coupled natural frequencies at ``n_phases`` loom angles over the cycle and at mid-lift."""
    period = model.period
    t_mid = mid_lift_time(model)
    t = jnp.concatenate([period * jnp.arange(n_phases) / n_phases, t_mid[None]])
    f = np.asarray(_frequencies_at(model, t))
    return FrequencyBand(loom_angle=np.asarray(t / period) * 720.0, frequencies=f,
                         mid_stroke=f[-1])


def crossing_speeds(low: float, high: float, speed_range, max_order: int
                    ) -> list[tuple[int, float, float]]:
    """Speed intervals [r/min] where the pick-rate harmonic k·n/60 lies in [low, high] [Hz].

    Returns (k, n_from, n_to) for k = 1…max_order whose interval [60·low/k, 60·high/k] meets
    ``speed_range`` = (n_min, n_max), clipped to it.
    """
    lo, hi = speed_range
    out = []
    for k in range(1, max_order + 1):
        a, b = max(60.0 * low / k, lo), min(60.0 * high / k, hi)
        if a <= b:
            out.append((k, a, b))
    return out


def max_harmonic(f_top: float, speed_min: float) -> int:
    """The highest k whose ray k·n/60 is below ``f_top`` [Hz] somewhere in the speed range."""
    return max(1, math.ceil(60.0 * f_top / speed_min))


def campbell_figure(band: FrequencyBand, speeds, deviation_pp_mm, *, f_top: float | None = None,
                    title: str = ""):
    """The resonance map: coupled bands and pick-rate rays over speed, deviation below.

    Args:
        band: :func:`frequency_band` of the machine.
        speeds: loom speeds of the sweep [r/min], (m,).
        deviation_pp_mm: heald-frame deviation, peak to peak, at those speeds [mm], (m,).
        f_top: top of the frequency axis [Hz]; default 1.5 × the first band's top.
    Returns the figure; its first axes holds one line per harmonic ray (label ``k = …``).
    """
    speeds = np.asarray(speeds, dtype=float)
    n_lo, n_hi = float(speeds.min()), float(speeds.max())
    f_top = 1.5 * float(band.high[0]) if f_top is None else f_top
    k_max = max_harmonic(f_top, n_lo)
    fig, (ax, ax_dev) = plt.subplots(2, 1, figsize=(7.2, 6.4), sharex=True, layout="constrained",
                                     height_ratios=(3, 2))
    n = np.linspace(0.0, n_hi * 1.02, 50)
    for k in range(1, k_max + 1):
        ax.plot(n, k * n / 60.0, color="0.55", lw=0.7, label=f"k = {k}")
        n_end = min(n_hi, 60.0 * f_top / k)
        if k <= 12 or k % 5 == 0:
            ax.text(n_end, k * n_end / 60.0, f" {k}", fontsize=7, color="0.35",
                    ha="left" if n_end >= n_hi else "center",
                    va="center" if n_end >= n_hi else "bottom")
    shown = [i for i in range(band.frequencies.shape[1]) if band.low[i] < f_top]
    for i in shown:
        ax.axhspan(band.low[i], band.high[i], color=f"C{i}", alpha=0.3, lw=0,
                   label=f"mode {i + 1}: {band.low[i]:.0f}–{band.high[i]:.0f} Hz over the cycle")
        ax.axhline(band.mid_stroke[i], color=f"C{i}", lw=1.0, ls="--")
    crossings = crossing_speeds(band.low[0], band.high[0], (n_lo, n_hi), k_max)
    last_label = math.inf
    for k, a, b in crossings:  # descending speed: k ascending
        ax.plot([a, b], [k * a / 60.0, k * b / 60.0], color="C3", lw=3.0, solid_capstyle="butt")
        ax_dev.axvspan(a, b, color="C3", alpha=0.12, lw=0)
        centre = 0.5 * (a + b)
        if last_label - centre > 0.07 * (n_hi - n_lo):  # name the harmonic where there is room
            ax_dev.text(centre, 1.0, f"k = {k}", transform=ax_dev.get_xaxis_transform(),
                        ha="center", va="top", fontsize=7, color="C3")
            last_label = centre
    hidden = [f"{band.mid_stroke[i]:.0f}" for i in range(band.frequencies.shape[1])
              if i not in shown]
    ax.set_ylim(0.0, f_top)
    ax.set_xlim(n_lo - 0.05 * (n_hi - n_lo) - 1.0, n_hi + 0.08 * (n_hi - n_lo) + 1.0)
    ax.set_ylabel("frequency [Hz]")
    handles = [h for h in ax.get_legend_handles_labels()[0] if not h.get_label().startswith("k =")]
    ax.legend(handles=handles, loc="upper left", fontsize=8, frameon=False)
    ax.set_title(title or ("Coupled natural frequencies (band over the cycle, dashed: mid-stroke) "
                           "and pick-rate harmonics k·n/60;\nred: a harmonic in the first band"
                           + (f"; higher modes at mid-stroke: {', '.join(hidden)} Hz"
                              if hidden else "")), fontsize=8)
    ax_dev.plot(speeds, np.asarray(deviation_pp_mm, dtype=float), "o-", color="C0", ms=3)
    ax_dev.set_xlabel("loom speed [r/min]")
    ax_dev.set_ylabel("heald-frame deviation,\npeak to peak [mm]")
    for a in (ax, ax_dev):
        a.grid(alpha=0.3)
    return fig
