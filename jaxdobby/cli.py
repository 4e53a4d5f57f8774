"""The ``jaxdobby`` command line.

Commands (``jaxdobby COMMAND --help`` for each):

* ``simulate`` — one run of the mechanism at an operating point (the default machine with no
  arguments): summary table, ``--json``, ``--out DIR`` for CSV/JSON/figures;
* ``sweep`` — the source study's one-at-a-time parameter studies;
* ``sobol`` — Sobol sensitivity indices from batched, sharded runs;
* ``optimize`` — gradient-based design of the bending arm;
* ``beam`` — the natural frequencies and mode shapes of the default bending arm;
* ``identify`` — fit parameters of the machine to a measured heald-frame trace.

The command line speaks the users' units (mm, r/min, N) and converts to SI at this boundary.
It is the only place that switches JAX to float64 and the only place that prints. Bad input
ends with one line naming the field and its valid range, and exit status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path
from collections.abc import Sequence

from .errors import InputError

EXIT_BAD_INPUT = 2


def _configure_jax() -> None:
    """float64, and a persistent compilation cache so that later runs skip most compiling
    (``JAXDOBBY_CACHE_DIR`` to move it, ``JAXDOBBY_CACHE_DIR=off`` to disable it)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    cache = os.environ.get("JAXDOBBY_CACHE_DIR",
                           str(Path.home() / ".cache" / "jaxdobby" / "xla"))
    if cache.lower() != "off":
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


FLAG_PARAMETERS = {"speed": "speed", "warp_force": "warp_force", "stroke": "stroke",
                   "thickness": "thickness"}
"""Command-line flags that set a model parameter (flag dest → registry name)."""


def _add_model_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--speed", type=float, metavar="RPM", help="loom speed [r/min] (default 800)")
    p.add_argument("--warp-force", type=float, metavar="N",
                   help="peak warp force on the heald frame [N] (default 690)")
    p.add_argument("--stroke", type=float, metavar="MM",
                   help="heald-frame stroke [mm] (default 140; moves the link-11 joint)")
    p.add_argument("--thickness", type=float, metavar="MM",
                   help="plate thickness of the bending arm [mm] (default 6)")
    p.add_argument("--modes", type=int, metavar="K", help="modes of the arm kept, 1-30 (default 4)")
    p.add_argument("--coupling", choices=["two-way", "one-way"], help="default two-way")
    p.add_argument("--warp-law", choices=["restoring", "opposing"], help="default restoring")
    p.add_argument("--method", choices=["collocation", "rk4", "adaptive"],
                   help="integrator (default collocation; rk4 for --coupling one-way)")
    p.add_argument("--config", metavar="FILE.toml",
                   help="configuration file (any model parameter; see README)")


def setup_from_args(ns: argparse.Namespace):
    """The (Setup, RunOptions) described by the config file and flags (flags win)."""
    from .config import RunOptions, apply_checked, check_value, load
    from .parameters import PARAMETERS, Setup

    setup, options = load(ns.config) if ns.config else (Setup(), RunOptions())
    values = {}
    for dest, name in FLAG_PARAMETERS.items():
        v = getattr(ns, dest)
        if v is not None:
            p = PARAMETERS[name]
            values[name] = check_value(p, v, f"--{dest.replace('_', '-')}")[0] * p.scale
    setup = apply_checked(setup, values)
    changes = {}
    if ns.modes is not None:
        if not 1 <= ns.modes <= 30:
            raise InputError(f"--modes = {ns.modes} is outside the valid range (an integer 1…30)")
        changes["n_modes"] = ns.modes
    for key in ("coupling", "warp_law"):
        if getattr(ns, key) is not None:
            changes[key] = getattr(ns, key)
    if changes:
        setup = dataclasses.replace(setup, machine=setup.machine.replace(**changes))
    if ns.method is not None:
        options.method = ns.method
    return setup, options


def _simulate(ns: argparse.Namespace) -> int:
    from .report import dumps, summary_table, write_run
    from .simulate import simulate, summary

    setup, options = setup_from_args(ns)
    _status("solving the periodic steady state (the first run compiles: up to a minute)...")
    run = simulate(setup.machine, setup.operating, method=options.method, steps=options.steps)
    result = summary(run)
    if ns.out:
        paths = write_run(ns.out, result, run.series, figures=not ns.no_figures)
        _status(f"wrote {len(paths)} files to {ns.out}")
    if ns.json:
        print(dumps(result))
    else:
        print("jaxdobby simulate: periodic steady state of one heald-frame cycle\n")
        print(summary_table(result))
    return 0 if result["converged"] else 1


def _sweep(ns: argparse.Namespace) -> int:
    import json as _json

    from .io import write_text
    from .plots import overlay_figure, plt
    from .sweep import STUDIES, csv_table, markdown_table, prepare_sweep, trend_figure

    setup, options = setup_from_args(ns)
    values = ns.values if ns.values else STUDIES.get(ns.parameter)
    if values is None:
        raise InputError(f"no default values for '{ns.parameter}': give them with --values")
    sweep = prepare_sweep(setup, ns.parameter, values, method=options.method)
    _status(f"sweeping {ns.parameter} over {len(values)} values (the first run compiles)...")
    result = sweep()
    if ns.out:
        out = Path(ns.out)
        out.mkdir(parents=True, exist_ok=True)
        write_text(out / "sweep.csv", csv_table(result))
        write_text(out / "sweep.md", markdown_table(result))
        label = lambda v: f"{result.parameter} = {v:g} {result.unit}".strip()  # noqa: E731
        runs = {label(v): series for v, series in zip(result.values, result.series)}
        for quantity in ("deviation", "velocity_deviation", "acceleration_flexible"):
            fig = overlay_figure(runs, quantity, title=f"{quantity.replace('_', ' ')} by "
                                                       f"{result.parameter}")
            fig.savefig(out / f"sweep_{quantity}.png", dpi=120)
            plt.close(fig)
        fig = trend_figure(result)
        fig.savefig(out / "sweep_trends.png", dpi=120)
        plt.close(fig)
        _status(f"wrote the table and figures to {out}")
    if ns.json:
        print(_json.dumps({"parameter": result.parameter, "unit": result.unit,
                           "values": result.values, "runs": result.rows}, indent=2))
    else:
        print(markdown_table(result))
    return 0 if all(r["converged"] for r in result.rows) else 1


def _status(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _beam(ns: argparse.Namespace) -> int:
    from .report import beam_report

    if not 1 <= ns.modes <= 30:
        raise InputError(f"--modes = {ns.modes} is outside the valid range (an integer 1…30)")
    print(beam_report(n_modes=ns.modes))
    return 0


def _add_optimize_arguments(p: argparse.ArgumentParser) -> None:
    from .optimize.command import add_arguments

    add_arguments(p)


def _optimize(ns: argparse.Namespace) -> int:
    from .optimize.command import run

    return run(ns)


def _identify(ns: argparse.Namespace) -> int:
    from .identify.command import run

    return run(ns, setup_from_args)


def _sobol(argv: Sequence[str]) -> int:
    from .sensitivity.command import main as sobol_main

    return sobol_main(argv)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxdobby",
        description="Differentiable simulator of the rigid-flexible lifting mechanism of a "
                    "rotary dobby.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    sim = sub.add_parser("simulate", help="one steady-state run (the default machine by default)")
    _add_model_arguments(sim)
    sim.add_argument("--out", metavar="DIR", help="write summary.json, timeseries.csv, figures")
    sim.add_argument("--json", action="store_true", help="print the summary as JSON")
    sim.add_argument("--no-figures", action="store_true", help="with --out: skip the figures")
    sim.set_defaults(run=_simulate)
    sweep = sub.add_parser("sweep", help="one-at-a-time study of one parameter (vmapped)",
                           description="Default values: modes 1-8; speed 400-1200 r/min; "
                                       "warp_force 690 1380 2760 N; stroke 140 115 80 mm; "
                                       "thickness 6 7 8 mm. Any parameter of the configuration "
                                       "file can be swept with --values.")
    sweep.add_argument("parameter", help="modes, speed, warp_force, stroke, thickness, or any "
                                         "parameter name of the registry")
    sweep.add_argument("--values", type=float, nargs="+", metavar="V",
                       help="values in the parameter's unit (default: the source study's)")
    _add_model_arguments(sweep)
    sweep.add_argument("--out", metavar="DIR", help="write sweep.csv, sweep.md and figures")
    sweep.add_argument("--json", action="store_true", help="print the rows as JSON")
    sweep.set_defaults(run=_sweep)
    opt = sub.add_parser("optimize", help="gradient-based design of the bending arm",
                         description="Minimise the heald-frame deviation (or another steady-state "
                                     "metric) over the arm's design variables with exact "
                                     "gradients, bounds and constraints.")
    _add_optimize_arguments(opt)
    opt.set_defaults(run=_optimize)
    beam = sub.add_parser("beam", help="natural frequencies of the default bending arm")
    beam.add_argument("--modes", type=int, default=8, help="number of modes to list (1-30)")
    beam.set_defaults(run=_beam)
    ident = sub.add_parser("identify", help="fit machine parameters to a measured heald-frame "
                                            "trace (least squares through the steady state)")
    _add_model_arguments(ident)
    from .identify.command import add_arguments as add_identify_arguments

    add_identify_arguments(ident)
    ident.set_defaults(run=_identify)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxdobby`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    _configure_jax()
    if argv and argv[0] == "sobol":
        return _sobol(argv[1:])
    parser = build_parser()
    ns = parser.parse_args(argv)
    try:
        return ns.run(ns)
    except InputError as err:
        print(f"jaxdobby {ns.command}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
