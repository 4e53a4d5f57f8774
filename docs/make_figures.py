"""Make the README's figures (``docs/figures/*.png``) from the package.

    python docs/make_figures.py                 # all
    python docs/make_figures.py cycle sweep     # some
    python docs/make_figures.py sobol --sobol-dir notebooks/runs/sobol-restoring-1024
    python docs/make_figures.py design --design-dirs notebooks/runs/design-thickness \
        notebooks/runs/design-depth

``cycle``: the default machine's heald frame over one cycle, rigid and flexible, and the
deviation; ``sweep``: the speed study (deviation and acceleration against speed); ``sobol``:
total Sobol indices of the deviation and the acceleration as bars and pie charts, read from the
``indices.json`` of a finished ``jaxdobby sobol`` run (notebook 05 keeps its N = 1024 run in
``notebooks/runs/``), or from a fresh run at ``--n`` base samples when none is given;
``mechanism``: the default machine drawn to scale at mid-lift, parts numbered as in the source
study; ``animation``: one steady cycle at 800 r/min as ``animation.gif`` and its frame at loom
angle 180° as ``animation_frame.png``; ``campbell``: the resonance map of the default machine
(coupled frequency bands, pick-rate harmonics, deviation at 400–1200 r/min by 50);
``design``: the arm's depth profile and the heald-frame deviation at 800 r/min of the default
machine beside the designs of finished ``jaxdobby optimize`` runs (their ``design.toml``, re-run
here with ``jaxdobby simulate``'s path; notebook 06 keeps its runs in ``notebooks/runs/``), and
the README's table of their masses and deviations at 800 and 1200 r/min on stderr.
Figures are kept small (100 dpi) because they are committed.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import jax
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "figures"
DPI = 100
METRICS = {"deviation_pp_mm": "heald-frame displacement deviation (p-p)",
           "acceleration_amp_m_s2": "heald-frame acceleration (p-p)"}


def cycle() -> plt.Figure:
    from jaxdobby import Machine, OperatingPoint, simulate

    run = simulate(Machine.default(), OperatingPoint.from_users_units(speed_rpm=800.0,
                                                                      warp_force_n=690.0))
    s = run.series
    t = np.asarray(s.t) * 1e3
    rigid, flexible = np.asarray(s.heald_rigid) * 1e3, np.asarray(s.heald_flexible) * 1e3
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.0, 5.0), sharex=True, layout="constrained",
                                 height_ratios=(3, 2))
    a1.plot(t, rigid, "k--", lw=1.0, label="rigid arm")
    a1.plot(t, flexible, color="C0", lw=1.0, label="flexible arm")
    a1.set_ylabel("heald-frame height [mm]")
    a1.set_title("Default machine, 800 r/min, 690 N, 140 mm stroke, 6 mm arm: one cycle "
                 "(two picks)", fontsize=10)
    a1.legend(frameon=False)
    a2.plot(t, flexible - rigid, color="C3", lw=1.0)
    a2.axhline(0.0, color="k", lw=0.6)
    a2.set_ylabel("deviation [mm]\n(flexible − rigid)")
    a2.set_xlabel("time in the cycle [ms]  (0: middle of the bottom dwell)")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.set_xlim(t[0], t[-1])
    return fig


def sweep() -> plt.Figure:
    from jaxdobby.parameters import Setup
    from jaxdobby.sweep import run_sweep, trend_figure

    result = run_sweep(Setup(), "speed", [400.0, 500.0, 600.0, 700.0, 800.0, 900.0, 1000.0,
                                          1100.0, 1200.0])
    return trend_figure(result)  # 690 N, 140 mm, 6 mm: the caption in the README says so


def mechanism() -> plt.Figure:
    from jaxdobby import Machine
    from jaxdobby.pictures.mechanism import mechanism_figure

    return mechanism_figure(Machine.default(), 180.0)


def animation() -> None:
    """Writes animation.gif (48 frames over the cycle) and its frame 12 (loom angle 180°)."""
    from PIL import Image

    from jaxdobby import simulate
    from jaxdobby.pictures.animation import animate

    path = animate(simulate(), OUT / "animation.gif", n_frames=48)
    with Image.open(path) as im:
        im.seek(12)
        im.convert("RGB").save(OUT / "animation_frame.png", optimize=True)
    print(f"wrote {path.relative_to(HERE.parent)} and animation_frame.png", file=sys.stderr)


def campbell() -> plt.Figure:
    import equinox as eqx

    from jaxdobby.dobby import build_model
    from jaxdobby.parameters import Setup
    from jaxdobby.pictures.campbell import campbell_figure, frequency_band
    from jaxdobby.pictures.command import DEFAULT_SPEEDS
    from jaxdobby.sweep import run_sweep

    setup = Setup()
    band = frequency_band(eqx.filter_jit(build_model)(setup.machine, setup.operating, None))
    result = run_sweep(setup, "speed", DEFAULT_SPEEDS)
    return campbell_figure(band, DEFAULT_SPEEDS, [r["deviation_pp_mm"] for r in result.rows])


def sobol_indices(directory: str | None, n: int) -> dict:
    """The ``indices.json`` of a finished run, or of a fresh one at ``n`` base samples."""
    if directory is None:
        from jaxdobby import sensitivity as sa

        directory = Path(tempfile.mkdtemp(prefix="jaxdobby-figures-")) / "sobol"
        sa.run_sobol(sa.SobolConfig(n=n, out=directory, figures=False))
    return json.loads((Path(directory) / "indices.json").read_text())


def sobol(indices: dict) -> plt.Figure:
    names = None
    fig, axes = plt.subplots(2, 2, figsize=(9.0, 7.2), layout="constrained",
                             height_ratios=(4, 5))
    for col, (metric, label) in enumerate(METRICS.items()):
        ix = indices["metrics"][metric]
        names = names or list(ix["ST"])
        st = np.array([ix["ST"][p] for p in names])
        st_conf = np.array([ix["ST_conf"][p] for p in names])
        s1 = np.array([ix["S1"][p] for p in names])
        s1_conf = np.array([ix["S1_conf"][p] for p in names])
        x = np.arange(len(names))
        ax = axes[0, col]
        ax.bar(x - 0.18, s1, 0.36, yerr=s1_conf, capsize=3, label="first order S1")
        ax.bar(x + 0.18, st, 0.36, yerr=st_conf, capsize=3, label="total ST")
        ax.set_xticks(x, [p.replace("_", "\n") for p in names])
        ax.axhline(0.0, color="0.3", lw=0.8)
        ax.set_ylim(min(0.0, float((s1 - s1_conf).min())) - 0.02, 1.0)
        ax.set_title(label, fontsize=10)
        ax.legend(frameon=False, fontsize=8)
        share = np.clip(st, 0.0, None)
        axes[1, col].pie(share / share.sum(), labels=names, autopct="%1.0f%%", startangle=90,
                         counterclock=False)
        axes[1, col].set_title("share of total sensitivity ST / ΣST", fontsize=9)
    axes[0, 0].set_ylabel("Sobol index [-]")
    n = indices["analysis"]["n_used"]
    fig.suptitle(f"Sobol indices (N = {n}, 95 % intervals) over speed 400–1200 r/min,\n"
                 "warp force 345–1035 N, stroke 80–140 mm, thickness 6–8 mm", fontsize=10)
    return fig


def design(directories: list[str]) -> plt.Figure:
    from jaxdobby import OperatingPoint, simulate
    from jaxdobby.config import load
    from jaxdobby.parameters import Setup

    runs = [("default arm: 6 mm plate, 40 mm deep", Setup(), None)]
    for directory in directories:
        setup, options = load(Path(directory) / "design.toml")
        result = json.loads((Path(directory) / "result.json").read_text())
        runs.append((_design_text(result["optimised"]["design"], setup), setup, options))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10.0, 3.8), layout="constrained",
                                 width_ratios=(2, 3))
    for (label, setup, options), style in zip(runs, ("k--", "C0-", "C3-", "C2-")):
        arm = setup.machine.arm
        s = np.linspace(0.0, float(arm.total_length), 200)
        depth = np.interp(s, np.atleast_1d(arm.depth_arc_lengths), np.atleast_1d(arm.depth))
        a1.plot(s * 1e3, depth * 1e3, style, lw=1.2, label=label)
        kwargs = {"method": options.method, "steps": options.steps} if options else {}
        run = simulate(setup.machine, setup.operating, **kwargs)
        pp = 1e3 * float(run.metrics["deviation_pp"])
        fast = simulate(setup.machine, OperatingPoint.from_users_units(
            speed_rpm=1200.0, warp_force_n=float(setup.operating.warp_force)), **kwargs)
        print(f"| {label} | {float(arm.mass()):.4f} kg | {pp:.3f} mm | "
              f"{1e3 * float(fast.metrics['deviation_pp']):.3f} mm |", file=sys.stderr)
        a2.plot(np.asarray(run.series.t) * 1e3, np.asarray(run.series.deviation) * 1e3, style,
                lw=1.0, label=f"{pp:.2f} mm p-p, arm {float(arm.mass()):.3f} kg")
    a1.set_xlabel("arc length from the pivot [mm]")
    a1.set_ylabel("in-plane depth [mm]")
    a1.set_ylim(0.0, 95.0)
    a1.set_title("bending arm", fontsize=10)
    a1.legend(frameon=False, fontsize=7, loc="upper right")
    a2.axhline(0.0, color="k", lw=0.6)
    a2.set_xlabel("time in the cycle [ms]")
    a2.set_ylabel("heald-frame deviation [mm]")
    a2.set_title("deviation at 800 r/min, 690 N, 140 mm stroke", fontsize=10)
    a2.legend(frameon=False, fontsize=8)
    for a in (a1, a2):
        a.grid(alpha=0.3)
    return fig


def _design_text(design: dict, setup) -> str:
    """A short legend label for an optimised design (its variables in mm)."""
    depths = [v for k, v in design.items() if k.startswith("depth")]
    parts = [f"{1e3 * float(setup.machine.arm.thickness):.0f} mm plate"]
    if depths:
        parts.append("depths " + "/".join(f"{v:.0f}" for v in depths) + " mm")
    return "optimised: " + ", ".join(parts)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = ["cycle", "sweep", "sobol", "design", "mechanism", "animation", "campbell"]
    parser.add_argument("which", nargs="*", default=names, choices=names,
                        help="figures (default: all)")
    parser.add_argument("--sobol-dir", default=None,
                        help="a finished `jaxdobby sobol` run to plot (its indices.json)")
    parser.add_argument("--n", type=int, default=256,
                        help="base samples of a fresh Sobol run (without --sobol-dir)")
    parser.add_argument("--design-dirs", nargs="*",
                        default=["notebooks/runs/design-thickness", "notebooks/runs/design-depth"],
                        help="finished `jaxdobby optimize` runs to plot (design.toml, result.json)")
    ns = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    OUT.mkdir(parents=True, exist_ok=True)
    makers = {"cycle": cycle, "sweep": sweep,
              "sobol": lambda: sobol(sobol_indices(ns.sobol_dir, ns.n)),
              "design": lambda: design(ns.design_dirs), "mechanism": mechanism,
              "animation": animation, "campbell": campbell}
    for name in ns.which:
        fig = makers[name]()
        if fig is None:  # the maker wrote its own files
            continue
        path = OUT / f"{name}.png"
        fig.savefig(path, dpi=DPI)
        plt.close(fig)
        print(f"wrote {path.relative_to(HERE.parent)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
