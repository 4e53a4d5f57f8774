"""One cold run of ``jaxdobby.simulate`` in this (fresh) process; prints its timings as JSON.

Run as ``python -m benchmarks._cold [--cache DIR] [--modes K]`` by :mod:`benchmarks.bench_simulate`:
import, first call (tracing + compilation + run) and a second call, each timed with
``block_until_ready``. With ``--cache`` the persistent compilation cache of the command line is
switched on at DIR (a second process then loads the compiled program instead of compiling it).
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def main(argv=None) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--cache", default=None, help="persistent compilation cache directory")
    p.add_argument("--modes", type=int, default=4, help="elastic modes of the arm")
    ns = p.parse_args(argv)
    t0 = time.perf_counter()
    import jax

    jax.config.update("jax_enable_x64", True)
    if ns.cache:
        jax.config.update("jax_compilation_cache_dir", ns.cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    from jaxdobby import Machine, simulate

    machine = Machine.default(n_modes=ns.modes)
    t1 = time.perf_counter()
    run = jax.block_until_ready(simulate(machine))
    t2 = time.perf_counter()
    jax.block_until_ready(simulate(machine))
    t3 = time.perf_counter()
    print(json.dumps({"import_s": t1 - t0, "first_call_s": t2 - t1, "second_call_s": t3 - t2,
                          "converged": bool(run.converged),
                          "deviation_pp": float(run.metrics["deviation_pp"])}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
