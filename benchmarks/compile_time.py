"""How long a user waits: the first ``jaxdobby simulate``, and compile time against modes.

Two measurements, each in fresh processes (nothing shared but what is said):

* **The command line** as a new user runs it: ``jaxdobby simulate`` with an empty cache
  folder (``JAXDOBBY_CACHE_DIR`` a new temporary directory: no XLA executable, no stored
  program but the package's shipped one), then again with that folder filled; wall time of the
  whole process, median of ``--repeats`` fresh folders.
* **The command line at other sizes**: ``jaxdobby simulate --modes k`` with an empty cache folder
  (no shipped program at k ≠ 4: tracing, export and compilation with the one-shot XLA options
  of ``jaxdobby.programs.ONE_SHOT``), whole process, for k in ``--cli-modes``.
* **Compile time against modes** k = 1…30: in one fresh process per k (XLA's persistent cache
  off, the command line's XLA flags), the simulate program's tracing and lowering, XLA
  compilation, its size (StableHLO lines) and the warm run time (median of 3), with the
  warm time per collocation step.

Writes ``results/compile_time.json``, ``results/compile_time.md`` and
``results/compile_time.png``.

Run:  python benchmarks/compile_time.py [--quick] [--modes 1 2 4 8 16 30] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/compile_time.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common as common

DEFAULT_MODES = (1, 2, 3, 4, 6, 8, 12, 16, 20, 24, 30)

_ONE_SIZE = r"""
import json, sys, time
t0 = time.perf_counter()
from jaxdobby.cli import _configure_jax
import os
os.environ["JAXDOBBY_CACHE_DIR"] = "off"
_configure_jax()
import jax, equinox as eqx
from jaxdobby import Machine, OperatingPoint
from jaxdobby.simulate import _SIMULATE_DEFAULTS, _simulate_impl
k = int(sys.argv[1])
machine, operating = Machine.default(n_modes=k), OperatingPoint()
dynamic, static = eqx.partition((machine, operating), eqx.is_array)
def metrics(d):
    m, o = eqx.combine(d, static)
    run = _simulate_impl(m, o, None, method="collocation", steps=432, **_SIMULATE_DEFAULTS)
    return run.metrics, run.converged
t1 = time.perf_counter()
lowered = jax.jit(metrics).lower(dynamic)
t2 = time.perf_counter()
compiled = lowered.compile()
t3 = time.perf_counter()
out = jax.block_until_ready(compiled(dynamic))
runs = []
for _ in range(3):
    s = time.perf_counter(); jax.block_until_ready(compiled(dynamic)); runs.append(time.perf_counter() - s)
runs.sort()
print(json.dumps({"modes": k, "import_s": t1 - t0, "trace_lower_s": t2 - t1, "compile_s": t3 - t2,
                  "stablehlo_lines": lowered.as_text().count("\n"), "warm_s": runs[1],
                  "warm_per_step_us": runs[1] / 432 * 1e6, "converged": bool(out[1]),
                  "deviation_pp_mm": float(out[0]["deviation_pp"]) * 1e3}))
"""


def _env(cache: str) -> dict:
    env = dict(os.environ, JAXDOBBY_CACHE_DIR=cache, PYTHONPATH=str(common.ROOT))
    env.pop(common.CACHE_ENV, None)
    return env


def _command() -> list[str]:
    exe = Path(sys.executable).parent / "jaxdobby"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "jaxdobby.cli"]


def command_line_modes(modes) -> list[dict]:
    """Wall time of ``jaxdobby simulate --modes k`` in a fresh process, empty cache folder."""
    rows = []
    for k in modes:
        with tempfile.TemporaryDirectory() as cache:
            t0 = time.perf_counter()
            out = subprocess.run(_command() + ["simulate", "--json", "--modes", str(k)],
                                 env=_env(cache), capture_output=True, text=True)
            rows.append({"modes": k, "cold_s": time.perf_counter() - t0,
                         "exit_code": out.returncode})
        print(f"  jaxdobby simulate --modes {k}: cold {rows[-1]['cold_s']:.1f} s "
              f"(exit {out.returncode})", flush=True)
    return rows


def command_line(repeats: int) -> dict:
    """Wall time of ``jaxdobby simulate`` cold (empty cache folder) and with it filled; and
    cold with the package's shipped executables switched off
    (``JAXDOBBY_SHIPPED_EXECUTABLES=off``: what a machine they do not fit waits, XLA
    compiling both programs)."""
    cmd = _command()
    cold, cached, compiled = [], [], []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as cache:
            for times in (cold, cached):
                t0 = time.perf_counter()
                subprocess.run(cmd + ["simulate", "--json"], env=_env(cache), check=True,
                               capture_output=True, text=True)
                times.append(time.perf_counter() - t0)
        with tempfile.TemporaryDirectory() as cache:
            t0 = time.perf_counter()
            subprocess.run(cmd + ["simulate", "--json"], check=True, capture_output=True,
                           env=dict(_env(cache), JAXDOBBY_SHIPPED_EXECUTABLES="off"), text=True)
            compiled.append(time.perf_counter() - t0)
    return {"cold_s": statistics.median(cold), "cold_all_s": cold,
            "cached_s": statistics.median(cached), "cached_all_s": cached,
            "cold_compiling_s": statistics.median(compiled), "cold_compiling_all_s": compiled,
            "shipped_executables": _executables_usable()}


def _executables_usable() -> bool:
    """Whether this machine loads the package's shipped executables."""
    out = subprocess.run([sys.executable, "-c", "from jaxdobby.programs import "
                          "executables_usable as u; print(u())"], env=_env("off"),
                         capture_output=True, text=True, check=True)
    return out.stdout.strip().endswith("True")


def against_modes(modes) -> list[dict]:
    rows = []
    for k in modes:
        out = subprocess.run([sys.executable, "-c", _ONE_SIZE, str(k)], env=_env("off"),
                             check=True, capture_output=True, text=True)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        r = rows[-1]
        print(f"  k = {k:2d}: trace+lower {r['trace_lower_s']:5.1f} s, compile "
              f"{r['compile_s']:5.1f} s, {r['stablehlo_lines']} lines, warm "
              f"{r['warm_s'] * 1e3:7.1f} ms", flush=True)
    return rows


def figure(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = [r["modes"] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    a.plot(k, [r["compile_s"] for r in rows], "o-", label="XLA compilation")
    a.plot(k, [r["trace_lower_s"] for r in rows], "s-", label="tracing + lowering")
    a.set(xlabel="modes kept k", ylabel="time [s]", title="simulate: compile time (cold)")
    a.legend()
    a.grid(alpha=0.3)
    b.loglog(k, [r["warm_per_step_us"] for r in rows], "o-", label="measured")
    ref = rows[min(range(len(rows)), key=lambda i: abs(rows[i]["modes"] - 4))]
    kk = [x for x in k if x >= ref["modes"]]
    for p, style in ((2, ":"), (3, "--")):
        b.loglog(kk, [ref["warm_per_step_us"] * (x / ref["modes"]) ** p for x in kk], style,
                 color="grey", label=f"∝ k{'²' if p == 2 else '³'}")
    b.set(xlabel="modes kept k", ylabel="warm time per step [µs]",
          title="simulate: run time per collocation step")
    b.legend()
    b.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def markdown(result) -> str:
    cl = result["command_line"]
    lines = ["# Compile time and first answer", "",
             "Each number in fresh processes (`benchmarks/compile_time.py`).", ""]
    if cl:
        lines += ["| `jaxdobby simulate` (whole process, wall) | median | all |", "|---|---|---|",
                  f"| cold: empty cache folder | {cl['cold_s']:.1f} s | "
                  + ", ".join(f"{t:.1f}" for t in cl["cold_all_s"]) + " |",
                  f"| cache filled (second run) | {cl['cached_s']:.1f} s | "
                  + ", ".join(f"{t:.1f}" for t in cl["cached_all_s"]) + " |"]
        if "cold_compiling_s" in cl:
            lines += [f"| cold, shipped executables off (XLA compiles) | "
                      f"{cl['cold_compiling_s']:.1f} s | "
                      + ", ".join(f"{t:.1f}" for t in cl["cold_compiling_all_s"]) + " |"]
        lines += [f"| `--modes {r['modes']}`, cold: empty cache folder | {r['cold_s']:.1f} s "
                  f"| exit {r['exit_code']} |" for r in result.get("command_line_modes") or []]
        lines += [""]
    if cl and "shipped_executables" in cl:
        lines += [("The package's shipped executables of the default configuration were "
                   + ("loaded" if cl["shipped_executables"] else "not usable here")
                   + " in the cold runs (`jaxdobby.programs`: Linux, x86-64-v3 CPU)."), ""]
    lines += ["| modes k | tracing + lowering [s] | XLA compile [s] | StableHLO lines | warm run "
              "[ms] | per step [µs] |", "|---|---|---|---|---|---|"]
    for r in result["modes"]:
        lines.append(f"| {r['modes']} | {r['trace_lower_s']:.1f} | {r['compile_s']:.1f} | "
                     f"{r['stablehlo_lines']} | {r['warm_s'] * 1e3:.1f} | "
                     f"{r['warm_per_step_us']:.0f} |")
    return "\n".join(lines) + "\n\n![compile time against modes](compile_time.png)\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="modes 1 and 4, one repeat (smoke)")
    p.add_argument("--modes", type=int, nargs="+", default=None)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-command-line", action="store_true")
    p.add_argument("--cli-modes", type=int, nargs="*", default=None,
                   help="sizes of the cold `jaxdobby simulate --modes k` runs (default 16 30)")
    p.add_argument("--out", default=str(common.RESULTS))
    ns = p.parse_args(argv)
    modes = ns.modes or ((1, 4) if ns.quick else DEFAULT_MODES)
    repeats = 1 if ns.quick else ns.repeats
    result = {"benchmark": "compile_time", "environment": common.environment(),
              "command_line": None}
    if not ns.no_command_line:
        print("jaxdobby simulate, cold and cached ...", flush=True)
        result["command_line"] = command_line(repeats)
        print(f"  cold {result['command_line']['cold_s']:.1f} s, cached "
              f"{result['command_line']['cached_s']:.1f} s", flush=True)
        cli_modes = ns.cli_modes if ns.cli_modes is not None else (() if ns.quick else (16, 30))
        result["command_line_modes"] = command_line_modes(cli_modes)
    print("compile time against modes ...", flush=True)
    result["modes"] = against_modes(modes)
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "compile_time_quick" if ns.quick else "compile_time"
    result["markdown"] = markdown(result).split("\n", 2)[2].rsplit("\n\n![", 1)[0]
    result["figure"] = f"{name}.png"
    (out / f"{name}.json").write_text(json.dumps(result, indent=1))
    (out / f"{name}.md").write_text(markdown(result))
    figure(result["modes"], out / f"{name}.png")
    print(f"wrote {out / name}.json, .md, .png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
