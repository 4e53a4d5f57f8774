"""What every ``jaxdobby`` subcommand shares: JAX's set-up for the command line (float64, XLA
flags, the persistent caches), the model flags and how they become a
:class:`~jaxdobby.parameters.Setup`, exit codes and status lines.

:mod:`jaxdobby.cli` builds the parser and dispatches; the subcommands' own modules
(``optimize.command``, ``pictures.command``, ``identify.command``…) import from here, never from
:mod:`jaxdobby.cli`, so dependencies run one way.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path

from .errors import InputError

EXIT_BAD_INPUT = 2
EXIT_SOLVER_FAILURE = 1


CPU_XLA_FLAGS = "--xla_cpu_use_fusion_emitters=false"
"""XLA flags of the command line's programs on the CPU: fusions compiled by XLA's loop emitters
rather than its newer MLIR fusion emitters, which compiled the dobby's programs about 1.5–2×
slower and ran them no faster (see ``jaxdobby.sensitivity.batch.CPU_COMPILER_OPTIONS``;
``benchmarks/compile_time.py``). Set only for jaxlib ≥ 0.7 (older ones abort on a flag they do
not know) and only when ``XLA_FLAGS`` does not set it already."""


def _configure_jax() -> None:
    """float64, XLA's CPU flags of :data:`CPU_XLA_FLAGS`, and a persistent compilation cache so
    that later runs (and other call sites of the same computation) skip most compiling
    (``JAXDOBBY_CACHE_DIR`` to move it, ``JAXDOBBY_CACHE_DIR=off`` to disable it). Must run
    before JAX's first computation (XLA reads its flags once)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" not in flags and _jaxlib_at_least(0, 7):
        os.environ["XLA_FLAGS"] = f"{flags} {CPU_XLA_FLAGS}".strip()
    import jax

    jax.config.update("jax_enable_x64", True)
    cache = _cache_dir()
    if cache is not None:
        jax.config.update("jax_compilation_cache_dir", str(cache))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", _min_compile_time())
        # no Python tracebacks in the programs' locations: the cache's key is the program's
        # text, so a program traced from another call site (a script, a test, a notebook)
        # would otherwise be compiled anew although it is the same computation
        jax.config.update("jax_traceback_in_locations_limit", 0)


def _min_compile_time() -> float:
    """Seconds a compilation must take to be kept in the persistent cache: JAX's own
    ``JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS`` if set (the test suite keeps every program,
    to share them between its processes), else 0.5 (the command line's programs, not the
    many tiny eager operations around them)."""
    value = os.environ.get("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "")
    try:
        return max(float(value), 0.0)
    except ValueError:
        return 0.5


def _cache_dir() -> Path | None:
    """XLA's persistent compilation cache of the command line (None: ``=off``); the traced
    programs of :mod:`jaxdobby.programs` are kept in its ``programs`` folder."""
    cache = os.environ.get("JAXDOBBY_CACHE_DIR", str(Path.home() / ".cache" / "jaxdobby" / "xla"))
    return None if cache.lower() == "off" else Path(cache)


def programs_dir() -> Path | None:
    """Where the command line stores its traced programs (:mod:`jaxdobby.programs`): the
    ``programs`` folder of :func:`_cache_dir`; None when the cache is off."""
    cache = _cache_dir()
    return None if cache is None else cache / "programs"


def _jaxlib_at_least(*version: int) -> bool:
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        parts = installed("jaxlib").split(".")[:len(version)]
        return tuple(int("".join(ch for ch in p if ch.isdigit()) or 0) for p in parts) >= version
    except PackageNotFoundError:
        return False


FLAG_PARAMETERS = {"speed": "speed", "warp_force": "warp_force", "stroke": "stroke",
                   "thickness": "thickness"}
"""Command-line flags that set a model parameter (flag dest → registry name)."""


def _add_model_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--speed", type=float, metavar="RPM", help="loom speed [r/min] (default 800)")
    p.add_argument("--warp-force", type=float, metavar="N",
                   help="peak warp force on the heald frame [N] (default 690)")
    p.add_argument("--stroke", type=float, metavar="MM",
                   help="heald-frame stroke [mm] (default 140; moves the link-11 joint)")
    p.add_argument("--thickness", type=float, metavar="MM",
                   help="plate thickness of the bending arm [mm] (default 6)")
    p.add_argument("--modes", type=int, metavar="K", help="modes of the arm kept, 1-30 (default 4)")
    p.add_argument("--elements", type=int, metavar="N",
                   help="elements of the arm's mesh, 4-200 (default 10, the study's 11 nodes)")
    p.add_argument("--coupling", choices=["two-way", "one-way"], help="default two-way")
    p.add_argument("--warp-law", choices=["restoring", "opposing"], help="default restoring")
    p.add_argument("--method", choices=["collocation", "rk4", "adaptive"],
                   help="integrator (default collocation; rk4 for --coupling one-way)")
    p.add_argument("--config", metavar="FILE.toml",
                   help="configuration file (any model parameter; see README)")


def setup_from_args(ns: argparse.Namespace):
    """The (Setup, RunOptions) described by the config file and flags (flags win)."""
    from .config import RunOptions, apply_checked, check_value, load
    from .parameters import PARAMETERS, Setup

    setup, options = load(ns.config) if ns.config else (Setup(), RunOptions())
    values = {}
    for dest, name in FLAG_PARAMETERS.items():
        v = getattr(ns, dest)
        if v is not None:
            p = PARAMETERS[name]
            values[name] = check_value(p, v, f"--{dest.replace('_', '-')}")[0] * p.scale
    setup = apply_checked(setup, values)
    changes = {}
    if ns.modes is not None:
        if not 1 <= ns.modes <= 30:
            raise InputError(f"--modes = {ns.modes} is outside the valid range (an integer 1…30)")
        changes["n_modes"] = ns.modes
    for key in ("coupling", "warp_law"):
        if getattr(ns, key) is not None:
            changes[key] = getattr(ns, key)
    if changes:
        setup = dataclasses.replace(setup, machine=setup.machine.replace(**changes))
    if getattr(ns, "elements", None) is not None:  # the optimiser's namespace has no --elements
        from .config import with_elements

        setup = with_elements(setup, ns.elements, "--elements")
    if ns.method is not None:
        options.method = ns.method
    return setup, options


def _status(text: str) -> None:
    print(text, file=sys.stderr, flush=True)
