"""Test configuration: float64 on, as every jaxdobby user is told to do (see README)."""

import jax

jax.config.update("jax_enable_x64", True)

import os
from pathlib import Path

# Share compiled executables between the in-process command-line tests and the ones that start
# `jaxdobby` in a subprocess (and between test runs on the same checkout).
os.environ.setdefault("JAXDOBBY_CACHE_DIR",
                      str(Path(__file__).resolve().parent.parent / ".pytest_cache" / "xla"))

# The suite's programs are compiled once and run briefly: LLVM's optimisation level 0 compiles
# them faster (CPU seconds of tests/test_sweep.py + test_dobby.py: 176 → 151, the default
# program's compile alone 21 → 13.5) for slower code that no test times. Same results to
# round-off.
if "xla_backend_optimization_level" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_backend_optimization_level=0").strip()

from jaxdobby.command_line import _configure_jax  # noqa: E402

_configure_jax()  # before anything compiles: the persistent cache is set up at first use
