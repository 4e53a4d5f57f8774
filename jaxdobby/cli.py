"""The ``jaxdobby`` command line.

Commands (``jaxdobby COMMAND --help`` for each):

* ``simulate`` — one run of the mechanism at an operating point (the default machine with no
  arguments): summary table, ``--json``, ``--out DIR`` for CSV/JSON/figures;
* ``sweep`` — the source study's one-at-a-time parameter studies;
* ``sobol`` — Sobol sensitivity indices from batched, sharded runs;
* ``optimize`` — gradient-based design of the bending arm;
* ``beam`` — the natural frequencies and mode shapes of the default bending arm.

The command line speaks the users' units (mm, r/min, N) and converts to SI at this boundary.
It is the only place that switches JAX to float64 and the only place that prints. Bad input
ends with one line naming the field and its valid range, and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .errors import InputError

EXIT_BAD_INPUT = 2


def _enable_x64() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)


def _beam(ns: argparse.Namespace) -> int:
    from .report import beam_report

    print(beam_report(n_modes=ns.modes))
    return 0


def _sobol(argv: Sequence[str]) -> int:
    from .sensitivity.command import main as sobol_main

    return sobol_main(argv)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxdobby",
        description="Differentiable simulator of the rigid-flexible lifting mechanism of a "
                    "rotary dobby.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    beam = sub.add_parser("beam", help="natural frequencies of the default bending arm")
    beam.add_argument("--modes", type=int, default=8, help="number of modes to list (1-30)")
    beam.set_defaults(run=_beam)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxdobby`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    _enable_x64()
    if argv and argv[0] == "sobol":
        return _sobol(argv[1:])
    parser = build_parser()
    ns = parser.parse_args(argv)
    try:
        return ns.run(ns)
    except InputError as err:
        print(f"jaxdobby {ns.command}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
