"""The ``jaxdobby optimize`` command: its options, the problem file, and the run.

Everything can be given by flags or in a problem file (``--problem FILE.toml``; flags win)::

    [objective]
    metric = "deviation"          # deviation | deviation_rms | acceleration
    speeds_rpm = [800, 1000, 1200]
    aggregate = "worst"           # worst | mean over the speeds
    acceleration_weight = 0.0     # adds w × acceleration amplitude (normalised)

    [variables]
    names = ["thickness", "depth"]
    thickness_mm = [4.0, 8.0]     # bounds, users' units
    depth_mm = [20.0, 80.0]
    depth_positions_mm = [0.0, 80.0, 140.0, 201.0, 226.0]

    [constraints]
    mass_budget_kg = 0.45
    frequency_floor_hz = 100.0
    stress_limit_mpa = 400.0       # peak stress over the cycle (smooth surrogate)
    fatigue_floor = 1.5            # Goodman safety factor of the arm
    pitch_mm = 12.0               # thickness <= pitch - clearance
    clearance_mm = 4.0

    [optimizer]
    name = "lbfgs"                # lbfgs | adam
    steps = 20
    learning_rate = 0.05          # adam
    inner_steps = 5
    penalty = 10.0
    tolerance = 1e-4
    gradient = "auto"             # auto | forward | reverse
    cycle_steps = 432             # optional; collocation steps per cycle
    starts = 10                   # scan that many starting designs in one batch first (1: local)

The starting machine is the default one, or ``--config FILE.toml`` (the ``simulate`` format).
Bad input ends with one line naming the field and its valid range (exit status 2).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tomllib
from pathlib import Path

from ..errors import InputError, check_range

DEFAULT_STARTS = 10
"""Starting designs the command scans by default: the given one and nine spread over the bounds
(one vmapped batch). From the default 6 mm arm a single start stops in the valley at 7.15 mm
(a resonance of the frame-on-arm mode with a pick harmonic near 7.35 mm); ten reach the 8 mm
bound the README reports (``tests/test_optimize_studies.py``)."""

PROBLEM_KEYS = {
    "objective": ("metric", "speeds_rpm", "aggregate", "acceleration_weight"),
    "variables": ("names", "thickness_mm", "depth_mm", "depth_positions_mm", "arc_radius_mm",
                  "heald_frame_mass_kg", "blade_inertia_kg_m2"),
    "constraints": ("mass_budget_kg", "frequency_floor_hz", "stress_limit_mpa", "fatigue_floor",
                    "pitch_mm", "clearance_mm"),
    "optimizer": ("name", "steps", "learning_rate", "inner_steps", "penalty", "tolerance",
                  "gradient", "cycle_steps", "starts"),
}
"""Valid tables and keys of a problem file."""

BOUND_KEYS = {"thickness": "thickness_mm", "depth": "depth_mm", "arc_radius": "arc_radius_mm",
              "heald_frame_mass": "heald_frame_mass_kg", "blade_inertia": "blade_inertia_kg_m2"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``jaxdobby optimize``."""
    g = p.add_argument_group("problem")
    g.add_argument("--problem", metavar="FILE.toml", help="problem file (see the docs); flags win")
    g.add_argument("--objective", choices=["deviation", "deviation_rms", "acceleration"],
                   help="metric to minimise (default deviation: its peak-to-peak)")
    g.add_argument("--speeds", metavar="RPM[,RPM...]",
                   help="loom speed(s) [r/min], one batch (default 800)")
    g.add_argument("--aggregate", choices=["worst", "mean"], help="over the speeds (default worst)")
    g.add_argument("--acceleration-weight", type=float, metavar="W",
                   help="add W × the acceleration amplitude (normalised; default 0)")
    g.add_argument("--vars", metavar="NAME[,NAME...]",
                   help="design variables: thickness, depth, arc_radius, heald_frame_mass, "
                        "blade_inertia (default thickness)")
    g.add_argument("--bounds", metavar="NAME=LO:HI[,...]",
                   help="bounds in users' units, e.g. thickness=4:8,depth=20:80")
    g.add_argument("--depth-positions", metavar="MM[,MM...]",
                   help="arc lengths of the depth control points [mm]")
    g.add_argument("--mass-budget", type=float, metavar="KG", help="largest arm mass [kg]")
    g.add_argument("--frequency-floor", type=float, metavar="HZ",
                   help="smallest first coupled natural frequency [Hz]")
    g.add_argument("--stress-limit", type=float, metavar="MPA",
                   help="largest peak stress in the arm over the cycle [MPa] (smooth surrogate)")
    g.add_argument("--fatigue-floor", type=float, metavar="N",
                   help="smallest Goodman fatigue safety factor of the arm (smooth surrogate)")
    g.add_argument("--pitch", type=float, metavar="MM", help="pitch between arms [mm] (12)")
    g.add_argument("--clearance", type=float, metavar="MM", help="clearance [mm] (4)")
    o = p.add_argument_group("optimiser")
    o.add_argument("--optimizer", choices=["lbfgs", "adam"], help="default lbfgs")
    o.add_argument("--steps", type=int, metavar="N", help="iterations (default 20)")
    o.add_argument("--learning-rate", type=float, metavar="LR", help="adam (default 0.05)")
    o.add_argument("--inner-steps", type=int, metavar="N",
                   help="iterations between multiplier updates (default 5)")
    o.add_argument("--penalty", type=float, metavar="RHO", help="initial penalty (default 10)")
    o.add_argument("--tolerance", type=float, metavar="TOL",
                   help="projected-gradient tolerance (default 1e-4)")
    o.add_argument("--gradient", choices=["auto", "forward", "reverse"], help="default auto")
    o.add_argument("--cycle-steps", type=int, metavar="N",
                   help="collocation steps per cycle (default 432)")
    o.add_argument("--starts", type=int, metavar="K",
                   help="evaluate K starting designs (the given one, then a grid or a Sobol "
                        "sequence over the bounds) in one vmapped batch and optimise from the "
                        f"best (default {DEFAULT_STARTS}: the objective has local minima between "
                        "resonances; --starts 1 optimises locally from the given design)")
    m = p.add_argument_group("machine")
    m.add_argument("--config", metavar="FILE.toml", help="starting machine (simulate format)")
    m.add_argument("--warp-force", type=float, metavar="N", help="peak warp force [N]")
    m.add_argument("--stroke", type=float, metavar="MM", help="heald-frame stroke [mm]")
    m.add_argument("--thickness", type=float, metavar="MM", help="starting thickness [mm]")
    r = p.add_argument_group("output")
    r.add_argument("--out", metavar="DIR", help="write history, result, design.toml, figures")
    r.add_argument("--json", action="store_true", help="print the result as JSON")
    r.add_argument("--no-figures", action="store_true", help="with --out: skip the figures")


def _read_problem(path) -> dict:
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"problem file {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read problem file {path}: {err}") from None
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"problem file {path} is not valid TOML: {err}") from None
    for table, keys in data.items():
        if table not in PROBLEM_KEYS:
            raise InputError(f"unknown table [{table}] in the problem file: valid tables are "
                             + ", ".join(f"[{t}]" for t in PROBLEM_KEYS))
        if not isinstance(keys, dict):
            raise InputError(f"[{table}] must be a table of key = value pairs")
        for key in keys:
            if key not in PROBLEM_KEYS[table]:
                raise InputError(f"unknown key '{key}' in [{table}]: valid keys are "
                                 + ", ".join(PROBLEM_KEYS[table]))
    return data


def _number_list(text: str, where: str) -> list[float]:
    try:
        out = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"{where} must be a comma-separated list of numbers, got {text!r}") \
            from None
    if not out:
        raise InputError(f"{where} must not be empty")
    return out


def _parse_bounds(text: str) -> dict[str, list[float]]:
    out = {}
    for item in text.split(","):
        name, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        try:
            out[name.strip()] = [float(lo), float(hi)]
        except ValueError:
            raise InputError(f"--bounds: '{item}' must read NAME=LOW:HIGH, e.g. "
                             "thickness=4:8") from None
        if not (sep and sep2):
            raise InputError(f"--bounds: '{item}' must read NAME=LOW:HIGH")
    return out


def _int(value, where, low, high) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise InputError(f"{where} = {value!r} is outside the valid range (an integer "
                         f"{low}…{high})")
    return value


def build_study(ns: argparse.Namespace):
    """The :class:`~jaxdobby.optimize.study.Study` described by the flags and problem file."""
    import jax.numpy as jnp

    from ..command_line import setup_from_args
    from .design import VARIABLES, Constraints, DesignSpace
    from .loop import Settings
    from .objective import Objective
    from .study import Study, speeds_from_rpm

    problem = _read_problem(ns.problem) if ns.problem else {}
    obj, var, con, opt = (problem.get(t, {}) for t in PROBLEM_KEYS)

    def pick(flag, table, key, default):
        return flag if flag is not None else table.get(key, default)

    metric = pick(ns.objective, obj, "metric", "deviation")
    if metric not in ("deviation", "deviation_rms", "acceleration"):
        raise InputError(f"[objective] metric = {metric!r} is not valid: use deviation, "
                         "deviation_rms or acceleration")
    speeds = (_number_list(ns.speeds, "--speeds") if ns.speeds is not None
              else obj.get("speeds_rpm", [800.0]))
    if not isinstance(speeds, list) or not speeds:
        raise InputError("[objective] speeds_rpm must be a list of speeds [r/min]")
    for s in speeds:
        check_range("speed", s, 0.0, unit="r/min")
    aggregate = pick(ns.aggregate, obj, "aggregate", "worst")
    if aggregate not in ("worst", "mean"):
        raise InputError(f"[objective] aggregate = {aggregate!r} is not valid: use worst or mean")
    weight = check_range("acceleration weight", pick(ns.acceleration_weight, obj,
                                                     "acceleration_weight", 0.0), 0.0,
                         low_open=False)

    names = (ns.vars.split(",") if ns.vars is not None else var.get("names", ["thickness"]))
    names = [n.strip() for n in names]
    bounds = {n: var[BOUND_KEYS[n]] for n in BOUND_KEYS if BOUND_KEYS[n] in var}
    if ns.bounds:
        bounds.update(_parse_bounds(ns.bounds))
    for name, b in bounds.items():
        if name not in VARIABLES:
            raise InputError(f"bounds given for unknown design variable '{name}': valid are "
                             + ", ".join(VARIABLES))
        if (not isinstance(b, list) or len(b) != 2
                or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in b)):
            raise InputError(f"bounds of {name} must be [lower, upper] in "
                             f"{VARIABLES[name][0]}")
    positions = (_number_list(ns.depth_positions, "--depth-positions")
                 if ns.depth_positions is not None else var.get("depth_positions_mm"))

    mass_budget = pick(ns.mass_budget, con, "mass_budget_kg", None)
    floor = pick(ns.frequency_floor, con, "frequency_floor_hz", None)
    if mass_budget is not None:
        check_range("mass budget", mass_budget, 0.0, unit="kg")
    if floor is not None:
        check_range("frequency floor", floor, 0.0, unit="Hz")
    stress_limit = pick(getattr(ns, "stress_limit", None), con, "stress_limit_mpa", None)
    fatigue_floor = pick(getattr(ns, "fatigue_floor", None), con, "fatigue_floor", None)
    if stress_limit is not None:
        check_range("stress limit", stress_limit, 0.0, unit="MPa")
    if fatigue_floor is not None:
        check_range("fatigue floor", fatigue_floor, 0.0)
    pitch = check_range("pitch", pick(ns.pitch, con, "pitch_mm", 12.0), 0.0, unit="mm")
    clearance = check_range("clearance", pick(ns.clearance, con, "clearance_mm", 4.0), 0.0,
                            pitch, unit="mm", low_open=False, high_open=True)

    optimizer = pick(ns.optimizer, opt, "name", "lbfgs")
    if optimizer not in ("lbfgs", "adam"):
        raise InputError(f"[optimizer] name = {optimizer!r} is not valid: use lbfgs or adam")
    settings = Settings(
        optimizer=optimizer,
        steps=_int(pick(ns.steps, opt, "steps", 20), "--steps", 0, 10_000),
        learning_rate=check_range("learning rate", pick(ns.learning_rate, opt, "learning_rate",
                                                        0.05), 0.0, 1.0),
        inner_steps=_int(pick(ns.inner_steps, opt, "inner_steps", 5), "--inner-steps", 1, 1000),
        penalty=check_range("penalty", pick(ns.penalty, opt, "penalty", 10.0), 0.0),
        tolerance=check_range("tolerance", pick(ns.tolerance, opt, "tolerance", 1e-4), 0.0, 1.0))
    gradient = pick(ns.gradient, opt, "gradient", "auto")
    if gradient not in ("auto", "forward", "reverse"):
        raise InputError(f"[optimizer] gradient = {gradient!r} is not valid: use auto, forward "
                         "or reverse")
    starts = _int(pick(ns.starts, opt, "starts", DEFAULT_STARTS), "--starts", 1, 4096)
    cycle_steps = pick(ns.cycle_steps, opt, "cycle_steps", None)
    if cycle_steps is not None:
        cycle_steps = _int(cycle_steps, "--cycle-steps", 72, 100_000)

    sim_ns = argparse.Namespace(config=ns.config, speed=None, warp_force=ns.warp_force,
                                stroke=ns.stroke, thickness=ns.thickness, modes=None,
                                coupling=None, warp_law=None, method=None)
    base, _ = setup_from_args(sim_ns)
    space = DesignSpace.create(base, names, bounds=bounds, depth_positions_mm=positions,
                               pitch_mm=pitch, clearance_mm=clearance)
    _check_start(space, jnp)
    objective = Objective(metric=metric, speeds=speeds_from_rpm(speeds), aggregate=aggregate,
                          acceleration_weight=weight)
    return Study(space=space, objective=objective,
                 limits=Constraints(mass_budget=mass_budget, frequency_floor=floor,
                                    stress_limit=None if stress_limit is None
                                    else float(stress_limit) * 1e6,
                                    fatigue_floor=None if fatigue_floor is None
                                    else float(fatigue_floor),
                                    speeds=speeds_from_rpm(speeds)),
                 settings=settings, gradient=gradient, steps=cycle_steps, starts=starts)


def default_study():
    """The :class:`~jaxdobby.optimize.study.Study` of a plain ``jaxdobby optimize`` (every flag
    at its default)."""
    p = argparse.ArgumentParser()
    add_arguments(p)
    return build_study(p.parse_args([]))


def default_evaluator(directory=None, ship=None):
    """(the :class:`~jaxdobby.optimize.objective.Evaluator` of :func:`default_study`, the
    study); ``directory``, ``ship``: as the evaluator's."""
    from .objective import Evaluator

    study = default_study()
    return Evaluator(study.space, study.objective, steps=study.steps, mode=study.gradient,
                     directory=directory, ship=ship), study


def ship_programs(directory) -> None:
    """Compile the programs of a plain ``jaxdobby optimize`` into ``directory`` (traced
    programs and executables; ``python -m jaxdobby.programs``), running each once."""
    import numpy as np

    from .study import start_candidates

    evaluator, study = default_evaluator(directory, ship=directory)  # compiles the values
    if study.starts > 1:
        evaluator.values_many(start_candidates(np.asarray(study.space.initial), study.starts))
    evaluator.value_and_grad(study.space.initial)


def _check_start(space, jnp) -> None:
    """The starting design must lie in the box (it is not moved silently)."""
    import numpy as np

    p = np.asarray(space.values(space.base))
    lo, hi = np.asarray(space.lower), np.asarray(space.upper)
    for label, (unit, scale), v, a, b in zip(space.labels(), space.units(), p, lo, hi):
        if not a - 1e-12 <= v <= b + 1e-12:
            raise InputError(f"starting {label} = {v / scale:g} {unit} is outside its bounds "
                             f"[{a / scale:g}, {b / scale:g}] {unit}")


def run(ns: argparse.Namespace) -> int:
    """Run ``jaxdobby optimize``; returns the exit status (0, or 1 if not converged)."""
    from ..command_line import programs_dir
    from .output import figures, write_outputs
    from .study import run_study

    study = build_study(ns)
    outcome = run_study(study, progress=lambda line: print(line, file=sys.stderr, flush=True),
                        programs=programs_dir())
    if ns.out:
        bounds = {f"{k}_{unit.replace(' ', '_')}": tuple(v) for (k, v), (unit, _) in
                  zip(outcome.summary["bounds"].items(), study.space.units())}
        figs = None if ns.no_figures else figures(outcome.history, list(study.limits.names),
                                                   outcome.profiles, outcome.deviations, bounds)
        paths = write_outputs(ns.out, outcome.history, outcome.summary, outcome.design_toml,
                              figs)
        print(f"wrote {len(paths)} files to {ns.out}", file=sys.stderr)
    if ns.json:
        print(json.dumps(outcome.summary, indent=2))
    else:
        print(summary_text(outcome.summary))
    ok = all(s["optimised"]["converged"] for s in outcome.summary["per_speed"])
    return 0 if ok else 1


def summary_text(summary: dict) -> str:
    """A readable table of the result."""
    lines = ["jaxdobby optimize: " + ", ".join(summary["variables"]) + " — "
             f"{summary['objective']['metric']} ({summary['objective']['aggregate']} over "
             f"{', '.join(f'{s:g}' for s in summary['objective']['speeds_rpm'])} r/min)", ""]
    lines.append(f"  {'variable':<24} {'start':>12} {'optimised':>12}")
    for key, v0 in summary["start"]["design"].items():
        lines.append(f"  {key:<24} {v0:>12.4f} {summary['optimised']['design'][key]:>12.4f}")
    for key, label in (("arm_mass_kg", "arm mass [kg]"),
                       ("first_frequency_hz", "first coupled freq. [Hz]"),
                       ("stroke_mm", "stroke [mm]")):
        lines.append(f"  {label:<24} {summary['start'][key]:>12.4f} "
                     f"{summary['optimised'][key]:>12.4f}")
    for key, label in (("stress_max_smooth_mpa", "peak stress smooth [MPa]"),
                       ("fatigue_safety_factor_smooth", "fatigue factor (smooth)")):
        if key in summary.get("stress", {}).get("optimised", {}):
            lines.append(f"  {label:<24} {summary['stress']['start'][key]:>12.4f} "
                         f"{summary['stress']['optimised'][key]:>12.4f}")
    lines.append("")
    lines.append(f"  {'speed [r/min]':<14} {'dev p-p start':>14} {'optimised':>10} "
                 f"{'change':>8}   (mm; modal model as in simulate)")
    for s in summary["per_speed"]:
        lines.append(f"  {s['speed_rpm']:<14g} {s['start']['deviation_pp_mm']:>14.4f} "
                     f"{s['optimised']['deviation_pp_mm']:>10.4f} "
                     f"{-s['improvement_percent']:>+7.1f}%")
    o = summary["optimality"]
    lines.append("")
    lines.append(f"  objective J {summary['objective_start']:.5f} → "
                 f"{summary['objective_optimised']:.5f} in {summary['iterations']} iterations "
                 f"({summary['evaluations']} gradient evaluations, "
                 f"{summary['gradient_mode']} mode)")
    lines.append(f"  optimality: projected gradient {o['projected_gradient']:.2e}, violation "
                 f"{o['violation']:.2e}, complementarity {o['complementarity']:.2e}; "
                 f"converged: {'yes' if summary['converged'] else 'no'}")
    if "warnings" in summary:
        lines += ["", _validity_text(summary)]
    return "\n".join(lines)


def _validity_text(summary: dict) -> str:
    """The optimised design's validity warnings (as ``jaxdobby simulate`` checks it), and the
    codes of the starting design's."""
    from ..validity import warning_lines

    start = sorted({w["code"] for s in summary["per_speed"] for w in s["start"]["warnings"]})
    lines = ["  validity of the optimised design (the checks of jaxdobby simulate): "
             + ("warnings below" if summary["warnings"] else "inside every limit")
             + f"; the starting design's: {', '.join(start) if start else 'none'}"]
    if summary["warnings"]:
        lines.append(warning_lines(summary["warnings"]))
    return "\n".join(lines)
