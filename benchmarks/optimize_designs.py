"""Optimised bending-arm designs and their improvement over the default machine.

Three design problems, each optimised at 800 r/min and, separately, at 1200 r/min (objective:
the smooth peak-to-peak heald-frame deviation at that speed, ``jaxdobby optimize``'s default):

* ``thickness`` — plate thickness alone (4–8 mm, 8 = pitch − clearance), no constraint;
* ``thickness+mass`` — the same with an arm-mass budget (default 0.48 kg; the default 6 mm arm
  is 0.423 kg);
* ``depth+mass`` — the in-plane depth at the five default control points (20–80 mm), thickness
  6 mm, arm mass ≤ the default (uniform 40 mm) arm's.

Every optimised design, and the default machine, is then run by :func:`jaxdobby.simulate` (the
modal model of ``jaxdobby simulate``, each design on its own modes) at both speeds with the same
collocation step count, and the improvement of the peak-to-peak deviation over the default machine is
tabulated. Writes ``optimize_designs.json`` and ``optimize_designs.md``.

Results are written after every optimisation; ``--resume`` keeps the rows already in
``optimize_designs.json`` (or, with ``--rows-from LOG``, the JSON rows a previous run printed)
and runs only the missing ones. Compilations go to jaxdobby's persistent cache
(``JAXDOBBY_CACHE_DIR``).

Run:  python benchmarks/optimize_designs.py [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from jaxdobby.cli import _configure_jax

_configure_jax()  # float64 and the persistent compilation cache, before anything compiles

import jax

from jaxdobby import OperatingPoint, simulate
from jaxdobby.periodic import DEFAULT_STEPS
from jaxdobby.optimize import Constraints, DesignSpace, Objective, Settings
from jaxdobby.optimize.study import Study, run_study
from jaxdobby.parameters import Setup

RPM = math.pi / 30.0
SPEEDS_RPM = (800.0, 1200.0)


def problems(mass_budget: float) -> dict[str, tuple[list[str], Constraints, int, int]]:
    """name → (variables, constraints, optimiser iterations, starting designs scanned)."""
    default_mass = float(Setup().machine.arm.mass())
    return {
        # the thickness objective has local minima between resonances: scan 10 starts first
        "thickness": (["thickness"], Constraints(), 15, 10),
        "thickness+mass": (["thickness"], Constraints(mass_budget=mass_budget), 30, 1),
        "depth+mass": (["depth"], Constraints(mass_budget=default_mass), 40, 1),
    }


def deviation_pp_mm(setup: Setup, speed_rpm: float, steps: int) -> float:
    """True peak-to-peak deviation [mm] of ``setup`` on its own modes (``jaxdobby simulate``)."""
    run = simulate(setup.machine, OperatingPoint.from_users_units(speed_rpm=speed_rpm),
                   steps=steps)
    assert bool(run.converged), f"steady state not converged at {speed_rpm} r/min"
    return float(run.metrics["deviation_pp"]) * 1e3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--mass-budget", type=float, default=0.48, help="kg, thickness+mass")
    ap.add_argument("--only", nargs="*", help="problem names to run (default: all)")
    ap.add_argument("--iterations", type=int, help="cap on the optimiser's iterations "
                    "(default: 15, 30, 40 by problem)")
    ap.add_argument("--resume", action="store_true", help="keep the rows already written")
    ap.add_argument("--rows-from", metavar="LOG", help="with --resume: take the rows from the "
                    "JSON lines a previous run printed")
    ns = ap.parse_args()
    out_dir = Path(ns.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    if ns.resume:
        if ns.rows_from:
            rows = [json.loads(line) for line in Path(ns.rows_from).read_text().splitlines()
                    if line.startswith('{"problem"')]
        elif (out_dir / "optimize_designs.json").exists():
            rows = json.loads((out_dir / "optimize_designs.json").read_text())["rows"]
    done = {(r["problem"], r["optimised_at_rpm"]) for r in rows}
    baseline: dict[tuple[float, int], float] = {}
    for name, (variables, limits, iterations, starts) in problems(ns.mass_budget).items():
        if ns.only and name not in ns.only:
            continue
        if ns.iterations:
            iterations = min(iterations, ns.iterations)
        space = DesignSpace.create(Setup(), variables)
        # The collocation grid is phase-normalised: one step count for every speed and design,
        # so the gradient compiles once for both speeds.
        steps = DEFAULT_STEPS
        for speed in SPEEDS_RPM:
            if (name, speed) in done:
                continue
            t0 = time.perf_counter()
            out = run_study(Study(space=space, objective=Objective(speeds=(speed * RPM,)),
                                  limits=limits, steps=steps, starts=starts,
                                  settings=Settings(optimizer="lbfgs", steps=iterations,
                                                    tolerance=1e-5)),
                            progress=lambda line: print("   ", line, flush=True))
            s = out.summary
            row = {"problem": name, "optimised_at_rpm": speed, "cycle_steps": steps,
                   "design": s["optimised"]["design"],
                   "arm_mass_kg": s["optimised"]["arm_mass_kg"],
                   "first_frequency_hz": s["optimised"]["first_frequency_hz"],
                   "mass_budget_kg": limits.mass_budget, "starts": starts,
                   "iterations": s["iterations"], "evaluations": s["evaluations"],
                   "converged": s["converged"], "optimality": s["optimality"],
                   "study_deviation_pp_mm": s["per_speed"][0]["optimised"]["deviation_pp_mm"],
                   "seconds": time.perf_counter() - t0, "at": {}}
            for rpm in SPEEDS_RPM:
                if (rpm, steps) not in baseline:
                    baseline[(rpm, steps)] = deviation_pp_mm(Setup(), rpm, steps)
                base = baseline[(rpm, steps)]
                opt = deviation_pp_mm(out.setup, rpm, steps)
                row["at"][f"{rpm:g}"] = {"default_deviation_pp_mm": base,
                                         "deviation_pp_mm": opt,
                                         "improvement_percent": 100.0 * (1.0 - opt / base)}
            rows.append(row)
            print(json.dumps(row), flush=True)
            write(out_dir, rows)
    write(out_dir, rows)
    print(markdown(rows))


def write(out_dir: Path, rows: list[dict]) -> None:
    order = list(problems(0.0))
    rows.sort(key=lambda r: (order.index(r["problem"]), r["optimised_at_rpm"]))
    (out_dir / "optimize_designs.json").write_text(json.dumps(
        {"device": str(jax.devices()[0]), "speeds_rpm": SPEEDS_RPM, "rows": rows}, indent=2))
    (out_dir / "optimize_designs.md").write_text(markdown(rows))


def markdown(rows: list[dict]) -> str:
    """The table of the markdown file (generated; do not edit by hand)."""
    lines = [
        "# Optimised bending-arm designs (generated by benchmarks/optimize_designs.py)",
        "",
        ("Each problem optimised (projected L-BFGS; the mass budget held by projection) at "
         "one speed; every design then run by `jaxdobby.simulate` (own modes, same collocation steps) at "
         "both speeds. Deviation = peak-to-peak heald-frame displacement deviation; improvement "
         "= 1 − deviation / default machine's deviation (positive is better)."),
        "",
        ("| problem | optimised at [r/min] | design | arm mass [kg] (budget) | f₁ [Hz] | "
         "dev. at 800 [mm] (default) | improvement at 800 | dev. at 1200 [mm] (default) | "
         "improvement at 1200 | iterations | converged |"),
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        design = ", ".join(f"{k.replace('_mm', '')} {v:.2f}" for k, v in r["design"].items())
        budget = "—" if r["mass_budget_kg"] is None else f"{r['mass_budget_kg']:.4f}"
        cells = [r["problem"], f"{r['optimised_at_rpm']:g}", design + " mm",
                 f"{r['arm_mass_kg']:.4f} ({budget})", f"{r['first_frequency_hz']:.1f}"]
        for rpm in ("800", "1200"):
            a = r["at"][rpm]
            cells += [f"{a['deviation_pp_mm']:.3f} ({a['default_deviation_pp_mm']:.3f})",
                      f"{a['improvement_percent']:+.1f} %"]
        cells += [str(r["iterations"]), "yes" if r["converged"] else "no"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
