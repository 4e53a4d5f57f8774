"""Throughput of the dobby's batched steady-state evaluation, the path ``jaxdobby sobol`` runs.

Measures, on this machine, float64, compile time apart:

* samples per second of :data:`jaxdobby.sensitivity.DOBBY` (steady-state metrics of the coupled
  model, :func:`jaxdobby.batch.steady_state_metrics`) over rows of the default problem's Sobol
  design, in chunks of ``--chunk`` rows, on 1 and on 2 host devices (each device count in a
  fresh process, ``XLA_FLAGS=--xla_force_host_platform_device_count=K``; the chunk is split
  over the devices with ``shard_map``), median of ``--repeats`` timed passes over the rows;
* the wall time of the whole default study, ``jaxdobby sobol --n 1024 --second-order``
  (10 240 runs, analysis and figures included), on the fastest device count;
* with ``--accuracy``: the largest relative error of each metric at the 16 corners of the
  default box against the adaptive reference (``jaxdobby.simulate(method="adaptive")``,
  rtol 1e-8), the accuracy the throughput is measured at.

Writes ``benchmarks/results/sobol_throughput.json`` and ``.md``.

Run:  python benchmarks/sobol_throughput.py [--quick] [--accuracy]
"""

from __future__ import annotations

import argparse
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
    model = DOBBY.build(space)
    t0 = time.perf_counter()
    evaluate(model, rows[: args.chunk], chunk_size=args.chunk)  # trace + compile + one chunk
    first = time.perf_counter() - t0
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        ev = evaluate(model, rows, chunk_size=args.chunk)
        times.append(time.perf_counter() - t0)
    run = statistics.median(times)
    chunk_time = run * args.chunk / len(rows)
    out = {"devices": len(jax.devices()), "rows": int(len(rows)), "chunk": args.chunk,
           "seconds": run, "samples_per_s": len(rows) / run,
           "compile_s": max(first - chunk_time, 0.0),
           "failed": int(np.sum(~ev.outputs["ok"])),
           "mean_deviation_pp_mm": float(np.mean(ev.outputs["deviation_pp_mm"]))}
    if args.study:
        from jaxdobby.sensitivity import SobolConfig, run_sobol

        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            run = run_sobol(SobolConfig(n=1024, second_order=True, out=d, chunk_size=args.chunk))
            out["study_wall_s"] = time.perf_counter() - t0
            out["study_rows"] = int(run.evaluation.outputs["ok"].size)
            st = run.result.metrics["deviation_pp_mm"].ST
            out["study_ST_deviation_pp"] = dict(zip(run.space.names, map(float, st)))
    return out


def in_subprocess(devices: int, args) -> dict:
    env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={devices}",
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, __file__, "--worker", "--n", str(args.n), "--rows", str(args.rows),
           "--chunk", str(args.chunk), "--repeats", str(args.repeats)]
    if args.study and devices == max(args.devices):
        cmd.append("--study")
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"worker with {devices} devices failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def accuracy() -> dict:
    """Largest relative error per metric over the 16 corners, batch vs adaptive reference."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from jaxdobby import simulate
    from jaxdobby.batch import METRICS, steady_state_metrics
    from jaxdobby.parameters import Setup, apply

    rpm = 3.141592653589793 / 30.0
    names = ("speed", "warp_force", "stroke", "thickness")
    lo, hi = (400 * rpm, 345.0, 0.080, 0.006), (1200 * rpm, 1035.0, 0.140, 0.008)
    rows = [[hi[i] if b else lo[i] for i, b in enumerate(bits)]
            for bits in itertools.product([0, 1], repeat=4)]

    def setup(r):
        return apply(Setup(), dict(zip(names, r)))

    batch = jax.jit(jax.vmap(lambda r: steady_state_metrics(setup(r))))(jnp.asarray(rows))
    worst = dict.fromkeys(METRICS, 0.0)
    for i, r in enumerate(rows):
        s = setup(jnp.asarray(r))
        ref = simulate(s.machine, s.operating, method="adaptive").metrics
        for m in METRICS:
            err = abs(float(batch[m][i]) - float(ref[m])) / abs(float(ref[m]))
            worst[m] = max(worst[m], err)
    return {"corners": len(rows), "max_relative_error": worst}


def markdown(result: dict) -> str:
    lines = ["| devices | rows | chunk | samples/s | compile [s] | failed |",
             "|---|---|---|---|---|---|"]
    for r in result["runs"]:
        lines.append(f"| {r['devices']} | {r['rows']} | {r['chunk']} | "
                     f"{r['samples_per_s']:.0f} | {r['compile_s']:.1f} | {r['failed']} |")
    for r in result["runs"]:
        if "study_wall_s" in r:
            lines.append("")
            lines.append(f"Default study (`jaxdobby sobol --n 1024 --second-order`, "
                         f"{r['study_rows']} runs) on {r['devices']} device(s): "
                         f"**{r['study_wall_s']:.1f} s** wall, compilation and analysis included.")
    if "accuracy" in result:
        errs = ", ".join(f"{k} {v:.1e}" for k, v in result["accuracy"]["max_relative_error"].items())
        lines.append("")
        lines.append(f"Accuracy at the 16 corners of the default box, largest relative error "
                     f"against the adaptive reference: {errs}.")
    lines.append("")
    lines.append(f"Measured {result['date']} on {result['machine']}, jax {result['jax']}.")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke size (a few seconds of running)")
    ap.add_argument("--devices", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--n", type=int, default=1024, help="base samples of the design")
    ap.add_argument("--rows", type=int, default=2048, help="rows timed per pass")
    ap.add_argument("--chunk", type=int, default=256, help="rows per chunk")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-study", dest="study", action="store_false",
                    help="skip the full default study")
    ap.add_argument("--accuracy", action="store_true",
                    help="also the corners against the adaptive reference (minutes)")
    ap.add_argument("--out", default=str(RESULTS))
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args)))
        return 0
    if args.quick:
        args.rows, args.chunk, args.repeats, args.study = 16, 8, 1, False
    import jax

    result = {"benchmark": "sobol_throughput", "quick": args.quick,
              "date": datetime.datetime.now().isoformat(timespec="seconds"),
              "machine": f"{platform.processor() or platform.machine()}, "
                         f"{os.cpu_count()} cores, {platform.system()}",
              "python": platform.python_version(), "jax": jax.__version__,
              "runs": [in_subprocess(d, args) for d in args.devices]}
    if args.accuracy:
        result["accuracy"] = accuracy()
    result["markdown"] = markdown(result)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "sobol_throughput_quick" if args.quick else "sobol_throughput"
    (out / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / f"{name}.md").write_text(result["markdown"])
    print(result["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
