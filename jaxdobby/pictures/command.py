"""Command-line parts of the pictures: ``simulate``'s drawing and animation, ``campbell``.

``jaxdobby simulate --out DIR`` also writes ``mechanism.png`` (the drawing at ``--loom-angle``);
``--animate [FILE]`` writes the animation of the steady cycle (``animation.gif`` in ``--out`` or
the current directory by default; ``.mp4`` with an ffmpeg binary). ``jaxdobby campbell`` draws the
resonance map of a configured machine (the same configuration flags as ``sweep``).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from ..errors import InputError

DEFAULT_SPEEDS = [400.0 + 50.0 * i for i in range(17)]
"""Speeds of the resonance map's deviation sweep [r/min]: 400…1200 in steps of 50."""


def add_simulate_arguments(p: argparse.ArgumentParser) -> None:
    """``simulate``'s picture flags."""
    p.add_argument("--loom-angle", type=float, default=180.0, metavar="DEG",
                   help="loom angle of the mechanism drawing written with --out [deg from the "
                        "middle of the bottom dwell, 0-720] (default 180: mid-lift)")
    p.add_argument("--animate", nargs="?", const="animation.gif", metavar="FILE",
                   help="write an animation of the steady cycle (.gif; .mp4 needs ffmpeg); "
                        "default animation.gif, in --out DIR if given")
    p.add_argument("--frames", type=int, default=48, metavar="N",
                   help="frames of the animation over one cycle, 2-360 (default 48)")
    p.add_argument("--magnification", type=float, metavar="X",
                   help="factor on the arm's deformation in the animation (default: automatic)")


def _check(ns: argparse.Namespace) -> None:
    if not (math.isfinite(ns.loom_angle) and 0.0 <= ns.loom_angle <= 720.0):
        raise InputError(f"--loom-angle = {ns.loom_angle:g} is outside the valid range 0…720 deg")
    if not 2 <= ns.frames <= 360:
        raise InputError(f"--frames = {ns.frames} is outside the valid range (an integer 2…360)")
    if ns.magnification is not None and not (math.isfinite(ns.magnification)
                                             and 0.0 < ns.magnification <= 1e4):
        raise InputError(f"--magnification = {ns.magnification:g} is outside the valid range "
                         "(0, 10000]")
    if ns.animate is not None and Path(ns.animate).suffix.lower() not in (".gif", ".mp4"):
        raise InputError(f"--animate {ns.animate}: the file must end in .gif or .mp4")


def simulate_pictures(ns: argparse.Namespace):
    """Check ``simulate``'s picture flags (raising :class:`InputError`) and return the function
    that writes the pictures of a run: ``write(machine, run) -> list[Path]``, ``run`` a function
    returning the :class:`~jaxdobby.simulate.Simulation` (called only for the animation)."""
    _check(ns)
    if ns.animate is not None and Path(ns.animate).suffix.lower() == ".mp4":
        from .animation import ffmpeg_binary

        if ffmpeg_binary() is None:
            raise InputError(f"--animate {ns.animate}: an .mp4 needs an ffmpeg binary (install "
                             "ffmpeg or `pip install imageio-ffmpeg`); a .gif needs nothing")

    def write(machine, run) -> list[Path]:
        paths = []
        if ns.out and not ns.no_figures:
            from ..plots import plt  # matplotlib only when drawing (0.5–1 s to import)
            from .mechanism import mechanism_figure

            fig = mechanism_figure(machine, ns.loom_angle)
            path = Path(ns.out) / "mechanism.png"
            fig.savefig(path, dpi=100)
            plt.close(fig)
            paths.append(path)
        if ns.animate is not None:
            from .animation import animate

            target = Path(ns.animate)
            if ns.out and not target.is_absolute() and target.parent == Path("."):
                target = Path(ns.out) / target
            paths.append(animate(run(), target, n_frames=ns.frames,
                                 magnification=ns.magnification))
        return paths

    return write


# -- jaxdobby campbell -----------------------------------------------------------------------
def add_campbell_arguments(p: argparse.ArgumentParser) -> None:
    from ..command_line import _add_model_arguments

    p.add_argument("--values", type=float, nargs="+", metavar="RPM",
                   help="loom speeds of the deviation sweep [r/min] (default 400-1200 by 50)")
    p.add_argument("--phases", type=int, default=48, metavar="N",
                   help="loom angles over the cycle at which the frequencies are computed, "
                        "4-720 (default 48)")
    p.add_argument("--fmax", type=float, metavar="HZ",
                   help="top of the frequency axis [Hz] (default 1.5 x the first band's top)")
    _add_model_arguments(p)
    p.add_argument("--out", metavar="DIR", help="write campbell.png, campbell.json, campbell.csv")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def campbell_result(band, speeds, rows) -> dict:
    """The resonance map's numbers (users' units) for JSON and the table."""
    from .campbell import crossing_speeds, max_harmonic

    lo, hi = min(speeds), max(speeds)
    crossings = crossing_speeds(float(band.low[0]), float(band.high[0]), (lo, hi),
                                max_harmonic(float(band.high[0]), lo))
    return {
        "band_low_hz": [float(f) for f in band.low],
        "band_high_hz": [float(f) for f in band.high],
        "mid_stroke_hz": [float(f) for f in band.mid_stroke],
        "crossings": [{"harmonic": k, "speed_from_rpm": a, "speed_to_rpm": b}
                      for k, a, b in crossings],
        "speeds_rpm": [float(v) for v in speeds],
        "deviation_pp_mm": [r["deviation_pp_mm"] for r in rows],
        "converged": [r["converged"] for r in rows],
    }


def campbell_text(result: dict) -> str:
    """A readable summary of :func:`campbell_result`."""
    lines = ["Coupled natural frequencies over the cycle [Hz] (mid-stroke in brackets):"]
    for i, (a, b, m) in enumerate(zip(result["band_low_hz"], result["band_high_hz"],
                                      result["mid_stroke_hz"])):
        lines.append(f"  mode {i + 1}: {a:8.1f} … {b:8.1f}  ({m:.1f})")
    lines.append("Pick-rate harmonics k·n/60 inside the first band:")
    for c in result["crossings"]:
        lines.append(f"  k = {c['harmonic']:2d}: {c['speed_from_rpm']:6.0f} … "
                     f"{c['speed_to_rpm']:6.0f} r/min")
    lines.append("Heald-frame deviation, peak to peak:")
    for n, d, ok in zip(result["speeds_rpm"], result["deviation_pp_mm"], result["converged"]):
        lines.append(f"  {n:6.0f} r/min  {d:7.3f} mm" + ("" if ok else "  (NOT converged)"))
    return "\n".join(lines)


def run_campbell(ns: argparse.Namespace) -> int:
    """``jaxdobby campbell``: the resonance map of the configured machine."""
    import equinox as eqx

    from ..command_line import _status, programs_dir, setup_from_args
    from ..dobby import build_model
    from ..io import write_json, write_text
    from ..plots import plt
    from ..sweep import prepare_sweep
    from .campbell import campbell_figure, frequency_band

    if not 4 <= ns.phases <= 720:
        raise InputError(f"--phases = {ns.phases} is outside the valid range (an integer 4…720)")
    if ns.fmax is not None and not (math.isfinite(ns.fmax) and ns.fmax > 0.0):
        raise InputError(f"--fmax = {ns.fmax:g} is outside the valid range (> 0 Hz)")
    setup, options = setup_from_args(ns)
    if ns.speed is not None:
        _status("note: --speed does not apply: the map sweeps the speed (--values)")
    speeds = list(ns.values) if ns.values else DEFAULT_SPEEDS
    sweep = prepare_sweep(setup, "speed", speeds, method=options.method,
                          directory=programs_dir())
    band = frequency_band(eqx.filter_jit(build_model)(setup.machine, setup.operating, None),
                          ns.phases)
    _status(f"sweeping the speed over {len(speeds)} values (the first run compiles)...")
    result = sweep()
    out = campbell_result(band, speeds, result.rows)
    if ns.out:
        directory = Path(ns.out)
        directory.mkdir(parents=True, exist_ok=True)
        fig = campbell_figure(band, speeds, out["deviation_pp_mm"], f_top=ns.fmax)
        fig.savefig(directory / "campbell.png", dpi=100)
        plt.close(fig)
        write_json(directory / "campbell.json", out)
        write_text(directory / "campbell.csv", "speed_rpm,deviation_pp_mm,converged\n" + "".join(
            f"{n:g},{d!r},{c}\n" for n, d, c in zip(speeds, out["deviation_pp_mm"],
                                                     out["converged"])))
        _status(f"wrote campbell.png, campbell.json and campbell.csv to {directory}")
    print(json.dumps(out, indent=2) if ns.json else campbell_text(out))
    return 0 if all(out["converged"]) else 1
