"""Compiling the few test programs whose running, not their compiling, is what a test waits for.

The suite compiles at LLVM's optimisation level 0 (``tests/conftest.py``): most test programs
run once and briefly, so compile time dominates. A long adaptive solve at rtol 1e-10 is the
opposite, and so is a right-hand side that scipy calls 1e5 times: :func:`jit_to_run` compiles
such a program (traced whole where it can be, set-up included: one program instead of many
eager operations) at XLA's default level. The arithmetic is the same at either level (no
fast-math), so the claims and tolerances do not depend on it.
"""

import jax

RUN_LONG = {"xla_backend_optimization_level": 3}
"""XLA's default LLVM optimisation level (``DebugOptions``), for programs that run long."""


def jit_to_run(fn):
    """``jax.jit(fn)`` compiled at :data:`RUN_LONG` (XLA's default level)."""
    return jax.jit(fn, compiler_options=RUN_LONG)
