"""Throughput of the dobby's batched steady-state evaluation, the path ``jaxdobby sobol`` runs.

Measures, on this machine, float64, compile time apart:

* samples per second of :data:`jaxdobby.sensitivity.DOBBY` (steady-state metrics of the coupled
  model, :func:`jaxdobby.periodic.steady_state_metrics`, each row's steps per cycle by its
  speed and rows grouped by them into chunks, as the command runs it) over rows of the default
  problem's Sobol design, in chunks of ``--chunk`` rows (default: the command's, 64 per device): in 1 and in 2 concurrent processes of one CPU device
  each (each its share of the rows, timing started together after all have compiled), and in
  one process of 2 CPU devices (``shard_map``, what a plain ``jaxdobby sobol`` does on a 2-core
  machine); median of ``--repeats`` timed passes;
* the wall time of the whole default study, ``jaxdobby sobol --n 1024 --second-order``
  (10 240 runs, analysis and figures included): in one process without a compilation cache,
  again with the command line's persistent cache filled by a previous run (what a user's
  second study of the same problem costs), and in 2 processes joined by ``jax.distributed``;
* with ``--accuracy``: the largest relative error of each metric at the 16 corners of the
  default box against the adaptive reference (``jaxdobby.simulate(method="adaptive")``,
  rtol 1e-8), the accuracy the throughput is measured at;
* with ``--steps N``: the same at N collocation steps per cycle for every row instead of the
  default's by speed (``jaxdobby sobol --steps N``), written to ``sobol_throughput_steps<N>.json``
  (``--steps 432``: every row at the most the default uses, its speed's baseline).

Writes ``benchmarks/results/sobol_throughput.json`` and ``.md``.

Run:  python benchmarks/sobol_throughput.py [--quick] [--accuracy] [--steps N]
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import itertools
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"


def worker(args) -> dict:
    """Time the evaluation in this process (its device count set by the parent)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    from jaxdobby.sensitivity import DOBBY, ParameterSpace, evaluate

    space = ParameterSpace.from_names(DOBBY.default_names, DOBBY.parameters)
    rows = space.sample(args.n, second_order=True, seed=0)[: args.rows]
    rows = rows[args.share::args.of]  # this process's share of the rows
    model = DOBBY.builder(args.steps)(space)
    from jaxdobby.sensitivity.command import default_chunk

    args.chunk = args.chunk or default_chunk(args.devices)  # a plain jaxdobby sobol's
    # as the command: without --steps each row's steps per cycle follow its speed, and rows
    # of one step count share chunks (padded: counted in the time, not in the rows)
    groups = DOBBY.row_groups(space, rows) if args.steps is None else None
    t0 = time.perf_counter()
    evaluate(model, rows[: args.chunk], chunk_size=args.chunk, devices=args.devices,
             groups=None if groups is None else groups[: args.chunk])  # trace + compile + one chunk
    first = time.perf_counter() - t0
    if args.barrier:  # start timing together with the other processes
        Path(f"{args.barrier}.ready{args.share}").touch()
        while not Path(f"{args.barrier}.go").exists():
            time.sleep(0.05)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        ev = evaluate(model, rows, chunk_size=args.chunk, devices=args.devices, groups=groups)
        times.append(time.perf_counter() - t0)
    run = statistics.median(times)
    chunk_time = run * args.chunk / len(rows)
    out = {"devices": len(jax.devices()), "processes": args.of, "rows": len(rows),
           "chunk": args.chunk,
           "mean_steps": float(np.mean(groups)) if groups is not None else args.steps or 432,
           "seconds": run, "samples_per_s": len(rows) / run,
           "compile_s": max(first - chunk_time, 0.0),
           "failed": int(np.sum(~ev.outputs["ok"])),
           "mean_deviation_pp_mm": float(np.mean(ev.outputs["deviation_pp_mm"]))}
    return out


def _env(devices: int = 1, cache: str = "off") -> dict:
    """Environment of a child process with ``devices`` CPU devices (0: the CLI's default, one
    per core) and the command line's compilation cache at ``cache`` ("off": none)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               JAXDOBBY_CACHE_DIR=cache)
    env.pop("XLA_FLAGS", None)
    if devices:
        env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    return env


def _worker_cmd(args, share: int, of: int, barrier: str | None, devices: int = 1) -> list[str]:
    cmd = [sys.executable, __file__, "--worker", "--devices", str(devices), "--n", str(args.n), "--rows", str(args.rows),
           "--chunk", str(args.chunk or 0), "--repeats", str(args.repeats), "--share", str(share),
           "--of", str(of), "--no-study"] + (
               ["--steps", str(args.steps)] if args.steps else [])
    return cmd + (["--barrier", barrier] if barrier else [])


def in_processes(processes: int, args, devices: int = 1) -> dict:
    """Rows timed in ``processes`` concurrent processes of ``devices`` CPU devices each (their
    shares), timing started together after every process has compiled; samples/s = rows /
    slowest."""
    with tempfile.TemporaryDirectory() as d:
        barrier = str(Path(d) / "sync") if processes > 1 else None
        procs = [subprocess.Popen(_worker_cmd(args, i, processes, barrier, devices),
                                  env=_env(devices),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                 for i in range(processes)]
        if barrier:
            while not all(Path(f"{barrier}.ready{i}").exists() for i in range(processes)):
                if any(p.poll() not in (None, 0) for p in procs):
                    break
                time.sleep(0.1)
            Path(f"{barrier}.go").touch()
        outs = [p.communicate() for p in procs]
    for p, (_, err) in zip(procs, outs):
        if p.returncode != 0:
            raise RuntimeError(f"worker failed:\n{err[-3000:]}")
    runs = [json.loads(o.strip().splitlines()[-1]) for o, _ in outs]
    rows = sum(r["rows"] for r in runs)
    seconds = max(r["seconds"] for r in runs)
    return {"devices": devices, "processes": processes, "rows": rows, "chunk": runs[0]["chunk"],
            "seconds": seconds, "samples_per_s": rows / seconds,
            "compile_s": max(r["compile_s"] for r in runs),
            "mean_steps": sum(r["mean_steps"] * r["rows"] for r in runs) / rows,
            "failed": sum(r["failed"] for r in runs)}


def default_study(processes: int, cache: str = "off", executables: bool = True) -> dict:
    """Wall time of `jaxdobby sobol --n 1024 --second-order` in ``processes`` processes joined
    by jax.distributed on localhost (compilation, analysis and figures included), with the
    compilation cache at ``cache`` ("off": none); ``executables`` False: the package's
    shipped executables off (``JAXDOBBY_SHIPPED_EXECUTABLES=off``, XLA compiles)."""
    import socket

    with socket.socket() as sock:
        sock.bind(("localhost", 0))
        port = sock.getsockname()[1]
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "jaxdobby.cli", "sobol", "--n", "1024", "--second-order",
               "--out", str(Path(d) / "run"), "--json"]
        if processes > 1:
            cmd += ["--coordinator", f"localhost:{port}", "--num-processes", str(processes)]
        t0 = time.perf_counter()
        env = _env(1, cache) if processes > 1 else _env(0, cache)
        if not executables:
            env["JAXDOBBY_SHIPPED_EXECUTABLES"] = "off"
        procs = [subprocess.Popen(cmd + (["--process-id", str(i)] if processes > 1 else []),
                                  env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True) for i in range(processes)]
        outs = [p.communicate() for p in procs]
        wall = time.perf_counter() - t0
    for p, (_, err) in zip(procs, outs):
        if p.returncode != 0:
            raise RuntimeError(f"sobol failed:\n{err[-3000:]}")
    indices = json.loads(outs[0][0])
    st = indices["metrics"]["deviation_pp_mm"]["ST"]
    return {"processes": processes, "rows": 10240, "study_wall_s": wall,
            "cache": "off" if cache == "off" else "filled", "study_ST_deviation_pp": st,
            "shipped_executables": executables and processes == 1 and _executables_usable()}


def _executables_usable() -> bool:
    """Whether a default study here loads the package's shipped chunk executable (this
    machine runs them, and the CLI's one device per core is the 2 it was compiled for)."""
    out = subprocess.run([sys.executable, "-c", "import os; from jaxdobby.programs import "
                          "executables_usable as u; print(u() and os.cpu_count() == 2)"],
                         env=_env(0), capture_output=True, text=True, check=True)
    return out.stdout.strip().endswith("True")


def cached_study() -> dict:
    """:func:`default_study` in one process with a persistent compilation cache that a first,
    untimed run of the same study filled."""
    with tempfile.TemporaryDirectory() as cache:
        default_study(1, cache)
        return default_study(1, cache)


def accuracy(steps: int | None = None) -> dict:
    """Largest relative error per metric over the 16 corners, batch vs adaptive reference, at
    ``steps`` collocation steps per cycle (None: the default's, by each corner's speed)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from jaxdobby import simulate
    from jaxdobby.periodic import METRICS, steady_state_metrics
    from jaxdobby.parameters import Setup, apply

    rpm = 3.141592653589793 / 30.0
    names = ("speed", "warp_force", "stroke", "thickness")
    lo, hi = (400 * rpm, 345.0, 0.080, 0.006), (1200 * rpm, 1035.0, 0.140, 0.008)
    rows = [[hi[i] if b else lo[i] for i, b in enumerate(bits)]
            for bits in itertools.product([0, 1], repeat=4)]

    def setup(r):
        return apply(Setup(), dict(zip(names, r)))

    n = steps or "speed"
    batch = jax.jit(jax.vmap(lambda r: steady_state_metrics(setup(r), steps=n)))(
        jnp.asarray(rows))
    worst = dict.fromkeys(METRICS, 0.0)
    for i, r in enumerate(rows):
        s = setup(jnp.asarray(r))
        ref = simulate(s.machine, s.operating, method="adaptive").metrics
        for m in METRICS:
            err = abs(float(batch[m][i]) - float(ref[m])) / abs(float(ref[m]))
            worst[m] = max(worst[m], err)
    return {"corners": len(rows), "steps": n, "max_relative_error": worst}


def markdown(result: dict) -> str:
    lines = ["| processes × devices | rows | mean steps | chunk | samples/s | compile [s] | failed |",
             "|---|---|---|---|---|---|---|"]
    for r in result["runs"]:
        lines.append(f"| {r['processes']} × {r['devices']} | {r['rows']} | "
                     f"{r.get('mean_steps', 432):.0f} | {r['chunk']} | "
                     f"{r['samples_per_s']:.0f} | {r['compile_s']:.1f} | {r['failed']} |")
    for r in result.get("studies", []):
        cache = ("with the persistent compilation cache filled by a previous run"
                 if r.get("cache") == "filled" else "no compilation cache")
        if r.get("cache") != "filled" and "shipped_executables" in r:
            cache += (", the package's shipped executable loaded" if r["shipped_executables"]
                      else ", XLA compiling (no shipped executable used)")
        lines.append("")
        lines.append(f"Default study (`jaxdobby sobol --n 1024 --second-order`, {r['rows']} runs) "
                     f"in {r['processes']} process(es), {cache}: **{r['study_wall_s']:.0f} s** "
                     "wall, compilation (or loading it), analysis and figures included.")
    if "accuracy" in result:
        errs = ", ".join(f"{k} {v:.1e}" for k, v in result["accuracy"]["max_relative_error"].items())
        lines.append("")
        when = result["accuracy"].get("date")  # kept from an earlier run without --accuracy
        lines.append(f"Accuracy at the 16 corners of the default box, largest relative error "
                     f"against the adaptive reference: {errs}"
                     + (f" (measured {when})." if when else "."))
    if result.get("steps"):
        lines.append("")
        lines.append(f"At {result['steps']} collocation steps per cycle (`jaxdobby sobol --steps "
                     f"{result['steps']}`) for every row, not the default's by speed.")
    lines.append("")
    lines.append(f"Measured {result['date']} on {result['machine']}, jax {result['jax']}.")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke size (a few seconds of running)")
    ap.add_argument("--processes", type=int, nargs="+", default=[1, 2],
                    help="process counts to time (one CPU device each)")
    ap.add_argument("--devices-list", type=int, nargs="+", default=[2],
                    help="CPU device counts to time in one process (shard_map)")
    ap.add_argument("--devices", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--n", type=int, default=1024, help="base samples of the design")
    ap.add_argument("--rows", type=int, default=10240,
                    help="rows timed per pass (default: the whole default study's 10 240, whose "
                         "speeds give the command's mix of steps per cycle and chunk padding)")
    ap.add_argument("--chunk", type=int, default=None,
                    help="rows per chunk (default: a plain jaxdobby sobol's on that many devices, "
                         "64 per device)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-study", dest="study", action="store_false",
                    help="skip the full default study")
    ap.add_argument("--accuracy", action="store_true",
                    help="also the corners against the adaptive reference (minutes)")
    ap.add_argument("--steps", type=int, default=None,
                    help="collocation steps per cycle of every row (default: the model's, by each "
                         "row's speed, 216-432)")
    ap.add_argument("--out", default=str(RESULTS))
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--share", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--of", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--barrier", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args)))
        return 0
    if args.quick:
        args.rows, args.chunk, args.repeats, args.study = 16, 8, 1, False
    if args.steps:  # the default study is the default steps' (jaxdobby sobol without --steps)
        args.study = False
    name = ("sobol_throughput" + (f"_steps{args.steps}" if args.steps else "")
            + ("_quick" if args.quick else ""))
    import jax

    result = {"benchmark": name.removesuffix("_quick"), "quick": args.quick,
              "date": datetime.datetime.now().isoformat(timespec="seconds"),
              "machine": f"{platform.processor() or platform.machine()}, "
                         f"{os.cpu_count()} cores, {platform.system()}",
              "python": platform.python_version(), "jax": jax.__version__,
              **({"steps": args.steps} if args.steps else {}),
              "runs": [in_processes(p, args) for p in args.processes]
              + [in_processes(1, args, d) for d in args.devices_list if d > 1]}
    if args.study:
        result["studies"] = [default_study(1), default_study(1, executables=False),
                             cached_study()] + (
            [default_study(max(args.processes))] if max(args.processes) > 1 else [])
    if args.accuracy:
        result["accuracy"] = accuracy(args.steps)
    else:  # keep the corners of the last run that measured them, with their date
        with contextlib.suppress(OSError, ValueError, KeyError):
            last = json.loads((Path(args.out) / f"{name}.json").read_text())
            result["accuracy"] = {"date": last["date"], **last["accuracy"]}  # its own date wins
    result["markdown"] = markdown(result)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / f"{name}.md").write_text(result["markdown"])
    print(result["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
