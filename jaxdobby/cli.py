"""The ``jaxdobby`` command line.

Commands (``jaxdobby COMMAND --help`` for each):

* ``simulate`` — one run of the mechanism at an operating point (the default machine with no
  arguments): summary table, ``--json``, ``--out DIR`` for CSV/JSON/figures;
* ``sweep`` — the source study's one-at-a-time parameter studies;
* ``sobol`` — Sobol sensitivity indices from batched, sharded runs;
* ``optimize`` — gradient-based design of the bending arm;
* ``beam`` — the natural frequencies and mode shapes of the default bending arm;
* ``campbell`` — the resonance map (coupled frequencies, pick-rate harmonics, deviation).
* ``identify`` — fit parameters of the machine to a measured heald-frame trace.

The command line speaks the users' units (mm, r/min, N) and converts to SI at this boundary.
It is the only place that switches JAX to float64 and the only place that prints. Bad input
ends with one line naming the field and its valid range, and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from collections.abc import Sequence

from .command_line import (  # noqa: F401  (re-exported: the tests and scripts use them)
    EXIT_BAD_INPUT,
    EXIT_SOLVER_FAILURE,
    _add_model_arguments,
    _configure_jax,
    _status,
    programs_dir,
    setup_from_args,
)
from .errors import InputError

def _simulate(ns: argparse.Namespace) -> int:
    from .pictures.command import simulate_pictures
    from .report import dumps, summary_table, write_run
    from .simulate import simulate, stored_report
    from .validity import failure, warning_lines

    setup, options = setup_from_args(ns)
    pictures = simulate_pictures(ns)  # checks the picture flags before the run
    if ns.lift_plan is not None:
        from .weave.plan import parse_plan

        parse_plan(ns.lift_plan, field="--lift-plan")
        options.lift_plan = ns.lift_plan.strip()
    _status("solving the periodic steady state (a first run of a configuration compiles it)...")
    result, series, stress = stored_report(setup, options, directory=programs_dir())
    reason = failure(result)
    if reason is not None:
        print(f"jaxdobby simulate: {reason}", file=sys.stderr)
        return EXIT_SOLVER_FAILURE
    if ns.out:
        pick = None
        if "lift_plan" in result:
            from .weave.metrics import pick_of

            pick = pick_of(series.t, series.t[-1], result["picks"],
                           float(setup.machine.chain.dwell))
        paths = write_run(ns.out, result, series, figures=not ns.no_figures, pick=pick,
                          stress=stress)
        _status(f"wrote {len(paths)} files to {ns.out}")

    def run():  # the animation needs the whole run (modes, shapes): solved again, in Python
        return simulate(setup.machine, setup.operating, method=options.method,
                        steps=options.steps, lift_plan=getattr(options, "lift_plan", None))

    for path in pictures(setup.machine, run):  # the drawing (--out), the animation (--animate)
        _status(f"wrote {path}")
    if ns.json:
        print(dumps(result))
    else:
        print("jaxdobby simulate: " + ("static equilibrium, the frame never moves"
                                       if result.get("static") else
                                       "periodic steady state of one heald-frame cycle")
              + (f" (lift plan {result['lift_plan']}, repeat of {result['picks']} picks)"
                 if "lift_plan" in result else "") + "\n")
        print(summary_table(result))
        if result["warnings"]:
            print("\n" + warning_lines(result["warnings"]))
    return 0 if result["converged"] else EXIT_SOLVER_FAILURE


def _sweep(ns: argparse.Namespace) -> int:
    import json as _json

    from .io import write_text
    from .plots import overlay_figure, plt
    from .sweep import STUDIES, csv_table, markdown_table, prepare_sweep, trend_figure
    from .validity import tally, tally_lines

    setup, options = setup_from_args(ns)
    values = ns.values if ns.values else STUDIES.get(ns.parameter)
    if values is None:
        raise InputError(f"no default values for '{ns.parameter}': give them with --values")
    sweep = prepare_sweep(setup, ns.parameter, values, method=options.method,
                          directory=programs_dir())
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
    warned = tally((f"{v:g}", r["warnings"]) for v, r in zip(result.values, result.rows))
    if ns.json:
        print(_json.dumps({"parameter": result.parameter, "unit": result.unit,
                           "values": result.values, "runs": result.rows, "warnings": warned},
                          indent=2))
    else:
        print(markdown_table(result))
        if warned:
            print(f"\nvalidity warnings, by {result.parameter} [{result.unit}] (each run's "
                  "in --json):\n" + tally_lines(warned, len(result.rows)))
    return 0 if all(r["converged"] for r in result.rows) else 1


def _loom(ns: argparse.Namespace) -> int:
    from .weave.command import run

    return run(ns, setup_from_args)


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


def _pictures_command():
    from .pictures import command

    return command


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxdobby",
        description="Differentiable simulator of the rigid-flexible lifting mechanism of a "
                    "rotary dobby.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    sim = sub.add_parser("simulate", help="one steady-state run (the default machine by default)")
    _add_model_arguments(sim)
    sim.add_argument("--lift-plan", metavar="0/1...",
                     help="the frame's lift sequence over the repeat, one 0/1 per pick (1 = up "
                          "in that pick's shed), e.g. 1100 (default 10: plain weave)")
    sim.add_argument("--out", metavar="DIR", help="write summary.json, timeseries.csv, figures")
    sim.add_argument("--json", action="store_true", help="print the summary as JSON")
    sim.add_argument("--no-figures", action="store_true", help="with --out: skip the figures")
    _pictures_command().add_simulate_arguments(sim)
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
    camp = sub.add_parser("campbell", help="resonance map: coupled frequencies, pick-rate "
                          "harmonics and the deviation against loom speed")
    _pictures_command().add_campbell_arguments(camp)
    camp.set_defaults(run=_pictures_command().run_campbell)
    loom = sub.add_parser("loom", help="a weave on the whole frame set (vmapped): dwell "
                                       "vibration per frame and pick",
                          description="Every frame of a weave (a WIF file or --weave) over the "
                                      "repeat, in one vmapped batch; strokes by the clean-shed "
                                      "rule H_i = H_1 L_i/L_1 or --strokes.")
    from .weave.command import add_arguments as _loom_arguments

    _loom_arguments(loom)
    for flag, kw in (("--speed", dict(type=float, metavar="RPM", help="loom speed [r/min]")),
                     ("--warp-force", dict(type=float, metavar="N", help="peak warp force [N]")),
                     ("--thickness", dict(type=float, metavar="MM", help="arm thickness [mm]")),
                     ("--modes", dict(type=int, metavar="K", help="modes of the arm, 1-30")),
                     ("--config", dict(metavar="FILE.toml", help="configuration file"))):
        loom.add_argument(flag, **kw)
    loom.set_defaults(run=_loom, stroke=None, coupling=None, warp_law=None, method=None)
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


def _attach_negative_values(argv: list[str]) -> list[str]:
    """``--speed -1e-3`` as ``--speed=-1e-3``: argparse takes a value that starts with '-' and
    is not a plain decimal (``-1e-3``, ``-inf``) for an option and fails with a usage message;
    attached, it reaches the range check, which names the field."""
    out, i = [], 0
    while i < len(argv):
        if argv[i] in SINGLE_VALUE_FLAGS and i + 1 < len(argv) and argv[i + 1].startswith("-"):
            try:
                float(argv[i + 1])
            except ValueError:
                pass
            else:
                out.append(f"{argv[i]}={argv[i + 1]}")
                i += 2
                continue
        out.append(argv[i])
        i += 1
    return out


SINGLE_VALUE_FLAGS = ("--speed", "--warp-force", "--stroke", "--thickness", "--modes")


EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT, as shells report it)."""


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxdobby`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    _configure_jax()
    if argv and argv[0] == "sobol":
        return _sobol(argv[1:])
    parser = build_parser()
    ns = parser.parse_args(_attach_negative_values(argv))
    try:
        return ns.run(ns)
    except InputError as err:
        print(f"jaxdobby {ns.command}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's status for SIGINT
        print(f"jaxdobby {ns.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
