"""Gradients of the heald-frame deviation: jaxdobby's autodiff against scipy finite differences.

The quantity is ``deviation_pp`` [m], the peak-to-peak heald-frame displacement deviation of the
periodic steady cycle, of the default machine at the default operating point, as a function of
design variables in SI units (set with :func:`jaxdobby.parameters.apply`):

* one variable: the arm's ``thickness``;
* eight: ``thickness``, ``straight_length``, ``arc_radius``, ``tip_length``,
  ``ring_joint_position``, ``youngs_modulus``, ``density``, ``heald_frame_mass``.

jaxdobby: ``jax.jacfwd`` (forward mode) and ``jax.grad`` (reverse mode) of
``simulate(...).metrics["deviation_pp"]`` (the default collocation path; through the periodic
state by the implicit-function theorem), jitted; compile time apart, median of repeats, and the
same for the forward solve alone, so the gradient's cost is also given in forward solves.

scipy: central finite differences, two steady-state solves per variable
(:func:`benchmarks.scipy_steady.solve_setup`, DOP853, jitted right-hand side — the fastest
scipy variant at the accuracy finite differences need, rtol 1e-9, step 1e-3 relative). The
thickness derivative is measured; the eight-variable cost is two solves per variable at the
measured median seconds per solve (the solves are alike), marked as extrapolated.

Run:  python benchmarks/bench_gradient.py [--quick] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common as common

VARIABLES = ("thickness", "straight_length", "arc_radius", "tip_length", "ring_joint_position",
             "youngs_modulus", "density", "heald_frame_mass")


def jax_side(modes: int, repeats: int, quick: bool = False) -> dict:
    jax = common.configure_jax()
    import jax.numpy as jnp
    import numpy as np

    from jaxdobby import Machine, OperatingPoint
    from jaxdobby.parameters import PARAMETERS, Setup, apply
    from jaxdobby.simulate import resolve_method, simulate

    machine = Machine.default(n_modes=modes)
    method, steps = resolve_method(machine, OperatingPoint())
    base = Setup(machine=machine)
    x0 = jnp.array([float(PARAMETERS[n].get(base)) for n in VARIABLES])

    def deviation(x):
        s = apply(base, {n: x[i] for i, n in enumerate(VARIABLES)})
        return simulate(s.machine, s.operating, method=method,
                        steps=steps).metrics["deviation_pp"]

    def deviation_thickness(t):
        return deviation(x0.at[0].set(t))

    cases = {"forward": (jax.jit(deviation), x0),
             "gradient_thickness": (jax.jit(jax.jacfwd(deviation_thickness)), x0[0]),
             "gradient_8": (jax.jit(jax.jacfwd(deviation)), x0),
             "gradient_8_reverse": (jax.jit(jax.grad(deviation)), x0)}
    if quick:  # two gradient compiles fewer (minutes on 2 cores): d/d thickness from the 8
        del cases["gradient_thickness"], cases["gradient_8_reverse"]
    out = {"method": method, "steps": steps, "x0": np.asarray(x0).tolist()}
    for name, (fn, x) in cases.items():
        t0 = time.perf_counter()
        value = common.block(fn(x))
        first = time.perf_counter() - t0
        # new values each call (same shapes): no caching of results, no recompilation
        t = common.timed(lambda fn=fn, x=x: common.block(fn(x * (1.0 + 1e-9))),
                         repeats=repeats, budget_s=60.0)
        out[name] = {"first_call_s": first, "compile_s": max(first - t["median_s"], 0.0),
                         "median_s": t["median_s"], "min_s": t["min_s"], "repeats": t["repeats"],
                         "value": np.asarray(value).tolist()}
        common.log(f"jaxdobby {name}: {t['median_s']:.3f} s (first {first:.1f} s)")
    if quick:
        out["gradient_thickness"] = dict(out["gradient_8"], value=out["gradient_8"]["value"][0],
                                         note="--quick: the first entry of the 8-gradient")
        out["gradient_8_reverse"] = dict(out["gradient_8"], note="--quick: forward mode")
    return out


def scipy_side(modes: int, rtol: float, rel_step: float, x0) -> dict:
    from benchmarks.scipy_steady import solve_setup
    from jaxdobby import Machine
    from jaxdobby.parameters import Setup, apply

    base = Setup(machine=Machine.default(n_modes=modes))
    # compile jaxdobby's model build and the jitted RHS outside the timing
    solve_setup(base, rhs="jitted", method="DOP853", rtol=1e-3, tolerance=1e-2)
    h = rel_step * x0[0]
    runs = []
    t0 = time.perf_counter()
    for sign in (1.0, -1.0):
        s = apply(base, {"thickness": x0[0] + sign * h})
        runs.append(solve_setup(s, rhs="jitted", method="DOP853", rtol=rtol,
                                tolerance=max(1e-8, 100 * rtol)))
    wall = time.perf_counter() - t0
    derivative = (runs[0].metrics["deviation_pp"] - runs[1].metrics["deviation_pp"]) / (2 * h)
    per_solve = statistics.median(r.seconds for r in runs)
    common.log(f"scipy central difference (thickness): {wall:.1f} s, {derivative:.6g}")
    return {"method": "DOP853", "rhs": "jitted", "rtol": rtol, "rel_step": rel_step,
                "gradient_thickness_s": wall, "per_solve_s": per_solve,
                "gradient_8_s_extrapolated": 2 * len(VARIABLES) * per_solve,
                "derivative_thickness": derivative,
                "converged": all(r.converged for r in runs)}


def markdown(rows: list[dict]) -> str:
    lines = [("| case | jaxdobby [s] | jaxdobby, in forward solves | scipy central differences [s]"
             " | scipy / jaxdobby |"), "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['jaxdobby_s']:.3g} | {r['forward_solves']:.2f} | "
                     f"{r['scipy_s']:.3g}{'*' if r.get('extrapolated') else ''} | "
                     f"{r['ratio']:.1f}× |")
    lines.append("")
    lines.append("\\* extrapolated: two solves per variable at the measured seconds per solve.")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="smoke size (tests)")
    p.add_argument("--repeats", type=int, default=None)
    p.add_argument("--modes", type=int, default=None, help="arm modes (default 4; quick 1)")
    p.add_argument("--rtol", type=float, default=None, help="scipy rtol (default 1e-9)")
    # 1e-4: the deviation is curved in the thickness (a resonance peak stands at 6.25 mm), so a
    # central difference over 1e-3 of 6 mm is 1 % off jaxdobby's own exact derivative (measured
    # 9.9e-3 at 1 mode; 9.9e-5 over 1e-4)
    p.add_argument("--step", type=float, default=1e-4, help="relative finite-difference step")
    p.add_argument("--out", type=Path, default=common.RESULTS)
    ns = p.parse_args(argv)
    modes = ns.modes or (1 if ns.quick else 4)
    repeats = ns.repeats or (1 if ns.quick else 5)
    # scipy's periodic state to max(1e-8, 100·rtol) relative: over a relative step of 2e-4
    # the central difference then errs by ~1e-8/2e-4 = 5e-5 of the deviation's scale (≈ 2.5e-4
    # of its derivative in thickness)
    rtol = ns.rtol or 1e-10
    common.configure_jax()
    record = {"benchmark": "gradient", "quick": ns.quick, "n_modes": modes, "variables": list(VARIABLES),
                  "metric": "deviation_pp", "environment": common.environment()}
    jx = record["jaxdobby"] = jax_side(modes, repeats, ns.quick)
    sp = record["scipy"] = scipy_side(modes, rtol, ns.step, jx["x0"])
    fwd = jx["forward"]["median_s"]
    ad = jx["gradient_thickness"]["value"]
    record["derivative_thickness"] = {
        "jaxdobby": ad, "scipy_central_difference": sp["derivative_thickness"],
        "relative_difference": abs(ad - sp["derivative_thickness"]) / abs(ad)}
    rows = [{"case": "forward solve", "jaxdobby_s": fwd, "forward_solves": 1.0,
                 "scipy_s": sp["per_solve_s"], "ratio": sp["per_solve_s"] / fwd},
            {"case": "gradient w.r.t. thickness", "jaxdobby_s": jx["gradient_thickness"]["median_s"],
                 "forward_solves": jx["gradient_thickness"]["median_s"] / fwd,
                 "scipy_s": sp["gradient_thickness_s"],
                 "ratio": sp["gradient_thickness_s"] / jx["gradient_thickness"]["median_s"]},
            *({"case": f"gradient w.r.t. 8 design variables, {mode} mode",
               "jaxdobby_s": jx[key]["median_s"], "forward_solves": jx[key]["median_s"] / fwd,
               "scipy_s": sp["gradient_8_s_extrapolated"], "extrapolated": True,
               "ratio": sp["gradient_8_s_extrapolated"] / jx[key]["median_s"]}
              for mode, key in (("forward", "gradient_8"), ("reverse", "gradient_8_reverse")))]
    record["rows"] = rows
    d = record["derivative_thickness"]
    record["markdown"] = markdown(rows) + (
        f"\n\nd(deviation_pp)/d(thickness): jaxdobby {d['jaxdobby']:.6g}, scipy central "
        f"difference {d['scipy_central_difference']:.6g} (relative difference "
        f"{d['relative_difference']:.1e}).")
    name = "gradient_quick.json" if ns.quick else "gradient.json"
    common.write_json(ns.out / name, common.finish(record))
    print(record["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
