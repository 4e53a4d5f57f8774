"""The ``jaxdobby sobol`` command: its options and the run itself.

The CLI wires argparse to this module::

    parser = subparsers.add_parser("sobol", help="Sobol sensitivity indices")
    add_arguments(parser, MODELS)
    ...
    jax.config.update("jax_enable_x64", True)
    run = run_sobol(SobolConfig.from_args(ns), MODELS[ns.model], progress=ProgressBar())

or simply calls :func:`main` (``python -m jaxdobby.sensitivity`` does).

Several processes or hosts: start the same command once per process with
``--coordinator HOST:PORT --num-processes P --process-id I`` (or the environment variables
``JAXDOBBY_COORDINATOR``, ``JAXDOBBY_NUM_PROCESSES``, ``JAXDOBBY_PROCESS_ID``), all with the same
``--out`` (a shared directory, or the same path on each host). Process I computes chunks
I, I + P, I + 2P, … and writes them; the outputs are then exchanged (``process_allgather``),
and process 0 analyses and writes the indices and figures. ``--resume`` works per process: each
reads back its own finished chunks.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import jax
import numpy as np

from .analysis import SobolResult, analyze, check_settings
from .batch import (DEFAULT_CHUNK, DEVICE_CHUNK, Evaluation, Progress, StoredModel,
                    check_chunk_size, evaluate,
                    local_devices)
from .dobby import DOBBY
from .failures import POLICIES, FailedSamplesError
from .models import ISHIGAMI, ModelSpec, check_steps
from .stress import DOBBY_STRESS
from .plots import save_figures
from .progress import ProgressBar
from .space import ParameterSpace, check_base_samples
from .store import ChunkStore, atomic_write, samples_digest, write_json

MODELS: dict[str, ModelSpec] = {"dobby": DOBBY, "ishigami": ISHIGAMI, "dobby-stress": DOBBY_STRESS}
"""Models ``--model`` can name (the dobby by default; Ishigami for checking the pipeline;
``dobby-stress`` adds the arm's peak stress and fatigue factor, :mod:`.stress`)."""

@dataclasses.dataclass(frozen=True)
class SobolConfig:
    """Settings of a Sobol run (the ``jaxdobby sobol`` options).

    Attributes:
        n: base samples N (power of two); the model runs N(D+2), or N(2D+2) with second order.
        params: the parameters: None (the model's default problem), names (a list or
            comma-separated), or the path of a TOML problem file (see ``space.py``).
        second_order: also estimate pair indices S2.
        seed: seed of the Sobol' scrambling and of the bootstrap.
        out: output directory.
        resume: continue the run in ``out`` from its finished chunks.
        devices: local devices to use (None: all).
        json: the CLI prints JSON instead of a table.
        chunk_size: rows per chunk (None: :data:`~jaxdobby.sensitivity.batch.DEVICE_CHUNK`
            per device).
        model: name of the model in :data:`MODELS`.
        steps: collocation steps per cycle of the dobby's models (None: their default, by
            each row's speed for the dobby, 432 for dobby-stress);
            fewer run faster and less accurately (:data:`STEPS_HELP`).
        on_failure: failed-sample policy, ``"raise"`` or ``"drop"`` (see ``failures.py``).
        num_resamples, conf_level: bootstrap resamples and level of the intervals.
        figures: write the figures.
        coordinator, num_processes, process_id: ``jax.distributed`` settings (all or none).
    """

    n: int = 1024
    params: str | Sequence[str] | None = None
    second_order: bool = False
    seed: int = 0
    out: str | os.PathLike = "sobol"
    resume: bool = False
    devices: int | None = None
    json: bool = False
    chunk_size: int | None = None
    model: str = "dobby"
    steps: int | None = None
    on_failure: str = "raise"
    num_resamples: int = 100
    conf_level: float = 0.95
    figures: bool = True
    coordinator: str | None = None
    num_processes: int | None = None
    process_id: int | None = None

    @classmethod
    def from_args(cls, ns: argparse.Namespace) -> "SobolConfig":
        """The config from parsed :func:`add_arguments` options."""
        return cls(**{f.name: getattr(ns, f.name) for f in dataclasses.fields(cls)
                      if hasattr(ns, f.name)})


@dataclasses.dataclass(frozen=True)
class SobolRun:
    """What a run produced. ``result`` is on every process; files only on process 0."""

    result: SobolResult
    evaluation: Evaluation
    space: ParameterSpace
    out: Path
    files: tuple[Path, ...]
    writer: bool


def add_arguments(parser: argparse.ArgumentParser,
                  models: Mapping[str, ModelSpec] = MODELS) -> None:
    """Add the ``sobol`` options to ``parser``."""
    env = os.environ.get
    a = parser.add_argument
    a("--n", type=int, default=1024, help="base samples N, a power of two (default 1024)")
    a("--params", default=None, help="parameters: comma-separated names (default: the model's "
      "default problem) or a TOML problem file")
    a("--second-order", action="store_true", help="also estimate pair indices S2")
    a("--seed", type=int, default=0, help="seed of the sampling and bootstrap (default 0)")
    a("--out", default="sobol", help="output directory (default ./sobol)")
    a("--resume", action="store_true", help="continue the run in --out from its finished chunks")
    a("--devices", type=int, default=None, help="local devices to use (default all; on CPU, K "
      "devices need XLA_FLAGS=--xla_force_host_platform_device_count=K)")
    a("--json", action="store_true", help="print the indices as JSON instead of a table")
    a("--chunk-size", type=int, default=None,
      help=f"rows per chunk (default {DEVICE_CHUNK} per device: {DEFAULT_CHUNK} on 2 devices)")
    a("--steps", type=int, default=None, help=STEPS_HELP)
    a("--on-failure", choices=POLICIES, default="raise", help="failed samples: 'raise' (default, "
      "no indices) or 'drop' (leave out their base samples)")
    a("--num-resamples", type=int, default=100, help="bootstrap resamples (default 100)")
    a("--conf-level", type=float, default=0.95, help="confidence level (default 0.95)")
    a("--no-figures", dest="figures", action="store_false", help="do not write figures")
    a("--coordinator", default=env("JAXDOBBY_COORDINATOR"), help="HOST:PORT of process 0, to "
      "run as one of several processes (jax.distributed; or $JAXDOBBY_COORDINATOR)")
    a("--num-processes", type=int, default=_int_env("JAXDOBBY_NUM_PROCESSES"),
      help="number of processes (or $JAXDOBBY_NUM_PROCESSES)")
    a("--process-id", type=int, default=_int_env("JAXDOBBY_PROCESS_ID"),
      help="this process's id, 0 … P-1 (or $JAXDOBBY_PROCESS_ID)")
    default_model = "dobby" if "dobby" in models else sorted(models)[0]
    a("--model", choices=sorted(models), default=default_model,
      help="dobby (default), dobby-stress (adds the arm's peak stress and fatigue factor; "
           "slower), ishigami (checks the pipeline)")


STEPS_HELP = (
    "collocation steps per cycle of every row of the dobby models, an integer 72…4320 "
    "(default, --model dobby: by each row's speed, 432 below 450 r/min, 360 below 650, 288 "
    "below 1000, 216 above, every metric within 3e-5 of the adaptive reference at the corners "
    "of each speed range; dobby-stress: 432). Fewer "
    "run faster and less accurately (measured on --model dobby): 216 steps give 1.7× the "
    "samples per second; over the default study's 10 240 rows they move the velocity "
    "deviation's amplitude by up to 1.3e-3 relative (median 1e-5), the other metrics by up to "
    "1.3e-4, and no index by 1e-5. Largest error at the box's corners against the adaptive "
    "reference: 216 steps 8e-4, 288 2.4e-4, 360 8e-5 (the velocity deviation's amplitude at "
    "400 r/min). Multiples of 72 keep the default modulator's dwell boundaries on step "
    "boundaries")
"""``--steps``' help: what the steps cost and give (the errors: :mod:`jaxdobby.periodic.steady`;
the speed: ``benchmarks/sobol_throughput.py --steps``)."""


def _int_env(name: str) -> int | None:
    value = os.environ.get(name)
    return None if value in (None, "") else int(value)


def build_space(config: SobolConfig, model: ModelSpec) -> ParameterSpace:
    """The parameter space the config asks for, checked against the model's registry."""
    p = config.params
    if p is None:
        return ParameterSpace.from_names(model.default_names, model.parameters)
    if isinstance(p, str) and (p.endswith(".toml") or os.path.isfile(p)):
        return ParameterSpace.from_toml(p, model.parameters)
    names = [s.strip() for s in p.split(",")] if isinstance(p, str) else list(p)
    if not all(names):
        raise ValueError(f"params: empty name in {p!r}; give comma-separated names or a .toml file")
    return ParameterSpace.from_names(names, model.parameters)


def initialize_distributed(config: SobolConfig) -> None:
    """Join ``jax.distributed`` when the config names a coordinator (all three fields or none)."""
    fields = (config.coordinator, config.num_processes, config.process_id)
    if all(f is None for f in fields):
        return
    if any(f is None for f in fields):
        raise ValueError("--coordinator, --num-processes and --process-id go together; got "
                         f"{fields}")
    if not 0 <= config.process_id < config.num_processes:
        raise ValueError(f"--process-id must be in [0, {config.num_processes}); "
                         f"got {config.process_id}")
    if not jax.distributed.is_initialized():
        jax.distributed.initialize(config.coordinator, config.num_processes, config.process_id)


@contextlib.contextmanager
def _stdout_to_stderr():
    """Send what native code writes to file descriptor 1 to stderr meanwhile.

    Gloo (JAX's CPU collectives) prints "[Gloo] Rank 0 is connected …" to stdout when the
    processes first connect; stdout is kept for the results (``--json``).
    """
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _everyone_ok(error: Exception | None) -> None:
    """Raise on every process if any process failed a check (so none waits at a barrier)."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        with _stdout_to_stderr():  # the first collective connects the processes
            flags = multihost_utils.process_allgather(np.int32(error is not None))
        if error is None and np.any(flags):
            raise ValueError("another process refused the output directory (see its message)")
    if error is not None:
        raise error


def run_sobol(config: SobolConfig, model: ModelSpec | None = None, *,
              progress: Progress | None = None) -> SobolRun:
    """Run a Sobol study: sample, evaluate in chunks (resumable), analyse, write results.

    Args:
        config: the run's settings.
        model: the model; None looks ``config.model`` up in :data:`MODELS`.
        progress: ``progress(done, total)`` in rows of this process's share (e.g. a
            :class:`ProgressBar`).

    Returns:
        The run; process 0 has written ``manifest.json``, ``chunks/``, ``outputs.npz``,
        ``indices.json``, ``indices.csv`` and ``figures/`` into ``config.out``.

    Raises:
        ValueError: bad settings, problem or output directory (a clear message).
        FailedSamplesError: samples failed under ``on_failure="raise"``; process 0 has written
            ``failures.json`` first.
    """
    if model is None:
        if config.model not in MODELS:
            raise ValueError(f"model must be one of {sorted(MODELS)}; got {config.model!r}")
        model = MODELS[config.model]
    n = check_base_samples(config.n)
    if config.on_failure not in POLICIES:
        raise ValueError(f"on_failure must be one of {POLICIES}; got {config.on_failure!r}")
    check_settings(num_resamples=config.num_resamples, conf_level=config.conf_level)
    steps = check_steps(model, config.steps)  # None: the model's default build
    space = build_space(config, model)
    initialize_distributed(config)  # before anything starts JAX's backend (build may)
    fn = model.builder(steps)(space)  # may refuse the problem (bounds the model cannot run)
    n_dev = len(local_devices(config.devices))
    chunk = config.chunk_size or default_chunk(n_dev)
    check_chunk_size(chunk, n_dev)  # before anything is written
    samples = space.sample(n, second_order=config.second_order, seed=config.seed)

    out = Path(config.out)
    manifest = {"format": 1, "model": model.name, "problem": space.to_dict(), "n": n,
                "seed": config.seed, "second_order": config.second_order, "chunk_size": chunk,
                "rows": int(samples.shape[0]), "samples_sha256": samples_digest(samples)}
    if steps is not None:  # (absent at the default: runs of earlier versions resume)
        manifest["steps"] = steps
    groups = model.row_groups(space, samples) if (
        steps is None and model.row_groups is not None) else None
    if groups is not None:  # chunks hold rows grouped by steps: not an earlier version's run
        manifest["chunk_order"] = "steps per cycle by speed"
    store = ChunkStore(out, manifest)
    try:
        store.prepare(config.resume)
        error = None
    except ValueError as e:
        error = e
    _everyone_ok(error)
    store.create()

    t0 = time.perf_counter()
    evaluation = evaluate(fn, samples, chunk_size=chunk, devices=config.devices,
                          store=store, progress=progress, stored=stored_model(model, space, steps),
                          groups=groups)
    seconds = time.perf_counter() - t0
    writer = jax.process_index() == 0
    files = []
    if writer:
        files.append(atomic_write(out / "outputs.npz", lambda f: np.savez(
            f, samples=samples, **{f"output_{k}": v for k, v in evaluation.outputs.items()})))
    run_info = {"model": model.name, "rows": int(samples.shape[0]), "chunk_size": chunk,
                **({} if model.default_steps is None else
                   {"steps": steps if steps is not None else (
                       "by speed" if model.row_groups is not None else model.default_steps)}),
                "devices": evaluation.devices, "processes": evaluation.processes,
                "chunks_computed_here": len(evaluation.computed_chunks),
                "evaluation_seconds": round(seconds, 3)}
    try:
        result = analyze(space, evaluation.outputs, n=n, second_order=config.second_order,
                         on_failure=config.on_failure, num_resamples=config.num_resamples,
                         conf_level=config.conf_level, seed=config.seed, run=run_info)
    except FailedSamplesError as e:
        if writer:
            write_json(out / "failures.json", e.to_dict())
        raise
    result = dataclasses.replace(result, warnings=_sample_warnings(space, samples,
                                                                   evaluation.outputs))
    if writer:
        files.append(write_json(out / "indices.json", result.to_dict()))
        text = result.to_csv()
        files.append(atomic_write(out / "indices.csv", lambda f: f.write(text.encode())))
        if config.figures:
            files += save_figures(result, out / "figures")
    return SobolRun(result, evaluation, space, out, tuple(files), writer)


def default_chunk(devices: int) -> int:
    """Rows per chunk when the config sets none: :data:`~jaxdobby.sensitivity.batch.DEVICE_CHUNK`
    rows per device."""
    return DEVICE_CHUNK * devices


SHIPPED_DEVICES = 2
"""The device count whose default study's program ships with the package (a 2-core CPU)."""


def default_study_program() -> tuple[Callable, StoredModel, jax.ShapeDtypeStruct]:
    """(per-device function, how it is stored, its argument) of the default study
    (``jaxdobby sobol`` with its defaults on :data:`SHIPPED_DEVICES` devices): what
    ``python -m jaxdobby.programs`` ships (:mod:`jaxdobby.programs`)."""
    import jax.numpy as jnp

    row, stored, dim = default_study_model()
    share = default_chunk(SHIPPED_DEVICES) // SHIPPED_DEVICES
    return jax.vmap(row), stored, jax.ShapeDtypeStruct((share, dim), jnp.float64)


def default_study_model() -> tuple[Callable, StoredModel, int]:
    """(model of one row, how it is stored, columns) of the default study."""
    config = SobolConfig()
    model = MODELS[config.model]
    space = build_space(config, model)
    return model.build(space), stored_model(model, space), len(space.names)


def stored_model(model: ModelSpec, space: ParameterSpace,
                 steps: int | None = None) -> StoredModel | None:
    """Where the traced program of a built-in model (:data:`MODELS`) is kept: the command
    line's programs folder (:func:`jaxdobby.command_line.programs_dir`), keyed by the model,
    the sampled parameters with their units and the steps per cycle (``steps`` as
    :func:`~jaxdobby.sensitivity.models.check_steps` returns it: None at the default); None for
    another model (its function is unknown here, so no key could tell two of them apart)."""
    from ..command_line import programs_dir

    if MODELS.get(model.name) is not model:
        return None
    key = repr((space.names, tuple(float(s) for s in space.si_scales)))
    if steps is not None:  # (the default's key unchanged: its shipped program stays valid)
        key += f", steps {steps}"
    return StoredModel(f"sobol-{model.name}", key, programs_dir())


def _sample_warnings(space, samples, outputs) -> dict:
    """Per-sample validity warnings (:func:`jaxdobby.sensitivity.validity.sample_warnings`); a
    stroke not sampled is the default machine's."""
    from .validity import sample_warnings

    if "deviation_pp_mm" not in outputs:
        return {}
    from ..parameters import Setup

    stroke_mm = float(Setup().machine.stroke()) * 1e3
    return sample_warnings(space.names, samples, outputs, stroke_mm)


def use_cpu_cores(devices: int | None) -> None:
    """Give JAX's CPU backend one device per core (or ``devices``), so that a chunk is split
    over all cores of a CPU-only machine without ``XLA_FLAGS``.

    Only possible before JAX has started its backends; when it has (an earlier JAX computation
    in this Python process), or ``XLA_FLAGS`` already sets the count, nothing changes. On a
    machine with accelerators their devices are used as before (the CPU backend is separate).
    """
    if "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", ""):
        return
    with contextlib.suppress(RuntimeError, AttributeError):
        jax.config.update("jax_num_cpu_devices", devices or os.cpu_count() or 1)


def main(argv: Sequence[str] | None = None, models: Mapping[str, ModelSpec] = MODELS) -> int:
    """``jaxdobby sobol``: parse options, run, print the table (or JSON). Returns the exit code."""
    parser = argparse.ArgumentParser(prog="jaxdobby sobol",
                                     description="Sobol sensitivity indices of the model's metrics")
    add_arguments(parser, models)
    ns = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)  # the CLI, not the library, sets float64
    if ns.coordinator is None:
        use_cpu_cores(ns.devices)
    try:
        run = run_sobol(SobolConfig.from_args(ns), models[ns.model], progress=ProgressBar())
    except FailedSamplesError as e:
        print(f"jaxdobby sobol: {e}", file=sys.stderr)
        return 1
    except (ValueError, FileNotFoundError) as e:
        print(f"jaxdobby sobol: error: {e}", file=sys.stderr)
        return 2
    if run.writer:
        if ns.json:
            print(run.result.to_json())
        else:
            print(run.result.table())
            steps = check_steps(models[ns.model], ns.steps)
            if steps is not None:
                print(f"\ncollocation steps per cycle: {steps} (default "
                      f"{models[ns.model].default_steps}): faster and less accurate, see "
                      "'jaxdobby sobol --help'")
            files = ", ".join(str(p.relative_to(run.out)) for p in run.files)
            print(f"\nwritten to {run.out}/: {files}")
    return 0
