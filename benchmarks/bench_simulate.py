"""One default simulation: jaxdobby against ``scipy.integrate.solve_ivp`` on the same equations.

What is timed (float64 on both sides, ``block_until_ready``, medians of repeats):

* jaxdobby **cold**: ``simulate()`` in a fresh Python process (import, tracing, compilation and
  the run; :mod:`benchmarks._cold`), without and with the persistent compilation cache (the
  second process with the cache loads what the first compiled);
* jaxdobby **warm**: ``simulate()`` as the command line calls it (Gauss collocation, 432 steps
  per cycle) and, for the work–precision figure, collocation at other step counts, RK4 (the step
  from the highest mode, and half of it) and the adaptive path at several tolerances (compile
  time reported apart);
* scipy: the periodic steady state by cycling ``solve_ivp`` (:mod:`benchmarks.scipy_steady`) with
  the plain numpy right-hand side and with the jitted one (plus its Jacobian for the implicit
  methods), RK45, DOP853, LSODA and Radau at several tolerances.

Accuracy: each run's metrics against a tight reference (DOP853, rtol 1e-12, periodic to 1e-10;
jitted right-hand side — the same equations, equal to the numpy one to 1e-15) evaluated by its
dense output on that run's own output grid, so the error is the integration error.

Run:  python benchmarks/bench_simulate.py [--quick] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common as common

FULL_SCIPY = {
    # a numpy right-hand side costs ~5x a jitted one per call: fewer tolerances for it
    "numpy": {"RK45": (1e-6,), "DOP853": (1e-8,), "LSODA": (1e-6,), "Radau": (1e-6,)},
    "jitted": {"RK45": (1e-5, 1e-7), "DOP853": (1e-6, 1e-8, 1e-10), "LSODA": (1e-6, 1e-8),
               "Radau": (1e-5, 1e-7)},
}
QUICK_SCIPY = {rhs: {"RK45": (1e-4,), "Radau": (1e-4,)} for rhs in ("numpy", "jitted")}


COLD_LABELS = {"no_cache": "cold, no cache (fresh process)",
               "no_cache_compiling": "cold, no cache, shipped executable off (compiles)",
               "cache_empty": "cold, persistent cache empty (compiles and writes it)",
               "cache_filled": "cold, persistent cache filled (fresh process)",
               "quick": "cold (fresh process; smoke run, cache as the environment says)"}


def cold_runs(quick: bool, modes: int) -> dict:
    """``simulate()`` in fresh processes: no cache; cache empty (compiles, writes); cache full.
    ``--quick``: one run, with ``$JAXDOBBY_BENCH_CACHE`` if set (the tests')."""
    env = dict(os.environ, PYTHONPATH=str(common.ROOT))
    env.pop("JAXDOBBY_CACHE_DIR", None)
    shared = env.pop(common.CACHE_ENV, None)
    out = {}

    def one(*args, shipped=True):
        run_env = env if shipped else dict(env, JAXDOBBY_SHIPPED_EXECUTABLES="off")
        p = subprocess.run([sys.executable, "-m", "benchmarks._cold", "--modes", str(modes),
                            *args], cwd=common.ROOT, env=run_env, capture_output=True,
                           text=True, check=True)
        return json.loads(p.stdout.strip().splitlines()[-1])

    if quick:
        out["quick"] = one(*(["--cache", shared] if shared else []))
    else:
        out["no_cache"] = one()  # the default sizes load the package's shipped executable
        out["no_cache_compiling"] = one(shipped=False)
        with tempfile.TemporaryDirectory() as cache:
            out["cache_empty"] = one("--cache", cache, shipped=False)
            out["cache_filled"] = one("--cache", cache, shipped=False)
    for r in out.values():
        r["total_s"] = r["import_s"] + r["first_call_s"]
    return out


def refresh_cold(path: Path, quick: bool, modes: int) -> int:
    """``--cold-only``: the cold runs measured anew, written into the results file ``path``
    (its warm and scipy runs kept, with the date they were measured)."""
    common.configure_jax()
    record = json.loads(path.read_text())
    if record.get("n_modes") != modes:
        raise SystemExit(f"{path} holds {record.get('n_modes')} modes, not {modes}")
    record.setdefault("warm_measured", record.get("environment", {}).get("date"))
    common.log("cold runs (fresh processes)...")
    record["cold"] = cold_runs(quick, modes)
    record["cold_environment"] = common.environment()
    rows = summary_rows(record)
    record["rows"], record["markdown"] = rows, markdown(rows)
    common.write_json(path, record)
    print(record["markdown"])
    return 0


def jax_runs(quick: bool, repeats: int, reference, numpy_model, machine) -> list[dict]:
    """Warm jaxdobby runs: the default call, RK4 step counts, adaptive tolerances."""
    import numpy as np

    from benchmarks.scipy_model import METRICS, metric_error
    from benchmarks.scipy_steady import metrics_on
    from jaxdobby import OperatingPoint
    from jaxdobby.periodic import DEFAULT_STEPS as COLLOCATION_STEPS
    from jaxdobby.simulate import default_steps, simulate

    n = default_steps(machine, OperatingPoint())
    cases = [("jaxdobby simulate()", {}, "collocation", COLLOCATION_STEPS)]
    if not quick:
        cases += [(f"jaxdobby collocation steps={m}", {"steps": m}, "collocation", m)
                  for m in (216, 288, 864)]
        cases += [(f"jaxdobby rk4 steps={m}", {"method": "rk4", "steps": m}, "rk4", m)
                  for m in (n, 2 * n)]
        cases += [(f"jaxdobby adaptive rtol={r:g}",
                   {"method": "adaptive", "rtol": r, "atol": 1e-4 * r,
                    "tolerance": max(1e-6, 100 * r)}, "adaptive", r) for r in (1e-6, 1e-8)]
    rows = []
    for label, kwargs, method, setting in cases:
        t0 = time.perf_counter()
        common.block(simulate(machine, **kwargs))
        first = time.perf_counter() - t0
        t = common.timed(lambda kw=kwargs: common.block(simulate(machine, **kw)),
                         repeats=repeats, budget_s=20.0)
        run = t["value"]
        metrics = {m: float(run.metrics[m]) for m in METRICS}
        ref = metrics_on(reference, numpy_model, np.asarray(run.series.t))
        rows.append({"label": label, "side": "jaxdobby", "method": method, "setting": setting,
                         "first_call_s": first, "compile_s": max(first - t["median_s"], 0.0),
                         "median_s": t["median_s"], "min_s": t["min_s"], "repeats": t["repeats"],
                         "converged": bool(run.converged), "steps": int(run.num_steps),
                         "metrics": metrics, "error": metric_error(metrics, ref)})
        common.log(f"{label}: {t['median_s']:.4f} s (first {first:.1f} s), "
                   f"error {rows[-1]['error']:.2e}")
    return rows


def scipy_runs(table: dict, problems: dict, repeats: int, budget_s: float, reference,
               numpy_model, n_out: int) -> list[dict]:
    """Every (right-hand side, method, rtol) of ``table``: time, cost counters and error."""
    import numpy as np

    from benchmarks.scipy_model import metric_error
    from benchmarks.scipy_steady import default_strategy, metrics_on, steady_state

    strategy = default_strategy(numpy_model.n_modes)
    t_out = np.linspace(0.0, numpy_model.period, n_out)
    ref = metrics_on(reference, numpy_model, t_out)
    rows = []
    for rhs, problem in problems.items():
        for method, rtols in table[rhs].items():
            for rtol in rtols:
                # periodicity asked of the steady state: as jaxdobby's adaptive runs above, no
                # less than 100·rtol (an adaptive period map is smooth only to about its rtol)
                t = common.timed(lambda p=problem, m=method, r=rtol: steady_state(
                    p, m, r, 1e-4 * r, t_out, strategy=strategy,
                    tolerance=max(1e-6, 100 * r)), repeats=repeats,
                    budget_s=budget_s)
                run = t["value"]
                row = run.record()
                row.update(label=f"scipy {method} ({rhs} RHS) rtol={rtol:g}", side="scipy",
                           median_s=t["median_s"], min_s=t["min_s"], repeats=t["repeats"],
                           error=metric_error(run.metrics, ref))
                row.pop("seconds")
                rows.append(row)
                common.log(f"{row['label']}: {row['median_s']:.2f} s, {row['nfev']} f-evals, "
                           f"error {row['error']:.2e}")
    return rows


def work_precision_figure(rows: list[dict], path: Path) -> Path:
    """Error against wall time, one series per solver (log–log)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    groups: dict[str, list] = {}
    for r in rows:
        key = (f"{r['method']} ({r['rhs']} RHS)" if r["side"] == "scipy"
               else f"jaxdobby {r['method']}")
        groups.setdefault(key, []).append((r["median_s"], max(r["error"], 1e-16)))
    for key, pts in sorted(groups.items()):
        pts.sort()
        style = "o-" if key.startswith("jaxdobby") else "s--"
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, label=key)
    ax.set_xlabel("wall time of one steady-state simulation [s] (warm)")
    ax.set_ylabel("max relative metric error vs DOP853 rtol 1e-12")
    ax.set_title("Work–precision: default dobby steady state")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def summary_rows(record: dict) -> list[dict]:
    """The README's rows: cold/warm jaxdobby and, per scipy variant, its fastest run at least as
    accurate as the default jaxdobby run (else its most accurate run)."""
    jax_default = record["jaxdobby"][0]
    rows = [{"case": f"jaxdobby simulate() {COLD_LABELS[key]}", "seconds": r["total_s"],
             "error": None} for key, r in record["cold"].items()]
    for r in record["jaxdobby"]:
        rows.append({"case": f"{r['label']} warm", "seconds": r["median_s"], "error": r["error"]})
    target = jax_default["error"]
    by_variant: dict[str, list] = {}
    for r in record["scipy"]:
        by_variant.setdefault(f"scipy {r['method']} ({r['rhs']} RHS)", []).append(r)
    for name, runs in by_variant.items():
        good = [r for r in runs if r["error"] <= target]
        best = min(good, key=lambda r: r["median_s"]) if good else min(runs,
                                                                         key=lambda r: r["error"])
        rows.append({"case": f"{name} rtol={best['rtol']:g}"
                         + ("" if good else " (most accurate tried)"),
                         "seconds": best["median_s"], "error": best["error"],
                         "ratio_to_jaxdobby_warm": best["median_s"] / jax_default["median_s"]})
    return rows


def markdown(rows: list[dict]) -> str:
    lines = ["| case | time [s] | metric error | scipy / jaxdobby warm |", "|---|---|---|---|"]
    for r in rows:
        err = "—" if r["error"] is None else f"{r['error']:.1e}"
        ratio = f"{r['ratio_to_jaxdobby_warm']:.0f}×" if "ratio_to_jaxdobby_warm" in r else ""
        lines.append(f"| {r['case']} | {r['seconds']:.4g} | {err} | {ratio} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="smoke size (tests)")
    p.add_argument("--repeats", type=int, default=None, help="repeats per timing (median)")
    p.add_argument("--out", type=Path, default=common.RESULTS, help="results directory")
    p.add_argument("--modes", type=int, default=None,
                   help="elastic modes of the arm (default 4; --quick: 1, a non-stiff smoke size)")
    p.add_argument("--cold-only", action="store_true",
                   help="measure the cold runs only and update them in the existing results "
                        "file (the warm and scipy runs take ~30 min)")
    ns = p.parse_args(argv)
    modes = ns.modes or (1 if ns.quick else 4)
    if ns.cold_only:
        return refresh_cold(ns.out / ("simulate_quick.json" if ns.quick else "simulate.json"),
                            ns.quick, modes)
    repeats = ns.repeats or (1 if ns.quick else 5)
    common.configure_jax()
    import numpy as np

    from benchmarks.scipy_model import METRICS, NumpyDobby
    from benchmarks.scipy_steady import (
        default_strategy,
        jitted_problem,
        numpy_problem,
        steady_state,
    )
    from jaxdobby import Machine, OperatingPoint
    from jaxdobby.dobby import build_model

    record = {"benchmark": "simulate", "quick": ns.quick, "n_modes": modes,
                  "environment": common.environment()}
    common.log("cold runs (fresh processes)...")
    record["cold"] = cold_runs(ns.quick, modes)
    machine = Machine.default(n_modes=modes)
    model = build_model(machine, OperatingPoint())
    numpy_model = NumpyDobby.from_model(model)
    problems = {"numpy": numpy_problem(numpy_model), "jitted": jitted_problem(model, numpy_model)}
    t0 = time.perf_counter()
    problems["jitted"].fun(0.0, np.zeros(2 * model.n_modes))
    problems["jitted"].jac(0.0, np.zeros(2 * model.n_modes))
    record["scipy_jitted_rhs_compile_s"] = time.perf_counter() - t0

    rtol_ref = 1e-10 if ns.quick else 1e-12
    common.log(f"reference: DOP853 rtol {rtol_ref:g} (jitted RHS)...")
    reference = steady_state(problems["jitted"], "DOP853", rtol_ref, 1e-4 * rtol_ref,
                             np.linspace(0.0, model.period, 3001), tolerance=1e-9,
                             strategy=default_strategy(modes), dense_output=True)
    record["reference"] = reference.record()
    record["jaxdobby"] = jax_runs(ns.quick, repeats, reference, numpy_model, machine)
    record["scipy"] = scipy_runs(QUICK_SCIPY if ns.quick else FULL_SCIPY, problems,
                                 1 if ns.quick else min(repeats, 3), 60.0, reference,
                                 numpy_model, 3001)
    record["metrics_compared"] = list(METRICS)
    rows = summary_rows(record)
    record["rows"] = rows
    record["markdown"] = markdown(rows)
    ns.out.mkdir(parents=True, exist_ok=True)
    figure = work_precision_figure(record["jaxdobby"] + record["scipy"],
                                   ns.out / ("simulate_work_precision"
                                             + ("_quick" if ns.quick else "") + ".png"))
    record["figure"] = figure.name
    name = "simulate_quick.json" if ns.quick else "simulate.json"
    common.write_json(ns.out / name, common.finish(record))
    print(record["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
