"""Where one chunk of the dobby's batch evaluation spends its time (issue 4).

Times, jitted over ``jax.vmap`` of one chunk of rows of the default Sobol design (one CPU
device, compile time apart, best of ``--repeats``), per sample, each part including the ones
before it, as :func:`jaxdobby.periodic.steady_state_metrics` runs them:

* ``model terms``: the model of each sample (finite elements, modal reduction, Kane's terms),
  one sample at a time (:func:`jaxdobby.periodic.steady.model_terms`);
* ``+ tables``: the rigid motion's tables of every lane, lanes last
  (:func:`~jaxdobby.periodic.steady.batch_tables`);
* ``+ linearise``: the frozen Newton matrices, monodromy matrix, linear periodic response and
  chord matrix of every lane (:func:`~jaxdobby.periodic.steady.batch_linearise`);
* ``+ one cycle``: one cycle of every lane with the extremes (as the batch's full cycles);
* ``steady_state_metrics``: everything, for each number of lanes per round of the chord
  iteration in ``--widths`` (:data:`jaxdobby.periodic.steady.ROUND_WIDTH`).

It also reports how many cycles the lanes needed: a vmapped while loop would integrate
(chunk × the slowest lane's cycles), the rounds about the sum of the lanes' own.

Run (alone on the machine; ``taskset -c 0`` pins it to one core):
    python benchmarks/batch_profile.py [--chunk 64] [--quick]
Writes ``benchmarks/results/batch_profile.json`` and ``.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run as `python benchmarks/batch_profile.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import (
    RESULTS,
    configure_jax,
    environment,
    finish,
    timed,
    write_json,
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chunk", type=int, default=64,
                    help="rows per chunk (default 64: what one device runs of a plain "
                         "jaxdobby sobol's chunk, jaxdobby.sensitivity.batch.DEVICE_CHUNK)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--widths", type=int, nargs="+", default=[8, 16, 32])
    ap.add_argument("--quick", action="store_true", help="smoke size (8 rows, 72 steps)")
    ap.add_argument("--out", default=str(RESULTS))
    args = ap.parse_args(argv)
    steps = 72 if args.quick else None
    if args.quick:
        args.chunk, args.repeats, args.widths = 8, 1, [2]

    jax = configure_jax()
    import jax.numpy as jnp

    from jaxdobby.periodic import steady
    from jaxdobby.parameters import Setup
    from jaxdobby.sensitivity import DOBBY, ParameterSpace
    from jaxdobby.sensitivity.batch import compile_for
    from jaxdobby.sensitivity.dobby import setup_of_row

    space = ParameterSpace.from_names(DOBBY.default_names, DOBBY.parameters)
    rows = jnp.asarray(space.sample(1024, second_order=True, seed=0)[: args.chunk])
    start = Setup()
    kw = {} if steps is None else {"steps": steps}

    def setup_of(x):
        return setup_of_row(start, space.names, space.si_scales, x)[0]

    # the stages of steady_state_metrics's batch rule (steady._solve), each program including
    # the ones before it
    def batch_terms(xs):
        terms, _ = jax.vmap(lambda x: steady.model_terms(setup_of(x)))(xs)
        return steady.batch_terms(terms, jax.tree.map(lambda _: True, terms), xs.shape[0])

    def batch_tables(xs):
        terms = batch_terms(xs)
        return terms, steady.batch_tables(terms, steady.rigid_motion(start, **kw))

    def batch_linearise(xs):
        terms, tables = batch_tables(xs)
        return tables, steady.batch_linearise(terms, tables)

    def batch_cycle(xs):
        tables, (rest, lin, chord_matrix, x) = batch_linearise(xs)
        # the cost of a cycle does not depend on where it starts
        return steady._chord_pass(rest, lin.solvers, chord_matrix, steady._start(x),
                                  tables=tables)

    def batch_metrics(xs):
        return jax.vmap(lambda x: steady.steady_state_metrics(setup_of(x), **kw))(xs)

    def per_sample(fn):
        # compiled as jaxdobby.sensitivity.evaluate compiles a chunk (its CPU options)
        g = compile_for(jax.jit(fn).lower(rows), jax.devices()[:1])
        jax.block_until_ready(g(rows))
        t = timed(lambda: jax.block_until_ready(g(rows)), repeats=args.repeats)
        return t["min_s"] / args.chunk * 1e3, t["value"]

    parts = {}
    for name, fn in [("model terms", batch_terms), ("+ tables", batch_tables),
                     ("+ linearise", batch_linearise), ("+ one cycle", batch_cycle)]:
        parts[name], _ = per_sample(fn)
        print(f"{name}: {parts[name]:.3f} ms per sample", flush=True)
    full, cycles = {}, None
    default = steady.ROUND_WIDTH
    try:
        for width in args.widths:
            steady.ROUND_WIDTH = width
            full[width], out = per_sample(batch_metrics)
            cycles = np.asarray(out["cycles"])
            print(f"steady_state_metrics, {width} lanes per round: {full[width]:.3f} ms per "
                  "sample", flush=True)
    finally:
        steady.ROUND_WIDTH = default
    result = {"benchmark": "batch_profile", "quick": args.quick, "environment": environment(),
              "chunk": args.chunk, "per_sample_ms": parts,
              "steady_state_metrics_ms": {str(k): v for k, v in full.items()},
              "cycles_histogram": np.bincount(cycles).tolist(),
              "cycles_needed": int(cycles.sum()),
              "cycles_vmapped_while": int(args.chunk * cycles.max())}
    lines = [f"One chunk of {args.chunk} rows of the default design, one device, per sample:", "",
             "| part | ms per sample |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in parts.items()]
    lines += [f"| steady_state_metrics, {k} lanes per round | {v:.2f} |"
              for k, v in full.items()]
    lines += ["", "Cycles per sample: "
              + ", ".join(f"{c}: {n}" for c, n in enumerate(result["cycles_histogram"]) if n)
              + f". Cycles the lanes need: {result['cycles_needed']}; a vmapped "
              f"while loop would integrate {result['cycles_vmapped_while']}."]
    result["markdown"] = "\n".join(lines) + "\n"
    name = "batch_profile_quick" if args.quick else "batch_profile"
    write_json(Path(args.out) / f"{name}.json", finish(result))
    (Path(args.out) / f"{name}.md").write_text(result["markdown"])
    print(result["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
