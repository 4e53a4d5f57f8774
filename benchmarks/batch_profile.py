"""Where one chunk of the dobby's batch evaluation spends its time (issue 4).

Times, jitted over ``jax.vmap`` of one chunk of rows of the default Sobol design (one CPU
device, compile time apart, best of ``--repeats``), per sample:

* ``prepare``: the model of each sample (finite elements, modal reduction, tables, static
  equilibrium; :func:`jaxdobby.batch.steady.prepare`);
* ``prepare + tangent pass``: with the first cycle and its 2k tangents (the chord matrix);
* ``prepare + chord pass``: with one cycle recording the extremes;
* ``steady_state_metrics``: everything, for each number of lanes per round of the chord
  iteration in ``--widths`` (:data:`jaxdobby.batch.steady.ROUND_WIDTH`).

It also reports how many cycles the lanes needed: a vmapped while loop would integrate
(chunk × the slowest lane's chord cycles), the rounds about the sum of the lanes' own.

Run (alone on the machine; ``taskset -c 0`` pins it to one core):
    PYTHONPATH=. python benchmarks/batch_profile.py [--chunk 256] [--quick]
Writes ``benchmarks/results/batch_profile.json`` and ``.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

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
    ap.add_argument("--chunk", type=int, default=256, help="rows per chunk")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--widths", type=int, nargs="+", default=[32, 64, 128])
    ap.add_argument("--quick", action="store_true", help="smoke size (8 rows, 72 steps)")
    ap.add_argument("--out", default=str(RESULTS))
    args = ap.parse_args(argv)
    steps = 72 if args.quick else None
    if args.quick:
        args.chunk, args.repeats, args.widths = 8, 1, [2]

    jax = configure_jax()
    import equinox as eqx
    import jax.numpy as jnp

    from jaxdobby.batch import steady
    from jaxdobby.batch.stepper import cycle_pass
    from jaxdobby.parameters import Setup, apply
    from jaxdobby.sensitivity import DOBBY, ParameterSpace
    from jaxdobby.stroke import arc_length_for_stroke

    space = ParameterSpace.from_names(DOBBY.default_names, DOBBY.parameters)
    rows = jnp.asarray(space.sample(1024, second_order=True, seed=0)[: args.chunk])
    start = Setup()

    def setup_of(x):  # as jaxdobby.sensitivity.dobby's model (strokes in range here)
        values = {n: x[i] * f for i, (n, f) in enumerate(zip(space.names, space.si_scales))}
        target = values.pop("stroke")
        setup = apply(start, values)
        s = arc_length_for_stroke(setup.machine.chain, target, check=False)
        return eqx.tree_at(lambda u: u.machine, setup, setup.machine.with_link11_arc_length(s))

    kw = {} if steps is None else {"steps": steps}

    def prepare(x):
        return steady.prepare(setup_of(x), **kw)

    def tangent(x):
        c = prepare(x)
        k = c.arm.mass.shape[0]
        run = cycle_pass(c.arm, c.downstream, c.tables, c.period, c.rest,
                         tangents=jnp.eye(2 * k), full_jacobian=True)
        return run.end, run.tangents

    def chord(x):
        c = prepare(x)
        run = cycle_pass(c.arm, c.downstream, c.tables, c.period, c.rest, outputs=True)
        return run.end, run.maxima

    def metrics(x):
        return steady.steady_state_metrics(setup_of(x), **kw)

    def per_sample(fn):
        g = jax.jit(jax.vmap(fn))
        jax.block_until_ready(g(rows))
        t = timed(lambda: jax.block_until_ready(g(rows)), repeats=args.repeats)
        return t["min_s"] / args.chunk * 1e3, t["value"]

    parts = {}
    for name, fn in [("prepare", prepare), ("prepare + tangent pass", tangent),
                     ("prepare + chord pass", chord)]:
        parts[name], _ = per_sample(fn)
        print(f"{name}: {parts[name]:.3f} ms per sample", flush=True)
    full, cycles = {}, None
    default = steady.ROUND_WIDTH
    try:
        for width in args.widths:
            steady.ROUND_WIDTH = width
            full[width], out = per_sample(metrics)
            cycles = np.asarray(out["cycles"])
            print(f"steady_state_metrics, {width} lanes per round: {full[width]:.3f} ms per "
                  "sample", flush=True)
    finally:
        steady.ROUND_WIDTH = default
    chords = cycles - 1
    result = {"benchmark": "batch_profile", "quick": args.quick, "environment": environment(),
              "chunk": args.chunk, "per_sample_ms": parts,
              "steady_state_metrics_ms": {str(k): v for k, v in full.items()},
              "cycles_histogram": np.bincount(cycles).tolist(),
              "chord_cycles_needed": int(chords.sum()),
              "chord_cycles_vmapped_while": int(args.chunk * chords.max())}
    lines = [f"One chunk of {args.chunk} rows of the default design, one device, per sample:", "",
             "| part | ms per sample |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in parts.items()]
    lines += [f"| steady_state_metrics, {k} lanes per round | {v:.2f} |"
              for k, v in full.items()]
    lines += ["", "Cycles per sample (tangent cycle included): "
              + ", ".join(f"{c}: {n}" for c, n in enumerate(result["cycles_histogram"]) if n)
              + f". Chord cycles the lanes need: {result['chord_cycles_needed']}; a vmapped "
              f"while loop would integrate {result['chord_cycles_vmapped_while']}."]
    result["markdown"] = "\n".join(lines) + "\n"
    name = "batch_profile_quick" if args.quick else "batch_profile"
    write_json(Path(args.out) / f"{name}.json", finish(result))
    (Path(args.out) / f"{name}.md").write_text(result["markdown"])
    print(result["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
