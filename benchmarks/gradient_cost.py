"""Cost of one design gradient relative to one forward steady-state solve.

For a few design-variable sets (1 to 7 variables) and both gradient modes, times on the default
machine at 800 r/min, on the optimiser's fixed reduction basis:

* one forward solve (J and the metrics),
* one gradient (J and ∇J) in forward mode (``jax.jacfwd``) and in reverse mode
  (``jax.value_and_grad``),

compile time apart, ``block_until_ready``, median of repeats. Writes JSON and a markdown table.

Run:  PYTHONPATH=. python benchmarks/gradient_cost.py [--repeats 3] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)


from jaxdobby.optimize.design import DesignSpace
from jaxdobby.optimize.objective import Evaluator, Objective
from jaxdobby.parameters import Setup

CASES = {
    "thickness": ["thickness"],
    "thickness+mass": ["thickness", "heald_frame_mass"],
    "depth (5)": ["depth"],
    "thickness+depth+mass (7)": ["thickness", "depth", "heald_frame_mass"],
}


def timed(fn, repeats):
    t0 = time.perf_counter()
    fn(0)
    first = time.perf_counter() - t0
    runs = []
    for i in range(repeats):
        t0 = time.perf_counter()
        fn(i + 1)
        runs.append(time.perf_counter() - t0)
    return first, statistics.median(runs)


def measure(name, variables, steps, repeats) -> dict:
    """Timings of one case: forward solve, forward- and reverse-mode gradients."""
    space = DesignSpace.create(Setup(), variables)
    row = {"case": name, "n_variables": space.size, "steps": steps}

    def nudge(i):  # new values each call, same shapes: no recompilation
        return space.initial + 1e-3 * i

    for mode in ("forward", "reverse"):
        ev = Evaluator(space, Objective(), steps=steps, mode=mode)
        if mode == "forward":
            _, row["solve_s"] = timed(lambda i, ev=ev: ev.value(nudge(i)), repeats)
        first, row[f"{mode}_gradient_s"] = timed(
            lambda i, ev=ev: ev.value_and_grad(nudge(i)), repeats)
        row[f"{mode}_compile_s"] = first - row[f"{mode}_gradient_s"]
        row[f"{mode}_ratio"] = row[f"{mode}_gradient_s"] / row["solve_s"]
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps", type=int, default=6800, help="RK4 steps (same for every case)")
    ap.add_argument("--out", default="benchmarks/results")
    ns = ap.parse_args()
    rows = []
    for name, variables in CASES.items():
        row = measure(name, variables, ns.steps, ns.repeats)
        rows.append(row)
        print(json.dumps(row), flush=True)
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "gradient_cost.json").write_text(json.dumps({
        "device": str(jax.devices()[0]), "rows": rows}, indent=2))
    header = ("| variables | n | forward solve [s] | forward-mode gradient [s] (×) | "
              "reverse-mode gradient [s] (×) |")
    lines = [header, "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['n_variables']} | {r['solve_s']:.2f} | "
                     f"{r['forward_gradient_s']:.1f} ({r['forward_ratio']:.1f}×) | "
                     f"{r['reverse_gradient_s']:.1f} ({r['reverse_ratio']:.1f}×) |")
    (out / "gradient_cost.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
