"""The arm designed with and without a fatigue constraint (``jaxdobby optimize --fatigue-floor``).

One design problem at 800 r/min: minimise the smooth peak-to-peak heald-frame deviation
(``jaxdobby optimize``'s default objective) over the plate thickness (4–8 mm) and the in-plane
depth at the five default control points (20–80 mm at 0/80/153/201/226 mm of arc length), the
arm's mass held at the default arm's (0.423 kg), from the default machine, one start, projected
L-BFGS with an augmented Lagrangian (the mass is bilinear in thickness and depth), solved

* ``mass`` — without a stress constraint, and
* ``mass+fatigue>=N`` — with the Goodman safety factor ≥ N at 800 r/min (the smooth surrogate
  of :mod:`jaxdobby.stress.design`), for each N of ``--fatigue-floors`` (default 1.5 and 2).

Both runs use a machined arm: surface factor k_a = 0.72 (1000 MPa, machined, Shigley Table 6-2)
and size factor k_b = 0.91 (6 × 40 mm in bending), so σ_e = 0.655 · 500 MPa ≈ 328 MPa (the
material factors change the fatigue factor only, not the dynamics or the deviation). Every
design (the start and both optima) is then run by :func:`jaxdobby.simulate` on its own modes
(the model of ``jaxdobby simulate``) at 800 and 1200 r/min, and its stress recovered
(:func:`jaxdobby.stress.run_stress`, mode acceleration): peak stress and where, the Goodman
factor for the machined arm and for a polished specimen (k_a = k_b = 1, the default material),
the deviation and the mass. Writes ``optimize_stress.json`` (read by notebook 06 and quoted by
the README) and ``optimize_stress.md``.

``--only mass`` / ``--only fatigue`` runs those problems and merges them into the JSON already
written (processes can run problems side by side); ``--evaluate-only`` recomputes the table
from the designs in the JSON.

Run:  python benchmarks/optimize_stress.py [--out benchmarks/results] [--iterations 30]

The committed results: ``--only mass --iterations 100``, then ``--only fatigue
--fatigue-floors 1.5 2 --iterations 30`` and ``--fatigue-floors 1.75`` (17–27 minutes of
compiling per floor on 2 heavily shared cores; 1.75 took 4.3 min in all on a quieter machine,
then a few seconds per iteration).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path

from jaxdobby.command_line import _configure_jax

_configure_jax()  # float64 and the persistent compilation cache, before anything compiles

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from jaxdobby import OperatingPoint, simulate  # noqa: E402
from jaxdobby.optimize import Constraints, DesignSpace, Objective, Settings  # noqa: E402
from jaxdobby.optimize.study import Study, run_study  # noqa: E402
from jaxdobby.parameters import Setup  # noqa: E402
from jaxdobby.stress import run_stress  # noqa: E402
from jaxdobby.stress.cycle import stress_metrics  # noqa: E402

RPM = math.pi / 30.0
SPEED_RPM = 800.0
CHECK_SPEEDS_RPM = (800.0, 1200.0)
MACHINED = {"surface_factor": 0.72, "size_factor": 0.91}
GROUPS = ("mass", "fatigue")


def machined_setup() -> Setup:
    """The default machine with the machined arm's Marin factors :data:`MACHINED`."""
    setup = Setup()
    arm = dataclasses.replace(setup.machine.arm, **MACHINED)
    return dataclasses.replace(setup, machine=dataclasses.replace(setup.machine, arm=arm))


def study(floor: float | None, iterations: int) -> Study:
    """The problem of the module docstring; ``floor``: the fatigue floor, or None (none)."""
    base = machined_setup()
    space = DesignSpace.create(base, ["thickness", "depth"])
    mass = float(base.machine.arm.mass())
    limits = Constraints(mass_budget=mass, fatigue_floor=floor, speeds=(SPEED_RPM * RPM,))
    return Study(space=space, objective=Objective(speeds=(SPEED_RPM * RPM,)), limits=limits,
                 starts=1, settings=Settings(optimizer="lbfgs", steps=iterations,
                                             tolerance=1e-4))


def evaluate(setup: Setup) -> dict:
    """Mass, deviation, peak stress and Goodman factors of ``setup`` at both check speeds."""
    arm = setup.machine.arm
    polished = dataclasses.replace(arm, surface_factor=1.0, size_factor=1.0)
    out = {"arm_mass_kg": float(arm.mass()), "at": {}}
    for rpm in CHECK_SPEEDS_RPM:
        run = simulate(setup.machine, OperatingPoint.from_users_units(speed_rpm=rpm))
        stress = run_stress(run)
        m = stress.metrics
        p = stress_metrics(stress.sigma, stress.arc_lengths, polished)
        out["at"][f"{rpm:g}"] = {
            "converged": bool(run.converged),
            "deviation_pp_mm": float(run.metrics["deviation_pp"]) * 1e3,
            "stress_max_mpa": float(m["stress_max"]) * 1e-6,
            "stress_max_position_mm": float(m["stress_max_position"]) * 1e3,
            "fatigue_safety_factor": float(m["fatigue_safety_factor"]),
            "fatigue_position_mm": float(m["fatigue_position"]) * 1e3,
            "fatigue_safety_factor_polished": float(p["fatigue_safety_factor"]),
        }
    return out


def design_setup(space: DesignSpace, design: dict) -> Setup:
    """The Setup of a design dict (users' units, as in a study summary)."""
    values = jnp.asarray([v for v in design.values()])
    scales = jnp.asarray([scale for _, scale in space.units()])
    lo, hi = space.lower, space.upper
    return space.setup((values * scales - lo) / (hi - lo))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--fatigue-floors", type=float, nargs="+", default=[1.5, 2.0])
    ap.add_argument("--iterations", type=int, default=30)
    ap.add_argument("--only", choices=GROUPS)
    ap.add_argument("--evaluate-only", action="store_true")
    ns = ap.parse_args()
    out_dir = Path(ns.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "optimize_stress.json"
    data = json.loads(path.read_text()) if path.exists() else {"rows": {}}
    data.update({"speed_rpm": SPEED_RPM, "variables": ["thickness", "depth"],
                 "material_factors": MACHINED, "device": str(jax.devices()[0])})
    data.pop("fatigue_floor", None)
    problems = [("mass", None)] + [(f"mass+fatigue>={f:g}", f) for f in ns.fatigue_floors]
    for name, floor in problems:
        if ns.evaluate_only or (ns.only and (floor is None) != (ns.only == "mass")):
            continue
        s = study(floor, ns.iterations)
        t0 = time.perf_counter()
        res = run_study(s, progress=lambda line: print("   ", line, flush=True))
        summ = res.summary
        row = {"problem": name, "fatigue_floor": floor, "design": summ["optimised"]["design"],
               "start_design": summ["start"]["design"],
               "first_frequency_hz": summ["optimised"]["first_frequency_hz"],
               "iterations": summ["iterations"], "evaluations": summ["evaluations"],
               "converged": summ["converged"], "optimality": summ["optimality"],
               "multipliers": summ["multipliers"], "constraint_names": list(s.limits.names),
               "final_constraints": {k: v for k, v in res.history[-1].items()
                                     if k.startswith("c_")},
               "seconds": time.perf_counter() - t0}
        data = json.loads(path.read_text()) if path.exists() else data  # merge a parallel run
        data.setdefault("rows", {})[name] = row
        path.write_text(json.dumps(data, indent=2))
        print(json.dumps(row), flush=True)
    # Evaluate every design on its own modes (simulate) with its stress.
    space = study(None, 1).space
    data = json.loads(path.read_text()) if path.exists() else data
    data.pop("fatigue_floor", None)
    if "mass+fatigue" in data.get("rows", {}):  # the first run's name (floor 1.5)
        data["rows"]["mass+fatigue>=1.5"] = {**data["rows"].pop("mass+fatigue"),
                                             "problem": "mass+fatigue>=1.5", "fatigue_floor": 1.5}
    data["rows"] = dict(sorted(data.get("rows", {}).items(),
                               key=lambda kv: kv[1].get("fatigue_floor") or 0.0))
    start = machined_setup()
    data["default"] = {"design": {"thickness_mm": 6.0, "depth_mm": 40.0}, **evaluate(start)}
    for name, row in data.get("rows", {}).items():
        row.update(evaluate(design_setup(space, row["design"])))
    data["markdown"] = markdown(data).split("\n", 2)[2]  # benchmarks/make_readme.py's table
    data["note"] = "Optimiser: " + "; ".join(
        f"{name}: {row['iterations']} iterations, reduced gradient "
        f"{row['optimality']['projected_gradient']:.1e}, multipliers "
        + ", ".join(f"{k} {v:.3g}" for k, v in row["multipliers"].items())
        for name, row in data.get("rows", {}).items()) + "."
    path.write_text(json.dumps(data, indent=2))
    (out_dir / "optimize_stress.md").write_text(markdown(data))
    print(markdown(data))


def constraint_cell(entry: dict) -> str:
    """'met' or the violated constraints (c > 1e-3) of a row, and its iterations."""
    if "final_constraints" not in entry:
        return "—"
    bad = {k[2:]: v for k, v in entry["final_constraints"].items() if v > 1e-3}
    text = ("met" if not bad else "not met: " + ", ".join(f"{k} {100 * v:+.1f} %"
                                                          for k, v in bad.items()))
    return f"{text} ({entry['iterations']})"


def markdown(data: dict) -> str:
    """The table of the markdown file (generated; do not edit by hand)."""
    lines = ["# The arm optimised with and without a fatigue constraint "
             "(generated by benchmarks/optimize_stress.py)", "",
             (f"Minimise the deviation at {data['speed_rpm']:g} r/min over thickness and depth "
              "profile at the default arm's mass; machined arm (k_a = "
              f"{data['material_factors']['surface_factor']}, k_b = "
              f"{data['material_factors']['size_factor']}); n (polished) with k_a = k_b = 1. "
              "Every design run by `jaxdobby.simulate` on its own modes."), "",
             "| design | thickness [mm] | depth [mm] | mass [kg] | dev. 800 [mm] | σ_max 800 "
             "[MPa] (at s [mm]) | n 800 machined (polished) | dev. 1200 [mm] | σ_max 1200 [MPa] "
             "| n 1200 machined (polished) | constraints at the end (iterations) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    entries = [("default machine", data["default"])]
    entries += [(f"optimised: {name}", row) for name, row in data.get("rows", {}).items()
                if "at" in row]
    for label, e in entries:
        d = e["design"]
        depth = " / ".join(f"{v:.1f}" for k, v in d.items() if k.startswith("depth"))
        cells = [label, f"{d['thickness_mm']:.2f}", depth, f"{e['arm_mass_kg']:.4f}"]
        for rpm in ("800", "1200"):
            a = e["at"][rpm]
            cells += [f"{a['deviation_pp_mm']:.3f}"]
            cells += [f"{a['stress_max_mpa']:.0f} ({a['stress_max_position_mm']:.0f})"
                      if rpm == "800" else f"{a['stress_max_mpa']:.0f}"]
            cells += [f"{a['fatigue_safety_factor']:.2f} "
                      f"({a['fatigue_safety_factor_polished']:.2f})"]
        cells.append(constraint_cell(e))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
