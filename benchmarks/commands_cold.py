"""How long each command of the command line takes a new user: cold and with the cache filled.

Each command with its defaults, as a whole process (wall time: import, tracing, compiling or
loading the package's shipped executables, the run, the output), in fresh processes:

* **cold**: an empty cache folder (``JAXDOBBY_CACHE_DIR`` a new temporary directory: no XLA
  executable and no stored program but the package's shipped ones);
* **cache filled**: the same command again with that folder.

The commands (``--commands`` picks some by name): ``simulate``, ``sweep speed``, ``sweep
modes``, ``campbell``, ``beam``, ``loom --weave twill22``, ``sobol`` (the default study,
10 240 runs), ``optimize`` (the default design study), ``identify`` (a two-parameter fit of
two periods of the default machine's own steady cycle, as ``jaxdobby simulate --out`` writes
it). With
``--commands``, the other commands' rows of the previous results are kept.

Writes ``results/commands_cold.json`` and ``.md``.

Run:  python benchmarks/commands_cold.py [--quick] [--commands simulate campbell ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/commands_cold.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common as common
from benchmarks.compile_time import _command, _env

COMMANDS = {
    "simulate": ["simulate"],
    "sweep speed": ["sweep", "speed"],
    "sweep modes": ["sweep", "modes"],
    "campbell": ["campbell"],
    "beam": ["beam"],
    "loom": ["loom", "--weave", "twill22"],
    "sobol": ["sobol"],
    "optimize": ["optimize"],
    "identify": ["identify", "measured.csv", "--fit", "heald_frame_mass_kg", "damping_ratio"],
}
"""Name → the command's arguments (its defaults otherwise)."""

INPUTS = {"identify": "measured.csv"}
"""Name → the input file the command reads from its working folder (:func:`measured_trace`)."""


def measured_trace(path: Path) -> None:
    """A measured-like trace for ``jaxdobby identify``: two periods of the default machine's
    steady cycle as ``jaxdobby simulate --out`` writes it (its own cache folder, so that the
    timed runs' stays empty), in the columns identify reads."""
    import numpy as np

    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        subprocess.run(_command() + ["simulate", "--out", out], env=_env(cache), check=True,
                       capture_output=True)
        data = np.genfromtxt(Path(out) / "timeseries.csv", delimiter=",", names=True)
    t, period = data["t_s"][:-1], data["t_s"][-1]  # the last sample repeats the first
    cycle = np.column_stack([data["acceleration_flexible_m_s2"], data["heald_flexible_mm"]])[:-1]
    # two cycles of the periodic steady state (identify asks for more than one)
    table = np.column_stack([np.concatenate([t, t + period]), np.concatenate([cycle, cycle])])
    np.savetxt(path, table, delimiter=",", fmt="%.17g", comments="",
               header="time_s,heald_frame_acceleration_m_s2,heald_frame_position_mm")

QUICK = ("simulate", "beam")
"""The smoke run's commands (``--quick``)."""


def timed_command(args: list[str], cache: str, workdir: str) -> dict:
    """One whole process of ``jaxdobby ARGS`` with the cache folder ``cache``."""
    t0 = time.perf_counter()
    out = subprocess.run(_command() + args, env=_env(cache), capture_output=True, text=True,
                         cwd=workdir)
    return {"wall_s": time.perf_counter() - t0, "exit_code": out.returncode,
            "stderr_tail": out.stderr[-300:] if out.returncode not in (0, 1) else ""}


def measure(names) -> list[dict]:
    """Cold and cache-filled wall time of each named command (see the module docstring)."""
    rows = []
    for name in names:
        # each run in a new working folder: commands refuse to overwrite a run's output
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as a, \
                tempfile.TemporaryDirectory() as b:
            if name in INPUTS:
                measured_trace(Path(a) / INPUTS[name])
                (Path(b) / INPUTS[name]).write_bytes((Path(a) / INPUTS[name]).read_bytes())
            cold = timed_command(COMMANDS[name], cache, a)
            again = timed_command(COMMANDS[name], cache, b)
        rows.append({"command": "jaxdobby " + " ".join(COMMANDS[name]), "cold_s": cold["wall_s"],
                     "cached_s": again["wall_s"], "exit_codes": [cold["exit_code"],
                                                                 again["exit_code"]],
                     "stderr_tail": cold["stderr_tail"]})
        print(f"  {rows[-1]['command']}: cold {cold['wall_s']:.1f} s, cache filled "
              f"{again['wall_s']:.1f} s (exit {cold['exit_code']}, {again['exit_code']})",
              flush=True)
    return rows


def markdown(rows: list[dict]) -> str:
    lines = ["| command (defaults) | cold: empty cache folder | cache filled | exit codes |",
             "|---|---|---|---|"]
    lines += [f"| `{r['command']}` | {r['cold_s']:.1f} s | {r['cached_s']:.1f} s | "
              f"{', '.join(map(str, r['exit_codes']))} |" for r in rows]
    return "\n".join(lines) + (
        "\n\nWhole processes, wall time, one run each. Exit code 1: the command ran and "
        "reported a run outside its limits (not converged), 2: bad input.")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK)} (smoke)")
    p.add_argument("--commands", nargs="+", choices=list(COMMANDS), default=None)
    p.add_argument("--out", default=str(common.RESULTS))
    ns = p.parse_args(argv)
    names = ns.commands or (QUICK if ns.quick else list(COMMANDS))
    common.configure_jax()  # float64, as the commands compute (recorded in the environment)
    result = {"benchmark": "commands_cold", "quick": ns.quick,
              "environment": common.environment()}
    print("each command cold and with the cache filled ...", flush=True)
    result["rows"] = measure(names)
    previous = Path(ns.out) / "commands_cold.json"
    if ns.commands and not ns.quick and previous.exists():  # the other commands' rows stay
        done = {r["command"] for r in result["rows"]}
        kept = [r for r in json.loads(previous.read_text())["rows"] if r["command"] not in done]
        order = ["jaxdobby " + " ".join(args) for args in COMMANDS.values()]
        result["rows"] = sorted(kept + result["rows"], key=lambda r: order.index(r["command"])
                                if r["command"] in order else len(order))
        result["merged"] = "rows of other commands kept from the previous run"
    result["markdown"] = markdown(result["rows"])
    name = "commands_cold_quick" if ns.quick else "commands_cold"
    common.write_json(Path(ns.out) / f"{name}.json", common.finish(result))
    (Path(ns.out) / f"{name}.md").write_text(result["markdown"] + "\n")
    print(result["markdown"])
    return 0 if all(c in (0, 1) for r in result["rows"] for c in r["exit_codes"]) else 1


if __name__ == "__main__":
    sys.exit(main())
