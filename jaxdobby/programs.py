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
compiled side by side: :func:`compile_together`), the per-device program of
the default ``jaxdobby sobol`` study on a 2-core CPU (:mod:`jaxdobby.sensitivity.batch`) and a
plain ``jaxdobby optimize``'s three (its values, the batched scan of its starting designs and
the reverse-mode gradient: :class:`jaxdobby.optimize.objective.Evaluator`) and
``jaxdobby loom``'s frame batch of a weave of 4 picks on 8 frames (``--weave twill22``,
``twill31``, ``basket22``: :func:`jaxdobby.weave.loom.ship_programs`), so that even the first
run with an empty cache skips tracing when the installed JAX is the one they were made with;
``tests/test_programs.py`` checks that they are current. Programs that depend on what else the
user asks for (another weave's size, another design study) are kept in the cache folder
through :func:`stored_call`: traced once, compiled once per process.

**Shipped executables.** With the tracing skipped, the first run still waits for XLA to
compile (on 2 cores, ~5 s for ``jaxdobby simulate``'s two programs, ~10 s for the study's).
The same programs therefore also ship *compiled* (``*.xlaexe``:
``jax.experimental.serialize_executable``), for the machines most users have: Linux on an
x86-64 CPU with AVX2 (x86-64-v3: Intel since 2013, AMD since 2015). They are compiled with
XLA's instruction set capped at AVX2 (``--xla_cpu_max_isa``) and used only where
:func:`executables_usable` finds the CPU backend and such a CPU, and where the executable's
key (:func:`executable_key`: the exact JAX, jaxlib, program text, compile options and device
count) matches. XLA also records in each executable the features of the CPU it was compiled
on, and its loader warns ("could lead to SIGILL") on a CPU that lacks one. Features that XLA's
code never uses (protection keys, cache control, transactional memory...:
:data:`SYSTEM_FEATURES`) are marked off in the shipped files; an executable is loaded only on a
CPU with all of its remaining ones (:func:`host_features`: the vector and bit-manipulation
extensions, and family-specific ones such as AMD's ``sse4a``), and each program may ship in
several *variants*, one per family of CPU it was compiled on (``<key>.<features>.xlaexe``).
A variant is current only while its key is: whenever the programs change, every variant is
compiled again, on the machine at hand. Today's were compiled on an Intel Xeon with AVX-512
(family 6, model 167; 2026-12-07), whose AVX2 level also records ``avxvnni``, ``gfni`` and
``avx10.1``, so they load only on such CPUs; an AMD EPYC (whose variants record ``sse4a``)
compiles until a session on one adds its variants (``python -m jaxdobby.programs`` keeps the
variants of other CPUs while their key is current). The Sobol study's chunk also ships
compiled under :data:`WIDE_ISA` (AVX-512) where the shipping CPU has it, and a CPU that fits
several variants loads the one of the most features (:func:`_load_first_fitting`).
Elsewhere, or with ``JAXDOBBY_SHIPPED_EXECUTABLES=off``, the programs compile as before.
Python's :func:`jaxdobby.simulate.simulate` loads the run's executable too (its result's
structure ships beside it, ``*.structure``: rebuilding it would mean tracing the run).
Measured on 2 cores: a fresh ``jaxdobby simulate`` with an empty cache takes 1.9 s with them,
5.9 s compiling (Intel Xeon, 2026-12-07; an AMD EPYC with AVX-512, 2026-12-06: 1.8 and 4.3 s).
"""

from __future__ import annotations

import hashlib
import os
import pickle
import platform
import re
import sys
import tempfile
import zlib
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


EXECUTABLE_ISA = "AVX2"
"""XLA's instruction-set cap (``--xla_cpu_max_isa``) of the shipped executables."""

_X86_64_V3 = frozenset({"sse4_2", "popcnt", "avx", "avx2", "bmi1", "bmi2", "f16c", "fma",
                        "movbe", "abm"})
"""The CPU flags (``/proc/cpuinfo``) an :data:`EXECUTABLE_ISA` executable may use (x86-64-v3;
``abm``: LZCNT)."""


def _cpu_flags() -> frozenset[str]:
    """This CPU's flags (``/proc/cpuinfo``; empty where there is none)."""
    try:
        with open("/proc/cpuinfo") as f:
            return frozenset(next((line.split(":", 1)[1].split() for line in f
                                   if line.startswith("flags")), []))
    except OSError:
        return frozenset()


@cache
def _cpu_runs_shipped() -> bool:
    """Linux on an x86-64 CPU with every flag of :data:`_X86_64_V3`."""
    if not sys.platform.startswith("linux") or platform.machine() not in ("x86_64", "AMD64"):
        return False
    return _X86_64_V3 <= _cpu_flags()


def executables_usable() -> bool:
    """Whether shipped executables may be loaded here (see the module docstring): not switched
    off by ``JAXDOBBY_SHIPPED_EXECUTABLES=off``, JAX's default backend the CPU, and a CPU that
    runs them."""
    if os.environ.get("JAXDOBBY_SHIPPED_EXECUTABLES", "").lower() == "off":
        return False
    return jax.default_backend() == "cpu" and _cpu_runs_shipped()


def executable_key(name: str, exported, specs: Sequence, setting: str) -> str | None:
    """The key of the compiled executable of an exported program (None for an
    :class:`Unstored` one): a hash of the program's text and argument shapes, ``setting``
    (what else the compilation depends on: options, devices, a wrapper around the program),
    the JAX and jaxlib versions and :data:`EXECUTABLE_ISA`. Its files are
    :func:`executable_variants`."""
    import jaxlib

    if not isinstance(exported, jax.export.Exported):
        return None
    digest = hashlib.sha256(exported.mlir_module_serialized)
    shapes = ";".join(f"{s.dtype}{list(s.shape)}" for s in map(_spec, specs))
    text = "\n".join([name, shapes, setting, jax.__version__, jaxlib.__version__,
                      EXECUTABLE_ISA])
    digest.update(text.encode())
    return f"{name}-{digest.hexdigest()[:24]}.xlaexe"


_FEATURES = re.compile(rb"[+-]64bit(?:,[+-][A-Za-z0-9_.\-]+)+")
"""LLVM's target-feature list as XLA:CPU records it in a serialised executable."""

SYSTEM_FEATURES = frozenset({
    # operating-system, privileged, cache-control, transactional, random-number and
    # synchronisation instructions: LLVM emits them only for their intrinsics or inline
    # assembly, which XLA's kernels do not contain (X86.td, "ISA Extensions")
    "cldemote", "clflushopt", "clwb", "clzero", "enqcmd", "fsgsbase", "hreset", "invpcid",
    "movdir64b", "movdiri", "mwaitx", "pconfig", "pku", "prefetchi", "ptwrite", "rdpid",
    "rdpru", "rdrnd", "rdseed", "rtm", "serialize", "sgx", "shstk", "tsxldtrk", "uintr",
    "waitpkg", "wbnoinvd", "xsave", "xsavec", "xsaveopt", "xsaves",
    # tuning flags, not instructions
    "prefer-no-gather", "prefer-no-scatter"})
"""CPU features XLA records (from the compile host) that its generated code never uses.
:func:`without_system_features` marks them off in a shipped executable, so that a CPU of the
same instruction set lacking one of them (an AMD EPYC without ``pku``, an Intel without
``rtm``) loads it, and XLA's loader does not warn of a SIGILL that cannot happen. Every other
recorded feature (vector, bit-manipulation, crypto, ``sse4a``, ``avx10.1``...) is one LLVM may
select by itself and is required of the CPU that loads the executable."""


def without_system_features(serialized: bytes) -> bytes:
    """A serialised XLA:CPU executable with each of its :data:`SYSTEM_FEATURES` recorded as
    disabled (``+pku`` → ``-pku``: the same length, so the record's framing is unchanged; the
    machine code is untouched)."""
    found = _FEATURES.search(serialized)
    if found is None:
        return serialized
    flags = found.group().split(b",")
    flags = [b"-" + f[1:] if f[:1] == b"+" and f[1:].decode() in SYSTEM_FEATURES else f
             for f in flags]
    return serialized[:found.start()] + b",".join(flags) + serialized[found.end():]


def compiled_features(serialized: bytes) -> frozenset[str]:
    """The CPU features (LLVM's names, e.g. ``avx2``, ``sse4a``) enabled in the compilation of
    a serialised XLA:CPU executable: those of the CPU it was compiled on, less the vector
    instructions above its ``--xla_cpu_max_isa``. Empty if none are recorded."""
    found = _FEATURES.search(serialized)
    if found is None:
        return frozenset()
    return frozenset(f[1:] for f in found.group().decode().split(",") if f.startswith("+"))


@cache
def host_features() -> frozenset[str]:
    """:func:`compiled_features` of a tiny program compiled here (~0.06 s): the CPU features
    XLA compiles for on this machine, with this process's XLA flags."""
    from jax.experimental.serialize_executable import serialize

    serialized, _, _ = serialize(jax.jit(lambda x: x + 1.0).lower(1.0).compile())
    return compiled_features(serialized)


def executable_variants(key: str) -> list[Path]:
    """The shipped files of executable ``key``: one per family of CPU it was compiled on,
    ``<key without .xlaexe>.<8 hex digits of its features>.xlaexe``."""
    return sorted(SHIPPED.glob(f"{key.removesuffix('.xlaexe')}.*.xlaexe"))


def _read_variant(path: Path) -> tuple:
    """(serialized, in_tree, out_tree) of a shipped executable file."""
    return pickle.loads(zlib.decompress(path.read_bytes()))


def variant_features(path: Path) -> frozenset[str]:
    """:func:`compiled_features` of a shipped executable file."""
    return compiled_features(_read_variant(path)[0])


def fits_here(path: Path) -> bool:
    """Whether this CPU has every feature the executable file was compiled for."""
    features = variant_features(path)
    return bool(features) and features <= host_features()


def _variant_name(key: str, features: frozenset[str]) -> str:
    tag = hashlib.sha256(",".join(sorted(features)).encode()).hexdigest()[:8]
    return f"{key.removesuffix('.xlaexe')}.{tag}.xlaexe"


def write_executable(compiled, directory: Path, key: str) -> Path:
    """Serialise a compiled program (``jax.stages.Compiled``) atomically into ``directory`` as
    the variant of executable ``key`` for this CPU's instruction set (:func:`executable_variants`,
    :func:`without_system_features`). Returns its path."""
    from jax.experimental.serialize_executable import serialize

    return write_variant(directory, key, serialize(compiled))


def write_variant(directory: Path, key: str, payload: tuple) -> Path:
    """Write a serialised executable ``(serialized, in_tree, out_tree)`` of ``key`` atomically
    into ``directory``, its system features marked off (:func:`without_system_features`), named
    after the features it then records (zlib-compressed: object code of a few MB shrinks about
    sixfold). Returns its path."""
    serialized, in_tree, out_tree = payload
    payload = (without_system_features(serialized), in_tree, out_tree)
    path = directory / _variant_name(key, compiled_features(payload[0]))
    directory.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=".xlaexe")
    with os.fdopen(fd, "wb") as f:
        f.write(zlib.compress(pickle.dumps(payload), 6))
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)
    return path


def _bind_lapack() -> None:
    """A deserialised executable calls jaxlib's LAPACK kernels (Cholesky, eigh, LU) directly,
    and jaxlib binds them to SciPy's LAPACK on the first *lowering* of a LAPACK operation:
    without one in this process, the first call of the executable crashes (seen: segmentation
    fault). Lowering one tiny Cholesky (no compile; ~0.3 s, mostly importing SciPy's LAPACK)
    binds them."""
    jax.jit(jnp.linalg.cholesky).lower(jnp.eye(1))


_LOADED: dict = {}
"""Loaded executables, by (key, this CPU's features, devices): each is loaded once per process
(``jaxdobby simulate --animate`` runs the shipped run from the command line and again from
Python's ``simulate()``; a sweep runs it once per value)."""


def _load_variant(key: str, devices: Sequence | None):
    """The first variant of ``key`` compiled for this CPU's features, loaded (once per
    process: :data:`_LOADED`); or None."""
    memo = (key, host_features(), None if devices is None else tuple(devices))
    if memo not in _LOADED:
        _LOADED[memo] = _load_first_fitting(key, devices)
    return _LOADED[memo]


def _load_first_fitting(key: str, devices: Sequence | None):
    """Of the variants of ``key`` compiled for features this CPU has, the one of the most
    features (an AVX-512 variant before the AVX2 one where both fit), loaded; or None."""
    from jax.experimental.serialize_executable import deserialize_and_load

    fitting = []
    for path in executable_variants(key):
        try:
            serialized, in_tree, out_tree = _read_variant(path)
        except Exception:  # noqa: BLE001  (an unreadable file: the next, or compile)
            continue
        features = compiled_features(serialized)
        if features and features <= host_features():  # else compiled for features it lacks
            fitting.append((len(features), path.name, (serialized, in_tree, out_tree)))
    for _, _, (serialized, in_tree, out_tree) in sorted(fitting, reverse=True):
        try:
            return deserialize_and_load(serialized, in_tree, out_tree,
                                        execution_devices=devices or jax.devices()[:1])
        except Exception:  # noqa: BLE001  (any failure to load: the next, or compile)
            continue
    return None


WIDE_ISA = "AVX512"
"""The second instruction-set cap of the Sobol study's chunk executable, shipped beside the
:data:`EXECUTABLE_ISA` one where the shipping CPU has it: the chunk's loops run over the
batch's lanes and gain from 512-bit vectors (`jaxdobby sobol`, N = 1024, on 2 cores with
AVX-512, 2026-12-07: 1075 samples/s compiled here against 864 with the AVX2 executable)."""


def isa_level(features: frozenset[str]) -> str:
    """The instruction-set cap an executable of these compiled features was built under:
    :data:`WIDE_ISA` where it may use AVX-512, else :data:`EXECUTABLE_ISA`."""
    return WIDE_ISA if "avx512f" in features else EXECUTABLE_ISA


def shipped_executables(keys: Sequence[str | None], devices: Sequence | None = None) -> list:
    """The shipped executable of each key, loaded onto ``devices`` (None: the default device):
    the first of its :func:`executable_variants` whose compiled features this CPU has
    (:func:`host_features`); None where none fits or :func:`executables_usable` says no.

    XLA's loading (rebuilding the optimised HLO module, its buffer assignment and thunks from
    their protos: it grows with the program's size, not its machine code, ~0.9 s for
    ``jaxdobby simulate``'s run on 2 cores) runs outside Python's lock: the executables and the
    LAPACK binding (:func:`_bind_lapack`) load in parallel threads (measured 1.15 s instead of
    1.43 s for simulate's two).

    The package's own files only (``pickle``, and an XLA executable is machine code: never
    load one from elsewhere)."""
    from concurrent.futures import ThreadPoolExecutor

    todo = [i for i, key in enumerate(keys) if key is not None and executable_variants(key)]
    if not todo or not executables_usable():
        return [None] * len(keys)
    with ThreadPoolExecutor(len(todo) + 1) as pool:
        bound = pool.submit(_bind_lapack)
        host_features()  # before the loads: each reads it
        loading = {i: pool.submit(_load_variant, keys[i], devices) for i in todo}
        bound.result()
        return [loading[i].result() if i in loading else None for i in range(len(keys))]


def shipped_executable(key: str | None, devices: Sequence | None = None):
    """:func:`shipped_executables` of one key."""
    return shipped_executables([key], devices)[0]


class Unstored(NamedTuple):
    """A program that cannot be exported (it calls back into Python: ``jax.export`` does not
    serialise host callbacks, which diffrax's adaptive solver uses): traced in every run and
    never stored, with the two attributes of an exported program this module uses."""

    call: Callable
    out_avals: tuple


def together_keys(programs: Sequence[tuple], compiler_options: dict | None = None) -> list:
    """:func:`executable_key` of each program :func:`compile_together` compiles (None: not
    shippable)."""
    setting = f"compile_together {sorted((compiler_options or {}).items())}"
    return [executable_key(getattr(exported, "fun_name", "program"), exported, specs, setting)
            for exported, specs in programs]


def compile_together(programs: Sequence[tuple], compiler_options: dict | None = None, *,
                     ship: Path | None = None) -> list:
    """Compile several exported programs at once: ``programs`` a sequence of (exported,
    argument specs); returns their compiled callables, in order. A program the package ships
    compiled (:func:`shipped_executable`) is loaded instead; ``ship``: a directory to write
    the compiled executables to (``python -m jaxdobby.programs``).

    Each is lowered here (Python work, one after the other), then XLA compiles them in as many
    threads: XLA's CPU compilation of one program runs on one core at a time, so two programs
    compile in about the time of the longer (measured on 2 cores, 2026-12-04: simulate's steady
    state and the batch evaluator's programs, 7.4 s one after the other, 4.5 s together).
    ``compiler_options``: XLA options of every compilation (e.g. :data:`ONE_SHOT`); None:
    JAX's.
    """
    from concurrent.futures import ThreadPoolExecutor

    keys = together_keys(programs, compiler_options)
    done = [None] * len(keys) if ship is not None else shipped_executables(keys)
    todo = [i for i, c in enumerate(done) if c is None]
    lowered = [jax.jit(programs[i][0].call).lower(*map(_spec, programs[i][1])) for i in todo]
    options = compiler_options or None
    if len(lowered) == 1:
        compiled = [lowered[0].compile(compiler_options=options)]
    else:
        with ThreadPoolExecutor(max(len(lowered), 1)) as pool:
            compiled = list(pool.map(lambda low: low.compile(compiler_options=options), lowered))
    for i, c in zip(todo, compiled):
        done[i] = c
        if ship is not None and keys[i] is not None:
            write_executable(c, ship, keys[i])
    return done


def shipped_program(name: str, static_key: str, args: Sequence) -> tuple:
    """(the exported program the package ships for ``name``, ``static_key`` and arguments
    shaped as ``args``, or None; the path it has or would have)."""
    path = SHIPPED / program_key(name, static_key, args)
    return (_read(path) if path.exists() else None), path


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


_CALLS: dict = {}
"""The compiled programs of :func:`stored_call`, by program and compile options: each is
compiled (or loaded) once per process."""


def stored_call(name: str, fn: Callable, args: Sequence, *, static_key: str = "",
                directory: Path | None = None, compiler_options: dict | None = None,
                ship: Path | None = None):
    """``fn(*args)`` through its stored program (:func:`stored_program`), compiled once per
    process (:func:`compile_together`: the package's shipped executable where there is one).

    The arrays among the leaves of ``args`` (any pytrees: equinox modules, dicts) are the
    program's inputs; everything else in them (strings, numbers, static fields, the trees'
    structure) is part of the program's key, with ``static_key`` (a text describing what
    ``fn`` closes over). A later call with other arrays of the same shapes runs the compiled
    program again; a later process reads the traced program from ``directory`` (or the
    package's) instead of tracing ``fn``. ``fn`` must return a pytree of standard containers
    of arrays.

    Args:
        name: the program's name (a file-name prefix).
        fn: the function; ``args``: its arguments.
        static_key: what else the program depends on.
        directory: where programs are stored; None: only the shipped ones are read.
        compiler_options: XLA options of the compilation (e.g. :data:`ONE_SHOT`).
        ship: where to write the compiled executable (``python -m jaxdobby.programs``).
    """
    flat, leaves, specs, key = _flattened(name, fn, args, static_key)
    memo = process_memo(program_key(name, key, specs),
                        repr(sorted((compiler_options or {}).items())), directory=directory)
    compiled = None if ship is not None else _CALLS.get(memo)
    if compiled is None:
        exported = stored_program(name, flat, specs, static_key=key, directory=directory)
        compiled = compile_together([(exported, specs)], compiler_options, ship=ship)[0]
        if ship is None:
            _CALLS[memo] = compiled
    return compiled(*leaves)


def process_memo(*parts, directory: Path | None) -> tuple:
    """The key under which a process keeps a compiled program (:func:`stored_call`,
    :func:`jaxdobby.simulate.stored_report_arrays`): ``parts`` (the program's key, its
    options), the folder it was read from, and what decides whether a shipped executable was
    loaded instead (the shipped folder, :func:`executables_usable`)."""
    return (*parts, str(directory), str(SHIPPED), executables_usable())


def call_program(name: str, fn: Callable, args: Sequence, *, static_key: str = "",
                 directory: Path | None = None) -> tuple:
    """(the exported program, its argument specs, its file name: :func:`program_key`) that
    :func:`stored_call` runs for these arguments, without compiling it (for
    :func:`together_keys`)."""
    flat, _, specs, key = _flattened(name, fn, args, static_key)
    return (stored_program(name, flat, specs, static_key=key, directory=directory), specs,
            program_key(name, key, specs))


def _flattened(name: str, fn: Callable, args: Sequence, static_key: str) -> tuple:
    """(fn of the flat arrays, the arrays, their specs, the static key) of a call."""
    import equinox as eqx

    dynamic, static = eqx.partition(tuple(args), eqx.is_array)
    leaves, tree = jax.tree.flatten(dynamic)
    leaves = [jnp.asarray(a) for a in leaves]

    def flat(*values):
        return fn(*eqx.combine(jax.tree.unflatten(tree, values), static))

    flat.__name__ = flat.__qualname__ = name.replace("-", "_")  # its executable's name
    return flat, leaves, [_spec(a) for a in leaves], repr((static, tree, static_key))


def main() -> None:
    """Make the shipped programs and executables of the default configuration
    (``python -m jaxdobby.programs``).

    Runs itself again in a fresh process whose XLA is set up as the shipped executables need
    it (XLA reads its flags once, when JAX starts its backend): instruction set capped at
    :data:`EXECUTABLE_ISA`, the devices of the default study, no persistent cache (whose
    executables were compiled for this CPU's full instruction set)."""
    from .sensitivity.command import SHIPPED_DEVICES

    stage = os.environ.get("_JAXDOBBY_SHIPPING")
    if stage not in ("1", WIDE_ISA):
        _ship_in_fresh_process("1", EXECUTABLE_ISA, SHIPPED_DEVICES)
    from .command_line import _configure_jax

    _configure_jax()
    if stage == WIDE_ISA:
        _ship_wide_chunk(SHIPPED_DEVICES)
        return
    from .config import RunOptions
    from .parameters import Setup
    from .simulate import stored_report, write_structure

    # XLA's machine code differs from one compilation to the next (not its arithmetic): an
    # executable whose key and CPU features are unchanged keeps its old bytes, so that the
    # repository does not take in megabytes of new binaries whenever the sources' fingerprint
    # changes; variants compiled on other CPUs are kept while their key is current
    before = {path.name: path.read_bytes() for path in SHIPPED.glob("*.xlaexe")}
    for path in [*SHIPPED.glob("*.jaxexport"), *SHIPPED.glob("*.xlaexe"),
                 *SHIPPED.glob("*.structure")]:
        path.unlink()
    stored_report(Setup(), RunOptions(), directory=SHIPPED, ship=SHIPPED)
    write_structure(SHIPPED, Setup(), RunOptions())  # what Python's simulate() rebuilds
    _ship_chunk(SHIPPED, SHIPPED_DEVICES)
    from .optimize.command import ship_programs

    ship_programs(SHIPPED)  # jaxdobby optimize's: values, the scan of starts, the gradient
    from .weave.loom import ship_programs as ship_loom

    ship_loom(SHIPPED)  # jaxdobby loom --weave twill22 (and every weave of 4 picks on 8 frames)
    current = {path.name.split(".")[0] for path in SHIPPED.glob("*.xlaexe")}
    for name, data in before.items():
        stem = name.split(".")[0]
        if stem in current:  # its system features marked off, if an older file has them
            payload = pickle.loads(zlib.decompress(data))
            path = write_variant(SHIPPED, stem + ".xlaexe", payload)
            if path.name == name:
                path.write_bytes(data)  # unchanged: the very bytes
        else:
            print(f"removed the stale executable {name}")
    for stem in current:  # a variant needing more features than another one of the same
        # instruction-set cap is dead weight (the other fits wherever it does, as fast)
        variants = {path: variant_features(path) for path in executable_variants(stem)}
        for path, features in variants.items():
            if any(other < features and isa_level(other) == isa_level(features)
                   for other in variants.values()):
                path.unlink()
                print(f"removed {path.name}: a variant of fewer features fits wherever it does")
    for path in sorted([*SHIPPED.glob("*.jaxexport"), *SHIPPED.glob("*.xlaexe"),
                        *SHIPPED.glob("*.structure")]):
        print(f"wrote {path.relative_to(PACKAGE.parent)} ({path.stat().st_size / 1e3:.0f} kB)")
    if "avx512f" in _cpu_flags():
        _ship_in_fresh_process(WIDE_ISA, WIDE_ISA, SHIPPED_DEVICES)


def _ship_in_fresh_process(stage: str, isa: str, devices: int) -> None:
    """Run ``python -m jaxdobby.programs`` again as ``stage``, in a process whose XLA is set
    up as the shipped executables need it (XLA reads its flags once, when JAX starts its
    backend): instruction set capped at ``isa``, ``devices`` CPU devices, no persistent cache
    (whose executables were compiled for this CPU's full instruction set)."""
    flags = (f"{os.environ.get('XLA_FLAGS', '')} --xla_cpu_max_isa={isa} "
             f"--xla_force_host_platform_device_count={devices}").strip()
    env = dict(os.environ, _JAXDOBBY_SHIPPING=stage, XLA_FLAGS=flags, JAXDOBBY_CACHE_DIR="off")
    os.execve(sys.executable, [sys.executable, "-m", "jaxdobby.programs"], env)


def _ship_chunk(directory: Path, devices: int) -> None:
    """The default Sobol study's chunk program traced and compiled into ``directory``."""
    import dataclasses

    from .sensitivity.batch import chunk_function
    from .sensitivity.command import default_chunk, default_study_model

    row, stored, dim = default_study_model()
    chunk_function(row, default_chunk(devices), dim, jax.devices()[:devices],
                   dataclasses.replace(stored, directory=directory, ship=directory))


def _ship_wide_chunk(devices: int) -> None:
    """The Sobol study's chunk executable compiled under :data:`WIDE_ISA`, added as a variant
    of its key (an unchanged variant keeps its old bytes)."""
    with tempfile.TemporaryDirectory() as tmp:
        _ship_chunk(Path(tmp), devices)
        for path in Path(tmp).glob("*.xlaexe"):
            if isa_level(variant_features(path)) != WIDE_ISA:
                continue  # this jaxlib compiled no AVX-512 code: nothing to add
            target = SHIPPED / path.name
            if not target.exists():
                path.replace(target)
            print(f"wrote {target.relative_to(PACKAGE.parent)} ({target.stat().st_size / 1e3:.0f}"
                  " kB)")


if __name__ == "__main__":
    main()
