"""Write ``benchmarks/README.md`` from the results JSON in ``benchmarks/results/``.

Every ``*.json`` there is read; a result with a ``markdown`` entry contributes that table, one
with only ``rows`` (a list of flat dicts) a table made from them, anything else a line naming
the file. ``*_quick.json`` (smoke runs of the tests) are skipped unless ``--include-quick``.
Known benchmarks come first in a fixed order, the rest alphabetically; each section states the
machine, versions and date it was measured on, as its JSON records them.

Run:  python benchmarks/make_readme.py [--results DIR] [--output FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

ORDER = ("compile_time", "commands_cold", "suite_time", "suite_compiles", "simulate", "batch",
         "gradient_cost",
         "gradient", "sobol_throughput", "sobol_throughput_steps432", "sobol_throughput_steps216",
         "batch_profile")
TITLES = {"compile_time": "The first answer and compile time against modes (`compile_time.py`, "
                          "issue 19)",
          "commands_cold": "Every command, cold and with the cache filled (`commands_cold.py`, "
                           "issue 19)",
          "suite_time": "The default test suite (`suite_time.py`, issue 19)",
          "suite_compiles": "Where the suite's time goes: its compilations "
                            "(`suite_compiles.py`, issue 19)",
          "simulate": "One default simulation (`bench_simulate.py`)",
          "batch": "Parameter batches (`bench_batch.py`)",
          "gradient_cost": "Cost of a design gradient in forward solves (`gradient_cost.py`, "
                           "issue 19)",
          "gradient": "Gradients of the deviation metric (`bench_gradient.py`)",
          "sobol_throughput": "Sobol throughput of the dobby (`sobol_throughput.py`, issue 4)",
          "sobol_throughput_steps432": "Sobol throughput at 432 steps per cycle for every row, "
                                       "the default's most (`sobol_throughput.py --steps 432`, "
                                       "issue 19)",
          "sobol_throughput_steps216": "Sobol throughput at 216 steps per cycle "
                                       "(`sobol_throughput.py --steps 216`, issue 19)",
          "batch_profile": "Where a chunk of the batch evaluation spends its time "
                           "(`batch_profile.py`, issue 4)"}
RERUN = """\
## How to rerun

From the repository root, with float64 on (the scripts set it) and nothing else heavy running:

```sh
python benchmarks/compile_time.py        # first jaxdobby simulate, compile time vs modes
python benchmarks/commands_cold.py       # every command's wall time, cold and cached
python benchmarks/suite_time.py          # the default test suite, empty caches
python benchmarks/suite_compiles.py      # the suite's XLA compilations, by program and test
python benchmarks/bench_simulate.py      # cold/warm simulate vs solve_ivp, work–precision
python benchmarks/bench_batch.py         # 256 / 4096 / 65 536 samples, 1 and 2 devices
python benchmarks/gradient_cost.py       # a design gradient's cost in forward solves
python benchmarks/bench_gradient.py      # d deviation / d design vs finite differences
python benchmarks/sobol_throughput.py --accuracy  # samples/s, the default study, corners
python benchmarks/sobol_throughput.py --accuracy --steps 216  # the same at jaxdobby sobol --steps 216
python benchmarks/sobol_throughput.py --steps 432 --processes 1 --devices-list 2 --no-study  # every row at 432 steps (the baseline)
taskset -c 0 python benchmarks/batch_profile.py  # ms per sample of each part, one core
python benchmarks/make_readme.py         # this file
```

The scripts with a smoke size take `--quick` (what `tests/test_benchmarks.py` runs, each
under a minute on 2 cores; results go to `*_quick.json`, ignored here) and `--out DIR`. The scipy side solves the same equations
(`benchmarks/scipy_model.py`: the dobby's right-hand side in numpy from jaxdobby's modal
matrices, equal to `jaxdobby.dobby.vector_field` to ~1e-15; `benchmarks/scipy_steady.py`: the
periodic steady state with `solve_ivp`); `tests/test_benchmarks.py` checks that equality and
that the scipy steady state's metrics agree with `jaxdobby.simulate(method="adaptive")`.
"""


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, dict)):
        return json.dumps(v)[:60]
    return str(v)


def rows_table(rows: list) -> str:
    """A markdown table from a list of flat dicts (the union of their keys, in order)."""
    rows = [r for r in rows if isinstance(r, dict)]
    if not rows:
        return ""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(_fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def machine_line(env) -> str:
    """One line: the machine, the versions and the date a result was measured with."""
    if not isinstance(env, dict):
        return ""
    dev, ver = env.get("device", {}) or {}, env.get("versions", {}) or {}
    parts = []
    if isinstance(dev, str):  # older results name the device in words
        parts.append(dev)
    elif dev:
        parts.append(f"{dev.get('cpu', '?')}, {dev.get('cores_available', '?')} cores"
                     + (f", {dev['memory_gib']:.0f} GiB" if dev.get("memory_gib") else ""))
    if isinstance(ver, dict) and ver:
        parts.append(", ".join(f"{k} {v}" for k, v in ver.items()))
    if env.get("date"):
        parts.append(env["date"])
    if env.get("load_average_start") is not None:
        parts.append("load average at start "
                     + "/".join(f"{x:.1f}" for x in env["load_average_start"][:3]))
    if env.get("git_commit"):
        parts.append(f"commit {env['git_commit']}")
    return "Measured on: " + "; ".join(parts) + "." if parts else ""


def section(path: Path, data) -> str:
    """The README section of one results file."""
    name = data.get("benchmark", path.stem) if isinstance(data, dict) else path.stem
    title = TITLES.get(name, f"`{path.name}`")
    out = [f"## {title}", ""]
    if not isinstance(data, dict):
        return "\n".join(out + [f"(`{path.name}`: not a JSON object; skipped)", ""])
    env = data.get("environment") or {k: data[k] for k in ("date", "device", "versions")
                                       if k in data}
    line = machine_line(env) if env else ""
    if isinstance(data.get("markdown"), str):
        out.append(data["markdown"].strip())
    elif isinstance(data.get("rows"), list) and rows_table(data["rows"]):
        out.append(rows_table(data["rows"]))
    else:
        out.append(f"(`{path.name}` has no `markdown` or `rows` entry; see the file.)")
    if data.get("figure"):
        out += ["", f"![{data['figure']}](results/{data['figure']})"]
    if isinstance(data.get("note"), str) and data["note"].strip():
        out += ["", data["note"].strip()]
    if line:
        out += ["", line]
    if isinstance(data.get("cold_environment"), dict):  # `bench_simulate.py --cold-only`
        out += ["", "The cold rows measured anew (`--cold-only`; the other rows as above): "
                + machine_line(data["cold_environment"]).removeprefix("Measured on: ")]
    out += ["", f"Source: `results/{path.name}`.", ""]
    return "\n".join(out)


def targets(by_name: dict) -> str:
    """The issue's targets against the measured figures (only those whose results exist)."""
    rows = []
    sim, batch, grad = by_name.get("simulate"), by_name.get("batch"), by_name.get("gradient")
    ct = by_name.get("compile_time")
    if ct and ct.get("command_line"):
        cl = ct["command_line"]
        shipped = cl.get("shipped_executables")
        rows.append(("first `jaxdobby simulate`, fresh process, empty cache folder (issue 19)",
                     "≤ 10 s (stretch 5 s)", f"{cl['cold_s']:.1f} s wall"
                     + (" (shipped executables loaded)" if shipped else "")
                     + (f"; {cl['cold_compiling_s']:.1f} s with them off (XLA compiles)"
                        if "cold_compiling_s" in cl else "")))
        rows.append(("`jaxdobby simulate` with the cache filled (issue 19)", "≤ 3 s",
                     f"{cl['cached_s']:.1f} s wall"))
    cli_k = {r["modes"]: r for r in (ct or {}).get("command_line_modes") or []}
    for k, limit in ((16, 30), (30, 60)):
        if k in cli_k:
            r = cli_k[k]
            rows.append((f"`jaxdobby simulate --modes {k}`, fresh process, empty cache folder "
                         "(issue 19)", f"≤ {limit} s",
                         f"{r['cold_s']:.0f} s wall (exit {r['exit_code']})"))
    if ct and ct.get("modes"):
        by_k = {r["modes"]: r for r in ct["modes"]}
        for k, limit in ((16, 30), (30, 60)):
            if k in by_k and k not in cli_k:
                r = by_k[k]
                rows.append((f"`--modes {k}` cold compile (issue 19)", f"≤ {limit} s",
                             f"{r['trace_lower_s'] + r['compile_s']:.0f} s (tracing "
                             f"{r['trace_lower_s']:.0f} + XLA {r['compile_s']:.0f})"))
    suite = by_name.get("suite_time")
    if suite and suite.get("wall_s"):
        rows.append(("default test suite, empty cache, 2 cores (issue 19)", "≤ 5 min",
                     f"{suite['wall_s'] / 60:.1f} min ({suite.get('summary', '')})"))
    if sim:
        cold = sim.get("cold", {})
        key = "no_cache" if "no_cache" in cold else next(iter(cold), None)
        if key:
            rows.append(("`simulate()` cold, compilation included", "≤ 10 s",
                         f"{cold[key]['total_s']:.1f} s ({key.replace('_', ' ')}"
                         + (", the shipped executable loaded); "
                            f"{cold['no_cache_compiling']['total_s']:.1f} s compiling"
                            if "no_cache_compiling" in cold else ")")
                         + (f"; {cold['cache_filled']['total_s']:.1f} s with the persistent "
                            "cache filled" if "cache_filled" in cold else "")))
        if sim.get("jaxdobby"):
            rows.append(("`simulate()` warm", "≤ 100 ms",
                         f"{1e3 * sim['jaxdobby'][0]['median_s']:.0f} ms"))
    if batch and batch.get("rows"):
        big = max(batch["rows"], key=lambda r: r["samples"])
        rows.append((f"batch ({big['samples']} samples) vs scipy serial loop, numpy RHS",
                     "≥ 1000×", f"{big['speedup_vs_serial_numpy']:.0f}×"))
        rows.append((f"batch ({big['samples']} samples) vs scipy on 2 cores, jitted RHS",
                     "≥ 20×", f"{big['speedup_vs_pool_jitted']:.0f}×"))
    cost = by_name.get("gradient_cost")
    cost_rows = [r for r in (cost or {}).get("rows", []) if r.get("n_variables", 0) >= 7]
    if cost_rows:  # gradient_cost.py (after issue 19's rewrite) supersedes bench_gradient.py
        r = max(cost_rows, key=lambda r: r["n_variables"])
        rows.append((f"gradient w.r.t. {r['n_variables']} design variables (issue 19; asked: 8)",
                     "≤ 4 forward solves",
                     f"{r['reverse_ratio']:.1f} forward solves (reverse mode; forward mode "
                     f"{r['forward_ratio']:.1f})"))
    elif grad and grad.get("rows"):
        eight = [r for r in grad["rows"] if "8" in r["case"]]
        if eight:
            best = min(eight, key=lambda r: r["forward_solves"])
            mode = next((m for m in ("forward", "reverse") if m in best["case"]), "")
            rows.append(("gradient w.r.t. 8 design variables (issue 19)", "≤ 4 forward solves",
                         f"{best['forward_solves']:.1f} forward solves"
                         + (f" ({mode} mode)" if mode else "")))
    sobol = by_name.get("sobol_throughput")
    if sobol and sobol.get("runs"):
        best = max(sobol["runs"], key=lambda r: r["samples_per_s"])
        fewer = by_name.get("sobol_throughput_steps216") or {}
        fast = max(fewer.get("runs", []), key=lambda r: r["samples_per_s"], default=None)
        errors = fewer.get("accuracy", {}).get("max_relative_error")
        most = by_name.get("sobol_throughput_steps432") or {}
        same = [r for r in most.get("runs", [])
                if (r["processes"], r["devices"]) == (best["processes"], best["devices"])]
        rows.append(("dobby steady-state samples per second, 2 cores (issue 19)", "≥ 2000",
                     f"{best['samples_per_s']:.0f} ({best['processes']} process × "
                     f"{best['devices']} devices, each row's steps per cycle by its speed, "
                     f"{best.get('mean_steps', 432):.0f} on average)"
                     + (f"; {same[0]['samples_per_s']:.0f} with 432 steps for every row"
                        if same else "")
                     + (f"; {fast['samples_per_s']:.0f} at `--steps 216` (not the default: "
                        f"largest corner error {max(errors.values()):.0e} against "
                        f"{max(sobol['accuracy']['max_relative_error'].values()):.0e})"
                        if fast and errors and sobol.get("accuracy") else "")))
        studies = sobol.get("studies", [])
        cached = [s for s in studies if s.get("cache") == "filled"]
        compiling = [s for s in studies[1:] if s.get("cache") != "filled"
                     and s.get("shipped_executables") is False and s.get("processes") == 1]
        for study in studies[:1]:
            rows.append(("default Sobol study, N = 1024 second order, cold (issue 19)", "≤ 15 s",
                         f"{study['study_wall_s']:.0f} s wall"
                         + (" (shipped executable loaded)" if study.get("shipped_executables")
                            else ", compilation included")
                         + (f"; {compiling[0]['study_wall_s']:.0f} s compiling (shipped "
                            "executable off)" if compiling and study.get("shipped_executables")
                            else "")
                         + (f"; {cached[0]['study_wall_s']:.0f} s with the persistent cache "
                            "filled" if cached else "")
                         + f"; {study['rows'] / best['samples_per_s']:.1f} s of evaluation at "
                         f"{best['samples_per_s']:.0f} samples/s"))
    if not rows:
        return ""
    lines = ["## Targets", "",
             "Each row's figure comes from its results file, measured on the date its section "
             "below gives (rows not marked issue 19 were last measured before the issue 19 "
             "changes).", "", "| target | asked | measured |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines) + "\n"


def build(results: Path, include_quick: bool = False) -> str:
    files = sorted(p for p in results.glob("*.json")
                   if include_quick or not p.stem.endswith("_quick"))
    loaded = []
    for p in files:
        try:
            data = json.loads(p.read_text())
        except (OSError, json.JSONDecodeError) as e:
            data = f"unreadable: {e}"
        name = data.get("benchmark", p.stem) if isinstance(data, dict) else p.stem
        rank = ORDER.index(name) if name in ORDER else len(ORDER)
        loaded.append((rank, p.name, p, data))
    loaded.sort(key=lambda x: (x[0], x[1]))
    head = ["# Benchmarks: jaxdobby against scipy",
            "",
            ("Generated by `benchmarks/make_readme.py` from `benchmarks/results/*.json`; do not "
            "edit by hand. Times are wall-clock seconds, float64 on both sides, medians of "
            "repeats after compilation unless a row says *cold*. Errors are the largest relative "
            "error of the compared metrics against a tight scipy reference (DOP853)."),
            ""]
    if not loaded:
        head.append("No results yet: run the scripts below.\n")
    by_name = {d.get("benchmark"): d for _, _, _, d in loaded if isinstance(d, dict)}
    body = [section(p, data) for _, _, p, data in loaded]
    return "\n".join(head + [targets(by_name)] + body + [RERUN])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--results", type=Path, default=HERE / "results")
    p.add_argument("--output", type=Path, default=HERE / "README.md")
    p.add_argument("--include-quick", action="store_true")
    ns = p.parse_args(argv)
    ns.output.write_text(build(ns.results, ns.include_quick))
    print(ns.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
