"""Parameter batches: jaxdobby's batch path on 1 and 2 devices against scipy loops.

The samples are a scrambled Sobol sequence (seed 0) over the default box of the sensitivity
study (speed 400–1200 r/min, warp force 345–1035 N, stroke 80–140 mm, arm thickness 6–8 mm).

* jaxdobby: :func:`jaxdobby.periodic.steady_state_metrics` (default ``steps``) of
  ``jaxdobby.parameters.apply(Setup(), sample)``, under ``jax.vmap`` + ``jax.jit`` in chunks of
  fixed size (the last one padded) — the Sobol pipeline's compiled chunk function — each device
  count in a fresh process (``XLA_FLAGS=--xla_force_host_platform_device_count=K``; a chunk is
  split over the devices with ``shard_map``); compile time apart; the median of repeated passes
  over all samples (one pass above 1024 samples).
* scipy serial loop: for each sample, build the model (the modal matrices both sides share) and
  find the periodic steady state by cycling ``solve_ivp`` with the plain numpy right-hand side
  (:func:`benchmarks.scipy_steady.solve_setup`); timed on the first few samples and
  extrapolated (median seconds per sample × samples).
* scipy with ``multiprocessing`` (a pool of 2 spawned processes, one per core): the same per
  sample, with the numpy and with the jitted right-hand side; throughput measured on a subset
  after the workers have compiled, extrapolated.

Two cores for jaxdobby: by default two host devices in one process
(``XLA_FLAGS=--xla_force_host_platform_device_count=2``, a chunk split over them with
``shard_map``, the Sobol pipeline's way); ``--two processes`` runs two concurrent one-device
processes instead, each with half of every batch. (Two host devices hung on this machine until
the batch path built each sample's model sequentially: two batched LAPACK calls deadlocked
jaxlib's 2-thread pool; see ``jaxdobby.periodic.steady.model_terms``.)

Accuracy, on the scipy subset: the batch metrics and the scipy metrics against a tight reference
(DOP853, rtol 1e-10, jitted right-hand side) on the same samples.

Run:  python benchmarks/bench_batch.py [--quick] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common as common

NAMES = ("speed", "warp_force", "stroke", "thickness")


def samples(n: int, seed: int = 0):
    """n Sobol rows over the default box, users' units (r/min, N, mm, mm), shape (n, 4)."""
    from scipy.stats import qmc

    from jaxdobby.parameters import PARAMETERS

    lo = [PARAMETERS[k].bounds[0] for k in NAMES]
    hi = [PARAMETERS[k].bounds[1] for k in NAMES]
    unit = qmc.Sobol(d=len(NAMES), scramble=True, seed=seed).random(n)
    return qmc.scale(unit, lo, hi)


def setup_of(row, modes: int):
    """The :class:`~jaxdobby.parameters.Setup` of one row (users' units); jittable."""
    from jaxdobby import Machine
    from jaxdobby.parameters import PARAMETERS, Setup, apply

    base = Setup(machine=Machine.default(n_modes=modes))
    return apply(base, {k: row[i] * PARAMETERS[k].scale for i, k in enumerate(NAMES)})


# -- jaxdobby, in a process with K devices -------------------------------------------------------
def jax_worker(sizes: list[int], chunk: int, repeats: int, modes: int, keep: int,
               part: int = 0, parts: int = 1) -> dict:
    """Time the batch path on every size in this process (its device count set by the parent).

    The per-chunk function is the Sobol pipeline's (:func:`jaxdobby.sensitivity.batch.
    chunk_function` of :func:`jaxdobby.sensitivity.dobby.dobby_model`: one row in users' units →
    :func:`jaxdobby.periodic.steady_state_metrics` of ``apply(Setup(), row)``, vmapped, split over
    the devices with ``shard_map``), compiled once; this loop feeds it chunks as
    :func:`jaxdobby.sensitivity.batch.evaluate` does, without recompiling per call.
    With ``parts`` > 1 this process takes every ``parts``-th row from ``part`` on of each size
    (one of several processes sharing the batch)."""
    jax = common.configure_jax()
    import numpy as np

    from jaxdobby import Machine
    from jaxdobby.periodic import DEFAULT_STEPS
    from jaxdobby.parameters import Setup
    from jaxdobby.sensitivity.batch import chunk_function
    from jaxdobby.sensitivity.dobby import DOBBY_PARAMETERS, METRIC_UNITS, dobby_model
    from jaxdobby.sensitivity.space import ParameterSpace

    devices = jax.devices()
    space = ParameterSpace.from_names(NAMES, DOBBY_PARAMETERS)
    model = dobby_model(Setup(machine=Machine.default(n_modes=modes)), steps=DEFAULT_STEPS)(space)
    t0 = time.perf_counter()
    compiled, sharding = chunk_function(model, chunk, len(NAMES), devices)
    compile_s = time.perf_counter() - t0
    rows_all = samples(max(sizes))

    def run(rows):
        n = len(rows)
        padded = np.concatenate([rows, np.repeat(rows[-1:], (-n) % chunk, axis=0)])
        outs = [compiled(jax.device_put(padded[i:i + chunk], sharding))
                for i in range(0, len(padded), chunk)]
        outs = jax.block_until_ready(outs)
        return {k: np.concatenate([np.asarray(o[k]) for o in outs])[:n] for k in outs[0]}

    t0 = time.perf_counter()
    run(rows_all[:chunk])
    first = time.perf_counter() - t0
    results = []
    for n in sizes:
        t = common.timed(lambda n=n: run(rows_all[:n][part::parts]),
                         repeats=repeats if n <= 1024 else 1, budget_s=120.0)
        out = t["value"]
        results.append({"samples": n, "median_s": t["median_s"], "min_s": t["min_s"],
                        "repeats": t["repeats"], "samples_per_s": n / t["median_s"],
                        "ok_fraction": float(np.mean(out["ok"]))})
        common.log(f"jaxdobby batch, {len(devices)} device(s), {n} samples: "
                   f"{t['median_s']:.2f} s ({n / t['median_s']:.0f}/s)")
    first_rows = run(rows_all[:keep])
    si = {key: (first_rows[name] / factor).tolist() for key, (name, factor) in METRIC_UNITS.items()}
    return {"devices": len(devices), "part": part, "parts": parts, "chunk": chunk, "steps": DEFAULT_STEPS,
            "compile_s": compile_s, "first_chunk_s": first, "sizes": results,
            "first_metrics": si}


def _worker_command(ns, sizes, part=0, parts=1):
    return [sys.executable, "-m", "benchmarks.bench_batch", "--worker", "--chunk", str(ns.chunk),
            "--repeats", str(ns.repeats), "--modes", str(ns.modes), "--keep",
            str(ns.scipy_samples), "--part", str(part), "--parts", str(parts), "--sizes",
            *map(str, sizes)]


def _finish(p) -> dict:
    out, err = p.communicate()
    sys.stderr.write(err[-3000:])
    if p.returncode:
        raise RuntimeError(f"batch worker failed (exit {p.returncode})")
    return json.loads(out.strip().splitlines()[-1])


def jax_in_subprocess(devices: int, ns, sizes: list[int]) -> dict:
    """The batch path in a fresh process with ``devices`` host devices."""
    return _finish(start_jax_subprocess(devices, ns, sizes))


def start_jax_subprocess(devices: int, ns, sizes: list[int]) -> subprocess.Popen:
    """:func:`jax_in_subprocess` started, not waited for (``_finish`` it)."""
    env = dict(os.environ, PYTHONPATH=str(common.ROOT),
               XLA_FLAGS=(os.environ.get("XLA_FLAGS", "")
                          + f" --xla_force_host_platform_device_count={devices}").strip())
    return subprocess.Popen(_worker_command(ns, sizes), cwd=common.ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def jax_in_processes(processes: int, ns, sizes: list[int]) -> dict:
    """The batch path on ``processes`` cores as as many concurrent 1-device processes, each with
    its share of every batch (started together; a size's time is the slowest share's)."""
    env = dict(os.environ, PYTHONPATH=str(common.ROOT))
    procs = [subprocess.Popen(_worker_command(ns, sizes, i, processes), cwd=common.ROOT,
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for i in range(processes)]
    parts = [_finish(p) for p in procs]
    out = dict(parts[0], devices=1, processes=processes, parts_raw=parts,
               compile_s=max(r["compile_s"] for r in parts))
    out["sizes"] = []
    for n, rows in zip(sizes, zip(*(r["sizes"] for r in parts))):
        slowest = max(r["median_s"] for r in rows)
        out["sizes"].append({"samples": n, "median_s": slowest, "samples_per_s": n / slowest,
                             "ok_fraction": min(r["ok_fraction"] for r in rows),
                             "repeats": rows[0]["repeats"]})
    return out


# -- scipy ---------------------------------------------------------------------------------------
_SCIPY: dict = {}


def _scipy_init(options: dict) -> None:
    """Pool initialiser: float64, then one solve to compile jaxdobby's model build (and the
    jitted right-hand side) in this worker, outside the timed region."""
    common.configure_jax()
    _SCIPY.update(options)
    _scipy_one(samples(1)[0], rtol_scale=100.0)


def _scipy_one(row, rtol_scale: float = 1.0) -> dict:
    from benchmarks.scipy_steady import solve_setup

    o = _SCIPY
    run = solve_setup(setup_of(row, o["modes"]), rhs=o["rhs"], method=o["method"],
                      rtol=o["rtol"] * rtol_scale, tolerance=o["tolerance"])
    return {"seconds": run.seconds, "metrics": run.metrics, "converged": run.converged,
                "nfev": run.counter.nfev, "period_maps": run.counter.period_maps}


def _ready(_):
    time.sleep(0.05)  # hold the worker a moment, so that the others get tasks too
    return os.getpid()


def scipy_serial(rows, options: dict) -> dict:
    """The plain loop in this process (compilation of the model build excluded by a warm-up)."""
    _scipy_init(options)
    runs = [_scipy_one(r) for r in rows]
    for r in runs:
        common.log(f"scipy serial ({options['rhs']} RHS): {r['seconds']:.1f} s, "
                   f"{r['period_maps']} cycles")
    return dict(options, per_sample_s=statistics.median(r["seconds"] for r in runs),
                measured=len(runs), runs=runs)


def scipy_pool(rows, options: dict, processes: int = 2) -> dict:
    """``multiprocessing.Pool`` (spawn) over the rows; wall time after the workers are ready."""
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(processes, initializer=_scipy_init, initargs=(options,)) as pool:
        # wait until every worker has run its initializer (compiling the model build), so that
        # the timing starts with the whole pool ready
        pids, deadline = set(), time.perf_counter() + 300.0
        while len(pids) < processes and time.perf_counter() < deadline:
            pids |= set(pool.map(_ready, range(4 * processes), chunksize=1))
        t0 = time.perf_counter()
        runs = pool.map(_scipy_one, list(rows), chunksize=1)
        wall = time.perf_counter() - t0
    common.log(f"scipy pool of {processes} ({options['rhs']} RHS): {len(rows)} samples in "
               f"{wall:.1f} s")
    return dict(options, processes=processes, workers_seen=len(pids), measured=len(runs),
                wall_s=wall, per_sample_s=wall / len(runs), runs=runs)


def reference_metrics(rows, modes: int, rtol: float) -> list[dict]:
    """Tight scipy reference (DOP853, jitted RHS) on the rows."""
    from benchmarks.scipy_steady import solve_setup

    return [solve_setup(setup_of(r, modes), rhs="jitted", method="DOP853", rtol=rtol,
                        tolerance=max(100 * rtol, 1e-9)).metrics for r in rows]


def markdown(rows: list[dict]) -> str:
    lines = [("| samples | jaxdobby 1 device [s] | jaxdobby 2 cores [s] | scipy serial, numpy RHS"
             " [s] | scipy 2 processes, numpy RHS [s] | scipy 2 processes, jitted RHS [s] |"
             " best jaxdobby vs serial numpy | vs 2 processes jitted |"),
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        star = "*" if r.get("jaxdobby_1_device_extrapolated") else ""
        lines.append(f"| {r['samples']} | {r['jaxdobby_1_device_s']:.3g}{star} | "
                     f"{r['jaxdobby_2_devices_s']:.3g} | {r['scipy_serial_numpy_s']:.3g}* | "
                     f"{r['scipy_pool_numpy_s']:.3g}* | {r['scipy_pool_jitted_s']:.3g}* | "
                     f"{r['speedup_vs_serial_numpy']:.0f}× | "
                     f"{r['speedup_vs_pool_jitted']:.0f}× |")
    lines.append("")
    lines.append("\\* extrapolated: scipy from the measured subset (seconds per sample × samples);"
                 " jaxdobby on 1 device from its largest timed size (samples per second).")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="smoke size (tests)")
    p.add_argument("--sizes", type=int, nargs="+", default=None)
    p.add_argument("--chunk", type=int, default=None, help="samples per compiled chunk")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--modes", type=int, default=None, help="arm modes (default 4; quick 1)")
    p.add_argument("--scipy-samples", type=int, default=None, help="samples timed with scipy")
    p.add_argument("--scipy-method", default="RK45")
    p.add_argument("--scipy-rtol", type=float, default=None, help="default 1e-6 (quick 1e-4)")
    p.add_argument("--max-single", type=int, default=4096,
                   help="largest size timed on 1 device (larger: extrapolated from it)")
    p.add_argument("--out", type=Path, default=common.RESULTS)
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--two", choices=("processes", "devices"), default="devices",
                   help="2 cores as 2 host devices in one process (shard_map; default) or as 2 "
                        "one-device processes")
    p.add_argument("--keep", type=int, default=2, help=argparse.SUPPRESS)
    p.add_argument("--part", type=int, default=0, help=argparse.SUPPRESS)
    p.add_argument("--parts", type=int, default=1, help=argparse.SUPPRESS)
    ns = p.parse_args(argv)
    ns.sizes = ns.sizes or ([16, 32] if ns.quick else [256, 4096, 65536])
    ns.chunk = ns.chunk or (16 if ns.quick else 256)
    ns.modes = ns.modes or (1 if ns.quick else 4)
    ns.scipy_samples = ns.scipy_samples or 2
    ns.scipy_rtol = ns.scipy_rtol or (1e-4 if ns.quick else 1e-6)
    if ns.worker:
        print(json.dumps(jax_worker(ns.sizes, ns.chunk, ns.repeats, ns.modes, ns.keep,
                                    ns.part, ns.parts),
                         default=common._default))
        return 0
    common.configure_jax()
    import numpy as np

    from benchmarks.scipy_model import metric_error

    record = {"benchmark": "batch", "quick": ns.quick, "n_modes": ns.modes, "chunk": ns.chunk,
                  "box": dict(zip(NAMES, [["400", "1200", "r/min"], ["345", "1035", "N"],
                                       ["80", "140", "mm"], ["6", "8", "mm"]])),
                  "environment": common.environment()}
    single = [n for n in ns.sizes if n <= ns.max_single] or ns.sizes[:1]
    record["two_cores"] = ns.two
    started = None
    if ns.quick and ns.two == "devices":
        # a smoke run: its timings are not results, so both jaxdobby processes run beside the
        # scipy runs (under a minute instead of ~70 s, issue 19)
        started = [start_jax_subprocess(1, ns, single), start_jax_subprocess(2, ns, ns.sizes)]
    else:
        record["jaxdobby"] = {"1": jax_in_subprocess(1, ns, single)}
        record["jaxdobby"]["2"] = (jax_in_subprocess(2, ns, ns.sizes) if ns.two == "devices"
                                   else jax_in_processes(2, ns, ns.sizes))
    rows = samples(ns.scipy_samples)
    options = {"modes": ns.modes, "method": ns.scipy_method, "rtol": ns.scipy_rtol, "tolerance": 1e-6}
    n_serial = max(1, ns.scipy_samples // 2)
    record["scipy_serial_numpy"] = scipy_serial(rows[:n_serial], dict(options, rhs="numpy"))
    record["scipy_pool_numpy"] = scipy_pool(rows, dict(options, rhs="numpy"))
    record["scipy_pool_jitted"] = scipy_pool(rows, dict(options, rhs="jitted"))
    if started is not None:
        record["jaxdobby"] = {"1": _finish(started[0]), "2": _finish(started[1])}

    ref_rtol = 1e-8 if ns.quick else 1e-10
    common.log(f"reference on {len(rows)} samples (DOP853 rtol {ref_rtol:g})...")
    refs = reference_metrics(rows, ns.modes, ref_rtol)
    batch = record["jaxdobby"]["1"]["first_metrics"]
    batch_err = [metric_error({k: batch[k][i] for k in batch}, refs[i]) for i in range(len(rows))]
    scipy_err = [metric_error(r["metrics"], refs[i])
                 for i, r in enumerate(record["scipy_pool_jitted"]["runs"])]
    record["accuracy"] = {"reference": f"DOP853 rtol {ref_rtol:g} (jitted RHS)",
                              "samples": len(rows), "jaxdobby_batch_max_error": max(batch_err),
                              "scipy_max_error": max(scipy_err), "jaxdobby_batch_errors": batch_err,
                              "scipy_errors": scipy_err}
    table = []
    for n in ns.sizes:
        measured = record["jaxdobby"]["1"]["sizes"]
        one = next((s for s in measured if s["samples"] == n), None)
        one_s = one["median_s"] if one else n / measured[-1]["samples_per_s"]
        two = next(s for s in record["jaxdobby"]["2"]["sizes"] if s["samples"] == n)
        best = min(one_s, two["median_s"])
        serial = n * record["scipy_serial_numpy"]["per_sample_s"]
        pool_np = n * record["scipy_pool_numpy"]["per_sample_s"]
        pool_jit = n * record["scipy_pool_jitted"]["per_sample_s"]
        table.append({"samples": n, "jaxdobby_1_device_s": one_s,
                      "jaxdobby_1_device_extrapolated": one is None,
                          "jaxdobby_2_devices_s": two["median_s"], "scipy_serial_numpy_s": serial,
                          "scipy_pool_numpy_s": pool_np, "scipy_pool_jitted_s": pool_jit,
                          "speedup_vs_serial_numpy": serial / best,
                          "speedup_vs_pool_numpy": pool_np / best,
                          "speedup_vs_pool_jitted": pool_jit / best,
                          "ok_fraction": min(one["ok_fraction"] if one else 1.0,
                                         two["ok_fraction"])})
    record["rows"] = table
    record["markdown"] = markdown(table) + (
        f"\n\nAccuracy on {len(rows)} samples against {record['accuracy']['reference']}: "
        f"jaxdobby batch {max(batch_err):.1e}, scipy {ns.scipy_method} rtol "
        f"{ns.scipy_rtol:g} {max(scipy_err):.1e} (max relative metric error).")
    ok = all(np.isfinite(e) for e in batch_err + scipy_err)
    record["sane"] = bool(ok)
    name = "batch_quick.json" if ns.quick else "batch.json"
    common.write_json(ns.out / name, common.finish(record))
    print(record["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
