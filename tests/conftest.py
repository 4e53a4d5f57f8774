"""Test configuration: float64 on, as every jaxdobby user is told to do (see README)."""

import jax

jax.config.update("jax_enable_x64", True)

import os
from pathlib import Path

# Share compiled executables between the in-process command-line tests and the ones that start
# `jaxdobby` in a subprocess (and between test runs on the same checkout).
os.environ.setdefault("JAXDOBBY_CACHE_DIR",
                      str(Path(__file__).resolve().parent.parent / ".pytest_cache" / "xla"))

from jaxdobby.command_line import _configure_jax  # noqa: E402

_configure_jax()  # before anything compiles: the persistent cache is set up at first use
