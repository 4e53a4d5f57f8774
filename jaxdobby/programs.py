"""Traced programs kept on disk, so that a later run skips tracing (``jax.export``).

Tracing and lowering the steady-state program of :func:`jaxdobby.simulate.simulate` takes
seconds of Python work before XLA compiles anything, and with XLA's persistent compilation cache
filled it is most of what a repeated ``jaxdobby simulate`` waits for. :func:`stored_program` gives
a function of flat arrays as its *exported* program (StableHLO, serialised with
``jax.export``): the first call traces and exports it and writes it to a directory; a later call
(any process) reads it back, and only a thin wrapper around it is lowered
(:func:`compile_together`) — and XLA's persistent cache then also holds the compiled
executable.

A stored program is found by a key of everything it depends on: the program's name and static
configuration (sizes, laws, method: ``static_key``), the shapes and dtypes of its arguments, the
JAX and jaxlib versions, the platform, and a fingerprint of jaxdobby's own source files. Any
change of the code therefore makes a new key — a stale program is never used, only not found.

Programs of the default configuration ship in the package (``jaxdobby/data/programs``, made by
``python -m jaxdobby.programs``): ``jaxdobby simulate``'s two (the run and its report,
compiled side by side: :func:`compile_together`) and the per-device program of
the default ``jaxdobby sobol`` study on a 2-core CPU (:mod:`jaxdobby.sensitivity.batch`), so
that even the first run with an empty cache skips tracing when the installed JAX is the one
they were made with; ``tests/test_programs.py`` checks that they are current.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp

PACKAGE = Path(__file__).resolve().parent
SHIPPED = PACKAGE / "data" / "programs"
"""Programs of the default configuration, shipped with the package."""


@cache
def source_fingerprint() -> str:
    """SHA-256 of jaxdobby's Python sources (paths and contents, in path order), with the JAX
    and jaxlib versions: what a stored program was made from."""
    import jaxlib

    digest = hashlib.sha256(f"jax {jax.__version__} jaxlib {jaxlib.__version__}".encode())
    for path in sorted(PACKAGE.rglob("*.py")):
        digest.update(str(path.relative_to(PACKAGE)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _spec(a) -> jax.ShapeDtypeStruct:
    """The shape and dtype of an array (or of a ``jax.ShapeDtypeStruct``, as it is)."""
    if isinstance(a, jax.ShapeDtypeStruct):
        return jax.ShapeDtypeStruct(a.shape, a.dtype)
    return jax.ShapeDtypeStruct(jnp.shape(a), jnp.result_type(a))


def program_key(name: str, static_key: str, args: Sequence) -> str:
    """The file name of a stored program (see the module docstring)."""
    shapes = ";".join(f"{s.dtype}{list(s.shape)}" for s in map(_spec, args))
    text = "\n".join([name, static_key, shapes, jax.default_backend(), source_fingerprint()])
    return f"{name}-{hashlib.sha256(text.encode()).hexdigest()[:24]}.jaxexport"


def _read(path: Path):
    try:
        return jax.export.deserialize(bytearray(path.read_bytes()))
    except (OSError, ValueError, ImportError):  # unreadable or from another JAX: trace anew
        return None


def export_program(fn: Callable, args: Sequence):
    """``jax.export`` of ``jax.jit(fn)`` for arguments shaped as ``args``, without Python
    tracebacks in its locations: the program is then the same whoever exports it (the command
    line, a test, ``python -m jaxdobby.programs``), so XLA's persistent cache, whose key is the
    program's text, compiles it once for all of them."""
    import contextlib

    try:  # the context-manager form of the jax_traceback_in_locations_limit option
        from jax._src.config import traceback_in_locations_limit
        no_tracebacks = traceback_in_locations_limit(0)
    except (ImportError, TypeError):  # another JAX: the program keeps its locations
        no_tracebacks = contextlib.nullcontext()
    with no_tracebacks:
        return jax.export.export(jax.jit(fn))(*map(_spec, args))


def write_program(exported, path: Path) -> None:
    """Write a serialised program atomically (a temporary file renamed into place)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".jaxexport")
    with os.fdopen(fd, "wb") as f:
        f.write(exported.serialize())
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)


ONE_SHOT = {"xla_backend_optimization_level": 0}
"""XLA options of a program run once per process (``jaxdobby simulate``'s): LLVM's optimisation
level 0. On the default configuration's program (2 cores, quiet machine) it compiles in
7.7–8.6 s instead of 11.4 s (CPU seconds 8.4–9.4 instead of 15.1) and runs in 0.11 s instead of
0.07 s: a good trade for a program that runs once. Results are the same to round-off
(``tests/test_programs.py``)."""


class Unstored(NamedTuple):
    """A program that cannot be exported (it calls back into Python: ``jax.export`` does not
    serialise host callbacks, which diffrax's adaptive solver uses): traced in every run and
    never stored, with the two attributes of an exported program this module uses."""

    call: Callable
    out_avals: tuple


def compile_together(programs: Sequence[tuple], compiler_options: dict | None = None) -> list:
    """Compile several exported programs at once: ``programs`` a sequence of (exported,
    argument specs); returns their compiled callables, in order.

    Each is lowered here (Python work, one after the other), then XLA compiles them in as many
    threads: XLA's CPU compilation of one program runs on one core at a time, so two programs
    compile in about the time of the longer (measured on 2 cores, 2026-12-04: simulate's steady
    state and the batch evaluator's programs, 7.4 s one after the other, 4.5 s together).
    ``compiler_options``: XLA options of every compilation (e.g. :data:`ONE_SHOT`); None:
    JAX's.
    """
    from concurrent.futures import ThreadPoolExecutor

    lowered = [jax.jit(exported.call).lower(*map(_spec, specs)) for exported, specs in programs]
    options = compiler_options or None
    if len(lowered) == 1:
        return [lowered[0].compile(compiler_options=options)]
    with ThreadPoolExecutor(len(lowered)) as pool:
        return list(pool.map(lambda low: low.compile(compiler_options=options), lowered))


def stored_program(name: str, fn: Callable, args: Sequence, *, static_key: str,
                   directory: Path | None):
    """The exported program of ``fn`` for arguments shaped as ``args``: read from ``directory``
    or the shipped programs, or traced, exported and written to ``directory`` (see the module
    docstring); :class:`Unstored` if it cannot be exported. Call it with ``exported.call``
    (inside ``jax.jit``, ``jax.shard_map`` ...) or compile it with :func:`compile_together`.

    Args:
        name: the program's name (a file-name prefix).
        fn: a function of the arrays ``args`` alone (everything static closed over and
            described by ``static_key``), returning a pytree of standard containers (dicts,
            lists, tuples) of arrays.
        args: the arrays, or their ``jax.ShapeDtypeStruct``.
        static_key: a text that differs whenever what ``fn`` closes over differs.
        directory: where programs are stored and looked for (besides the shipped ones);
            None: do not store.
    """
    key = program_key(name, static_key, args)
    places = ([directory / key] if directory is not None else []) + [SHIPPED / key]
    for path in places:
        if path.exists() and (exported := _read(path)) is not None:
            return exported
    try:
        exported = export_program(fn, args)
    except NotImplementedError:  # host callbacks (diffrax's adaptive solver) do not serialise
        return Unstored(fn, tuple(jax.tree.leaves(jax.eval_shape(fn, *map(_spec, args)))))
    if directory is not None:
        try:
            write_program(exported, directory / key)
        except OSError:  # a read-only cache only costs the next run the tracing
            pass
    return exported


def main() -> None:
    """Make the shipped programs of the default configuration (``python -m jaxdobby.programs``)."""
    from .command_line import _configure_jax

    _configure_jax()
    from .config import RunOptions
    from .parameters import Setup
    from .simulate import stored_report

    for path in SHIPPED.glob("*.jaxexport"):
        path.unlink()
    stored_report(Setup(), RunOptions(), directory=SHIPPED)
    from .sensitivity.command import default_study_program

    fn, stored, share = default_study_program()
    stored_program(stored.name, fn, [share], static_key=stored.static_key, directory=SHIPPED)
    for path in sorted(SHIPPED.glob("*.jaxexport")):
        print(f"wrote {path.relative_to(PACKAGE.parent)} ({path.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
