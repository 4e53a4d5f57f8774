"""The ``jaxdobby identify`` command: options, checks and the run.

    jaxdobby identify MEASURED.csv --speed 800 --fit heald_frame_mass_kg damping_ratio \\
        [--config machine.toml] [--starts 4] [--bounds damping_ratio=0.001:0.2] [--out DIR] [--json]

Bad input (the CSV's columns, times or values; an unknown, integer or list parameter; bounds)
ends with one line and exit status 2; a fit that did not converge with status 1.
"""

from __future__ import annotations

import argparse
import json
import sys

from ..errors import InputError


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``jaxdobby identify`` (the model options come from the CLI's own)."""
    p.add_argument("measured", metavar="MEASURED.csv",
                   help="time_s and heald_frame_acceleration_m_s2 and/or heald_frame_position_mm")
    p.add_argument("--fit", nargs="+", required=True, metavar="KEY",
                   help="float parameters to identify, by their configuration key "
                        "(e.g. heald_frame_mass_kg blade_inertia_kg_m2 damping_ratio)")
    p.add_argument("--starts", type=int, default=4, metavar="N",
                   help="starts of Levenberg-Marquardt, one vmapped batch (default 4; 1-64)")
    p.add_argument("--spread", type=float, default=0.5, metavar="Z",
                   help="random starts within ±Z of the configuration's values in the fitted "
                        "coordinates (log parameters: a factor e^Z; default 0.5)")
    p.add_argument("--bounds", nargs="+", default=[], metavar="KEY=LO:HI",
                   help="bounds of fitted parameters in their units (default: the valid range)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    p.add_argument("--out", metavar="DIR",
                   help="write identified.toml, identify.json and identify_fit.png")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--no-figures", action="store_true", help="with --out: skip the figure")


def parse_bounds(items, keys) -> dict[str, tuple[float, float]]:
    """{TOML key: (low, high)} from ``KEY=LO:HI`` items (users' units; a key or a name)."""
    from ..parameters import PARAMETERS
    from .model import by_key

    def key_of(k):
        return PARAMETERS[by_key(k)].key

    keys = [key_of(k) for k in keys]
    out = {}
    for item in items:
        key, _, rest = item.partition("=")
        low, _, high = rest.partition(":")
        try:
            lo, hi = float(low), float(high)
        except ValueError:
            raise InputError(f"--bounds {item!r}: expected KEY=LOW:HIGH with numbers") from None
        key = key_of(key) if key else key
        if key not in keys:
            raise InputError(f"--bounds {item!r}: {key} is not among the fitted parameters "
                             f"({', '.join(keys)})")
        if not lo < hi:
            raise InputError(f"--bounds {item!r}: LOW must be < HIGH")
        out[key] = (lo, hi)
    return out


def run(ns: argparse.Namespace, setup_from_args) -> int:
    """Run ``jaxdobby identify``; returns the exit status."""
    from ..modulator import cycle_period
    from .fit import identify
    from .measurement import check_length, read_csv
    from .model import parameterisation
    from ..command_line import programs_dir
    from ..validity import setup_warnings
    from .report import summary, text, write

    if not 1 <= ns.starts <= 64:
        raise InputError(f"--starts = {ns.starts} is outside the valid range (an integer 1…64)")
    if not 0.0 <= ns.spread <= 5.0:
        raise InputError(f"--spread = {ns.spread} is outside the valid range (0…5)")
    setup, options = setup_from_args(ns)
    meas = read_csv(ns.measured)
    bounds = parse_bounds(ns.bounds, ns.fit)
    parameterisation(setup, ns.fit, bounds)  # every check before the long part
    check_length(meas, float(cycle_period(setup.operating.speed)))
    print("identifying (compiling the fit's programs first: about a minute on 2 cores; their "
          "tracing is stored for the next run)...", file=sys.stderr, flush=True)
    result = identify(setup, meas, ns.fit, options=options, starts=ns.starts, spread=ns.spread,
                      bounds=bounds, seed=ns.seed,
                      progress=lambda line: print(line, file=sys.stderr, flush=True),
                      directory=programs_dir())
    print("checking the identified machine against the model's validity limits...",
          file=sys.stderr, flush=True)
    summ = summary(result, setup_warnings(result.setup, options, directory=programs_dir()))
    if ns.out:
        paths = write(ns.out, meas, result, summ, options, figures=not ns.no_figures)
        print(f"wrote {len(paths)} files to {ns.out}", file=sys.stderr)
    for w in result.warnings:
        print(f"jaxdobby identify: warning: {w}", file=sys.stderr)
    if ns.json:
        keys = ("estimates", "standard_errors", "correlation", "residual_rms", "phase_deg",
                "converged")
        print(json.dumps({k: summ[k] for k in keys} | {"warnings": summ["warnings"]}, indent=2))
    else:
        print(text(summ))
    return 0 if result.converged else 1
