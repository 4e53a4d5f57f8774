"""Batched evaluation of a model over a whole sample matrix: chunks, devices, processes.

``evaluate(model, samples)`` runs ``model`` (one sample row → dict of scalar metrics) on every
row of ``samples``:

* **Chunks.** Rows go through in chunks of a fixed size C; the last chunk is padded (with copies
  of its last row; the padding's outputs are dropped), so every chunk has the same shape and the
  per-chunk function is traced and compiled exactly once (ahead of time: a shape change would be
  an error, never a silent recompilation). Only the per-sample metrics leave a chunk, so a model
  that reduces its trajectory to metrics inside the solve keeps batch memory at C trajectories.
  The next chunk is dispatched before the previous one's results are copied out and stored.
* **Devices.** A chunk is split over the local devices with ``jax.shard_map`` over a 1-D mesh
  (axis ``"samples"``; C must be a multiple of the device count); each device runs the vmapped
  model on its C / devices rows. ``check_vma=False`` because models are loops (diffrax #735).
  On CPU, several host devices need ``jax_num_cpu_devices`` (or
  ``XLA_FLAGS=--xla_force_host_platform_device_count=K``) set before JAX starts; the
  ``jaxdobby sobol`` command sets one device per core.
* **Processes.** Under ``jax.distributed`` with P processes, chunk i belongs to process
  i mod P. Every process computes its own chunks on its own devices (no communication during
  the run), writes them to its store, and at the end the outputs of all chunks are exchanged
  with ``multihost_utils.process_allgather``, so every process returns the whole result. All
  processes must call ``evaluate`` with the same model, samples and chunk size.
* **Store.** With a :class:`~jaxdobby.sensitivity.store.ChunkStore`, each finished chunk is
  written atomically; chunks already in the store are read instead of computed (resume).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import NamedSharding, PartitionSpec

from .._x64 import require_x64
from ..programs import executable_key, shipped_executable, stored_program, write_executable
from .failures import STATUS, SampleFailure, find_failures
from .store import ChunkStore

Progress = Callable[[int, int], None]
"""``progress(done, total)``: rows of this process's share finished so far, out of ``total``."""


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """Model outputs for every row of a sample matrix.

    Attributes:
        outputs: per-row arrays of shape (M,): the metrics, and ``"ok"`` if the model returns it.
        chunk_size: rows per chunk C.
        devices: local devices each process used.
        processes: number of processes that shared the chunks.
        computed_chunks: chunks computed by this call on this process (the rest came from the
            store or from other processes).
    """

    outputs: dict[str, np.ndarray]
    chunk_size: int
    devices: int
    processes: int
    computed_chunks: tuple[int, ...]

    @property
    def failures(self) -> tuple[SampleFailure, ...]:
        """Failed rows (``"ok"`` false or any metric non-finite), with reasons."""
        return find_failures(self.outputs)


def local_devices(devices: int | Sequence[jax.Device] | None = None) -> list[jax.Device]:
    """Resolve a device choice: None → all local devices, k → the first k, or a list as is."""
    available = jax.local_devices()
    if devices is None:
        return available
    if isinstance(devices, int):
        if not 1 <= devices <= len(available):
            raise ValueError(
                f"devices must be between 1 and the {len(available)} local device(s); got {devices}"
                " (on CPU, set XLA_FLAGS=--xla_force_host_platform_device_count=K before start)")
        return available[:devices]
    return list(devices)


def check_chunk_size(chunk_size: int, n_devices: int) -> None:
    """Raise ``ValueError`` unless ``chunk_size`` is a positive multiple of ``n_devices``."""
    if chunk_size < 1 or chunk_size % n_devices:
        raise ValueError(f"chunk_size must be a positive multiple of the device count "
                         f"({n_devices}); got {chunk_size}")


def chunk_function(model: Callable, chunk_size: int, dim: int, devices: Sequence[jax.Device],
                   stored: StoredModel | None = None):
    """The compiled per-chunk function: (C, D) float64 samples → dict of (C,) outputs.

    Compiled once per (model, C, D, devices) and kept (the last few), so calling
    :func:`evaluate` again with the same model function does not compile again.

    Args:
        model: one row (D,) → dict of scalar outputs.
        chunk_size: rows per chunk C, a multiple of ``len(devices)``.
        dim: columns D.
        devices: local devices of the 1-D mesh.
        stored: where the traced program of one device's share of a chunk (the vmapped model
            on C / devices rows) is kept (:class:`StoredModel`); None: traced every time.

    Returns:
        ``(compiled, sharding)``: the AOT-compiled function and the input sharding it expects.
    """
    check_chunk_size(chunk_size, len(devices))
    return _compile(model, chunk_size, dim, tuple(devices), stored)


@dataclasses.dataclass(frozen=True)
class StoredModel:
    """How a model's traced per-device program is kept (:func:`jaxdobby.programs.stored_program`).

    Tracing the dobby's model (the finite elements, the modal reduction, the kinematics and the
    collocation passes, vmapped) takes seconds of Python work on every run, longer than XLA
    takes to load its compiled executable from the persistent cache. The per-device program
    (``jax.vmap(model)`` on C / devices rows) is exported once and run under ``shard_map``
    by any number of devices.

    Attributes:
        name: the program's name (a file-name prefix).
        static_key: a text that differs whenever the model function differs (the model, its
            sampled parameters and their units).
        directory: where programs are stored; None: only the shipped ones are read.
        ship: where to write the compiled chunk program (``python -m jaxdobby.programs``);
            None: the package's shipped executable is loaded where there is one
            (:func:`jaxdobby.programs.shipped_executable`).
    """

    name: str
    static_key: str
    directory: Path | None
    ship: Path | None = None


@functools.lru_cache(maxsize=8)
def _compile(model: Callable, chunk_size: int, dim: int, devices: tuple[jax.Device, ...],
             stored: StoredModel | None = None):
    mesh = jax.make_mesh((len(devices),), ("samples",), axis_types=(jax.sharding.AxisType.Auto,),
                         devices=devices)
    spec = PartitionSpec("samples")
    sharding = NamedSharding(mesh, spec)
    body = jax.vmap(model)
    key = None
    if stored is not None:
        share = jax.ShapeDtypeStruct((chunk_size // len(devices), dim), jnp.float64)
        exported = stored_program(stored.name, body, [share], static_key=stored.static_key,
                                  directory=stored.directory)
        body = exported.call
        key = chunk_key(stored, exported, share, devices)
    compiled = None if stored is not None and stored.ship is not None else (
        shipped_executable(key, devices))
    if compiled is None:
        sharded = jax.shard_map(body, mesh=mesh, in_specs=spec, out_specs=spec,
                                check_vma=False)
        arg = jax.ShapeDtypeStruct((chunk_size, dim), jnp.float64, sharding=sharding)
        compiled = compile_for(jax.jit(sharded).lower(arg), devices)
        if stored is not None and stored.ship is not None and key is not None:
            write_executable(compiled, stored.ship, key)
    _check_outputs(compiled.out_info, chunk_size)
    return compiled, sharding


def chunk_key(stored: StoredModel, exported, share, devices: Sequence[jax.Device]) -> str | None:
    """The :func:`jaxdobby.programs.executable_key` of the chunk program compiled from the
    per-device program ``exported`` (for arguments ``share``) over ``devices``: besides that
    program, it depends on the mesh and the compile options."""
    cpu = all(d.platform == "cpu" for d in devices)
    setting = (f"shard_map over {len(devices)} {devices[0].platform} devices, "
               f"options {sorted(CPU_COMPILER_OPTIONS.items()) if cpu else []}")
    return executable_key(f"{stored.name}-chunk", exported, [share], setting)


DEVICE_CHUNK = 64
"""Rows per device of a chunk when the command line sets none (``jaxdobby sobol``).

Larger chunks share each step's fixed costs among more samples, until the chunk program's
temporary buffer outgrows the CPU's caches and glibc's ``mmap`` threshold: XLA's CPU runtime
allocates one temporary buffer per run of a chunk program, and the dobby's batch evaluator
holds ~0.67 MB per sample in it (the rigid motion's tables at the 1296 collocation nodes and
the steps' inverted Newton matrices, each sample's own). glibc serves an allocation above 32 MB
(its largest ``mmap`` threshold) with fresh pages on every run, which the kernel faults in and
zeroes (20 880 page faults per run at 128 samples per device). Measured with
``benchmarks/sobol_throughput.py --chunk C``, one process of two devices, the default study's
rows, steps by speed:

* Intel Xeon (family 6, model 167), 2026-12-07, this code: 1970, 2223 and 1749 samples/s for
  C = 64, 128, 192 (128 again 2140 and 2099 before the inversions of
  :func:`jaxdobby.periodic.collocation.inverse` kept their eliminations, 64 then 1925).
* AMD EPYC (family 25), 2026-12-07, the code before the tables of a sampled linkage were
  built lanes last: 1067, 1219, 1296, 1061 and 945 samples/s for C = 32, 48, 64, 128, 256
  (there 32 per device was best: 1.36 against 1.62 ms per sample at 128 per device with the
  page faults switched off by ``GLIBC_TUNABLES=glibc.malloc.hugetlb=1:glibc.malloc.mmap_max=0``).

The best chunk depends on the CPU (its caches, its cost of a page fault); 64 is this
project's measured best of the machine where the targets are checked, ``--chunk`` sets another."""

DEFAULT_CHUNK = 2 * DEVICE_CHUNK
"""Rows per chunk of :func:`evaluate` by default: :data:`DEVICE_CHUNK` on each of a 2-core
CPU's two devices."""


CPU_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False,
                        "xla_cpu_prefer_vector_width": 512,
                        "xla_cpu_copy_insertion_use_region_analysis": True}
"""XLA options of the per-chunk program on CPU devices.

* Fusions compiled by XLA's loop emitters rather than its newer MLIR fusion emitters. On the
  dobby's batch program (the collocation passes: many small elementwise fusions per step)
  measured faster and quicker to compile (2-core AMD EPYC, jax 0.10.2, 2026-12-02, 256 samples
  on one pinned core, best of 4, interleaved: 1.33–1.42 against 1.52–1.70 ms per sample; two
  devices of one process: 1250 against 840–1010 samples/s; again later that day, one compile
  of each: 1.48 against 1.67 ms per sample, compiled in 14 s against 27 s, metrics equal to
  1.4e-13 relative).
* Vectors of 512 bits where the CPU has them (LLVM otherwise prefers 256 on x86), and copy
  insertion by region analysis (fewer copies of the buffers of nested loops). With the batch's
  lanes last (:func:`jaxdobby.periodic.steady._solve`) the passes' loops run over contiguous
  lanes: 256 samples of the default design on one pinned core (AMD EPYC with AVX-512,
  2026-12-07, best of 5, the arm's terms then laid out by a layout constraint, the effect of
  :func:`jaxdobby.periodic.steady._lane_by_lane` now): 2.28 ms per sample without either,
  2.08 with the first, 2.11 with the second, 1.77 with both (the lanes-first program of
  before: 2.33 without, 2.31 with 512-bit vectors); metrics equal to 3e-12 relative. Shipped
  executables are compiled for AVX2, so the chunk also ships an AVX-512 variant
  (:data:`jaxdobby.programs.WIDE_ISA`).

The numbers are float64 either way (only the generated loops differ, so round-off may). A
jaxlib without one of the options compiles without any."""


def compile_for(lowered, devices: Sequence[jax.Device]):
    """``lowered.compile()``, with :data:`CPU_COMPILER_OPTIONS` when every device is a CPU and
    this jaxlib knows them."""
    if all(d.platform == "cpu" for d in devices):
        try:
            return lowered.compile(compiler_options=CPU_COMPILER_OPTIONS)
        except jax.errors.JaxRuntimeError as err:
            if "compile option" not in str(err):
                raise
    return lowered.compile()


def _check_outputs(out_info, chunk_size: int) -> None:
    if not isinstance(out_info, dict) or not out_info:
        raise TypeError("the model must return a non-empty dict of scalar metrics; got "
                        f"{jax.tree.structure(out_info)}")
    for k, v in out_info.items():
        if not isinstance(k, str) or k.startswith("__"):
            raise TypeError(f"model output names must be strings not starting with '__'; got {k!r}")
        if not hasattr(v, "shape") or v.shape != (chunk_size,):
            raise TypeError(f"model output {k!r} must be a scalar per sample; got shape "
                            f"{getattr(v, 'shape', None)} for {chunk_size} samples")
        if k == STATUS:
            if not (jnp.issubdtype(v.dtype, jnp.bool_) or jnp.issubdtype(v.dtype, jnp.integer)):
                raise TypeError(f"model output {STATUS!r} must be bool or an integer code; "
                                f"got {v.dtype}")
        elif not jnp.issubdtype(v.dtype, jnp.floating):
            raise TypeError(f"metric {k!r} must be a float; got {v.dtype}")


def chunk_order(groups: np.ndarray, chunk_size: int) -> np.ndarray:
    """The rows in the order chunks take them when rows of different ``groups`` (one int per
    row) must not share a chunk: group by group (ascending), each group's rows in their order
    and padded to whole chunks with copies of its last row."""
    parts = []
    for g in np.unique(groups):
        rows = np.flatnonzero(groups == g)
        parts.append(np.concatenate([rows, np.repeat(rows[-1:], -len(rows) % chunk_size)]))
    return np.concatenate(parts)


def evaluate(model: Callable, samples: np.ndarray, *, chunk_size: int = DEFAULT_CHUNK,
             devices: int | Sequence[jax.Device] | None = None, store: ChunkStore | None = None,
             progress: Progress | None = None, stored: StoredModel | None = None,
             groups: np.ndarray | None = None) -> Evaluation:
    """Evaluate ``model`` on every row of ``samples`` (see the module docstring).

    Args:
        model: pure JAX function of one row (D,) [users' units] → dict of scalar metrics, plus
            an optional ``"ok"`` status (bool, or integer code with 0 = success).
        samples: (M, D) float64 sample matrix.
        chunk_size: rows per chunk C, a multiple of the number of local devices used.
        devices: local devices to shard each chunk over: None (all), a count, or a list.
        store: where finished chunks are written and read back on resume; must be created
            (``prepare`` + ``create``) by the caller.
        progress: called with (rows done, rows in this process's share) once at the start and
            after each finished chunk.
        stored: keep the traced program of the model on disk (:class:`StoredModel`).
        groups: (M,) ints, or None: rows of different groups never share a chunk
            (:func:`chunk_order`; the store's chunks then hold rows in that order). For a
            model whose chunk runs as long as its most demanding row (the dobby's steps per
            cycle by speed: :func:`jaxdobby.sensitivity.dobby.step_groups`).

    Returns:
        The outputs of every row, identical on every process.
    """
    require_x64()
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    if samples.ndim != 2 or not samples.shape[0]:
        raise ValueError(f"samples must be a non-empty (M, D) matrix; got shape {samples.shape}")
    if not np.all(np.isfinite(samples)):
        raise ValueError("samples must be finite")
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != samples.shape[:1]:
            raise ValueError(f"groups must have one entry per row ({samples.shape[0]}); got "
                             f"shape {groups.shape}")
        check_chunk_size(chunk_size, 1)  # (the device count's multiple: checked below)
        order = chunk_order(groups, chunk_size)
        first = np.zeros(len(order), bool)
        first[np.unique(order, return_index=True)[1]] = True  # each row once, padding not
        real = np.add.reduceat(first, np.arange(0, len(order), chunk_size))
        ev = _evaluate(model, samples[order], chunk_size, devices, store, progress, stored, real)
        where = np.empty(len(samples), int)
        where[order[first]] = np.flatnonzero(first)
        return dataclasses.replace(ev, outputs={k: v[where] for k, v in ev.outputs.items()})
    return _evaluate(model, samples, chunk_size, devices, store, progress, stored)


def _evaluate(model, samples, chunk_size, devices, store, progress, stored, real=None):
    """:func:`evaluate` of rows in chunk order; ``real``: rows of each chunk that are not
    padding (counted by ``progress``), None: all."""
    total, dim = samples.shape
    devs = local_devices(devices)
    compiled, sharding = chunk_function(model, chunk_size, dim, devs, stored)
    dtypes = {k: np.dtype(v.dtype) for k, v in compiled.out_info.items()}
    n_chunks = math.ceil(total / chunk_size)
    proc, n_proc = jax.process_index(), jax.process_count()
    mine = list(range(proc, n_chunks, n_proc))
    rows = {i: (i * chunk_size, min((i + 1) * chunk_size, total)) for i in mine}
    counted = {i: b - a if real is None else int(real[i]) for i, (a, b) in rows.items()}
    share = sum(counted.values())

    results: dict[int, dict[str, np.ndarray]] = {}
    stored = store.finished() if store is not None else set()
    for i in mine:
        if i in stored:
            results[i] = _read(store, i, rows[i], list(dtypes))
    done = sum(counted[i] for i in results)
    if progress is not None:
        progress(done, share)

    def finish(i, out):
        nonlocal done
        a, b = rows[i]
        host = {k: np.asarray(v)[: b - a] for k, v in out.items()}
        if store is not None:
            store.write_chunk(i, (a, b), host, process=proc)
        results[i] = host
        done += counted[i]
        if progress is not None:
            progress(done, share)

    todo = [i for i in mine if i not in results]
    pending = None
    for i in todo:
        a, b = rows[i]
        x = samples[a:b]
        if b - a < chunk_size:
            x = np.concatenate([x, np.repeat(x[-1:], chunk_size - (b - a), axis=0)])
        out = compiled(jax.device_put(x, sharding))  # dispatched; runs while we store the last
        if pending is not None:
            finish(*pending)
        pending = (i, out)
    if pending is not None:
        finish(*pending)

    outputs = _gather(results, mine, n_chunks, chunk_size, total, dtypes, n_proc)
    return Evaluation(outputs, chunk_size, len(devs), n_proc, tuple(todo))


def _read(store: ChunkStore, i: int, rows: tuple[int, int], keys: list[str]):
    got_rows, data, _ = store.read_chunk(i)
    if got_rows != rows or sorted(data) != sorted(keys):
        raise ValueError(f"{store.chunk_path(i)} holds rows {got_rows} and outputs {sorted(data)}; "
                         f"expected rows {rows} and outputs {sorted(keys)}: not this run's chunk")
    return data


def _gather(results, mine, n_chunks, chunk_size, total, dtypes, n_proc):
    """All chunks' outputs, in row order, on every process."""
    if n_proc == 1:
        return {k: np.concatenate([results[i][k] for i in range(n_chunks)]) for k in dtypes}
    from jax.experimental import multihost_utils

    # Every process sends (slots, C) per output, chunk i in slot i // P of process i mod P;
    # bools travel as int8.
    slots = math.ceil(n_chunks / n_proc)
    local = {}
    for k, dtype in dtypes.items():
        buf = np.zeros((slots, chunk_size), dtype=np.int8 if dtype == np.bool_ else dtype)
        for i in mine:
            buf[i // n_proc, : len(results[i][k])] = results[i][k]
        local[k] = buf
    everyone = multihost_utils.process_allgather(local)
    out = {}
    for k, dtype in dtypes.items():
        full = np.asarray(everyone[k])
        rows = np.concatenate([full[i % n_proc, i // n_proc] for i in range(n_chunks)])
        out[k] = rows[:total].astype(dtype)
    return out
