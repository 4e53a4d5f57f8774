"""Test configuration: float64 on, as every jaxdobby user is told to do (see README)."""

import jax
import pytest

jax.config.update("jax_enable_x64", True)

import os
from pathlib import Path

# The command line's one-shot XLA options (jaxdobby.programs.ONE_SHOT: LLVM's optimisation
# level 0) for every program the tests compile, here and in the command-line subprocesses and
# the notebooks' kernels, which inherit the environment: most test programs run once, so compile
# time is what the suite waits for (the default suite 8.4 -> 5.9 min on 2 cores, empty cache).
# It changes how fast the machine code is, not its arithmetic (no fast-math at any level):
# results are the default level's to round-off, as tests/test_programs.py checks for ONE_SHOT.
# JAXDOBBY_TEST_XLA_FLAGS holds these flags for tests that build a subprocess's XLA_FLAGS.
# Set JAXDOBBY_TEST_XLA_OPT=default to test at XLA's default level.
from jaxdobby.programs import ONE_SHOT  # noqa: E402

if os.environ.get("JAXDOBBY_TEST_XLA_OPT") != "default":
    _flags = " ".join(f"--{k}={v}" for k, v in ONE_SHOT.items())
    os.environ["JAXDOBBY_TEST_XLA_FLAGS"] = _flags
    if _flags not in os.environ.get("XLA_FLAGS", ""):  # pytest-xdist's workers inherit it
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {_flags}".strip()

# Share compiled executables between the in-process command-line tests and the ones that start
# `jaxdobby` in a subprocess (and between test runs on the same checkout).
os.environ.setdefault("JAXDOBBY_CACHE_DIR",
                      str(Path(__file__).resolve().parent.parent / ".pytest_cache" / "xla"))

# Every compiled program goes into that cache, the small ones too (the command line keeps only
# those of at least 0.5 s): the two pytest-xdist workers and the subprocesses then compile each
# of the thousands of small eager operations once rather than once per process (measured: the
# default suite 5.9 -> 5.7 min, benchmarks/suite_time.py). The command line reads the variable
# (jaxdobby.command_line._configure_jax); JAX reads it at import in the notebooks' kernels.
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")

from jaxdobby.command_line import _configure_jax  # noqa: E402

_configure_jax()  # before anything compiles: the persistent cache is set up at first use

# The notebooks' kernels (tests/test_notebooks.py) read the same cache with the same settings
# (JAX reads these at import), so a program a test compiled is not compiled again there.
if os.environ["JAXDOBBY_CACHE_DIR"].lower() != "off":
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", os.environ["JAXDOBBY_CACHE_DIR"])
    os.environ.setdefault("JAX_TRACEBACK_IN_LOCATIONS_LIMIT", "0")


# Test files that compile the same programs run in one pytest-xdist worker (``--dist loadgroup``
# in pyproject.toml): the first compiles, the others read the persistent cache. Every other file
# is its own group (as ``--dist loadfile``), so module fixtures are computed once.
SHARED_PROGRAMS = {
    # the command line's report program of the default configuration (jit(call), ~10 s), and
    # simulate()'s default program with the stress recovery (~10 s): test_dobby, test_pictures,
    # test_dense_output and test_stress_arm call simulate() on the default machine (one
    # in-memory program for all of them; test_programs and notebook 02 then read its compiled
    # executable from the cache), test_sweep runs the report program for its single runs
    # (measured alone: 32.5 s, after test_cli's default run 20.9 s), test_sensitivity_dobby
    # for the rows it re-runs through the report program
    "test_cli.py": "report", "test_programs.py": "report", "test_validity.py": "report",
    "test_robustness.py": "report", "test_notebooks.py": "report", "test_sweep.py": "report",
    "test_dobby.py": "report", "test_pictures.py": "report", "test_dense_output.py": "report",
    "test_stress_arm.py": "report", "test_sensitivity_dobby.py": "report",
}


# The longest groups first (worker seconds in the default suite, measured 2026-12-04: report
# ~205, batch ~56, kane_limits ~36, identify ~30, ritz ~28, benchmarks ~22, ...; the ~15 other
# files, ~50 s together, follow in file order), so that the two workers finish together rather
# than one starting a long file when the other is done (longest-processing-time-first).
# pytest-xdist keeps this order only with --no-loadscope-reorder (pyproject.toml): by default it
# orders the groups by their number of tests.
LONGEST_FIRST = ("report", "test_batch.py", "test_kane_limits.py", "test_identify.py",
                 "test_ritz.py", "test_benchmarks.py", "test_sensitivity_parallel.py",
                 "test_optimize.py", "test_reference_dobby.py", "test_reference_spinup.py",
                 "test_kinematics.py", "test_stress_recovery.py")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    def group(item):
        return SHARED_PROGRAMS.get(item.path.name, item.path.name)

    for item in items:
        item.add_marker(pytest.mark.xdist_group(group(item)))
    rank = {g: i for i, g in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(group(item), len(rank)))  # stable: file order kept
