"""Shared pieces of the benchmark scripts: JAX set-up, timing, environment record, JSON."""

from __future__ import annotations

import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"


CACHE_ENV = "JAXDOBBY_BENCH_CACHE"
"""Environment variable: a persistent compilation cache for every benchmark process (the tests
set it so that their smoke runs reuse compiled programs; full runs leave it unset, so that the
compile times they report are real)."""


def configure_jax(cache_dir: str | None = None):
    """float64 on (both sides compute in float64); a persistent compilation cache at
    ``cache_dir`` or ``$JAXDOBBY_BENCH_CACHE`` if either is given, with the command line's
    settings (:func:`jaxdobby.cli._configure_jax`). Returns ``jax``."""
    import jax

    jax.config.update("jax_enable_x64", True)
    cache_dir = cache_dir or os.environ.get(CACHE_ENV) or None
    if cache_dir is not None:
        jax.config.update("jax_compilation_cache_dir", str(cache_dir))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    return jax


def block(tree):
    """Wait for every array in ``tree`` (JAX dispatches asynchronously)."""
    import jax

    return jax.block_until_ready(tree)


def timed(fn, *, repeats: int, budget_s: float = float("inf")) -> dict:
    """Call ``fn()`` up to ``repeats`` times (at least once; stop early once ``budget_s`` is
    spent) and return the median, min and all times [s] and the last result (``value``)."""
    times, value = [], None
    start = time.perf_counter()
    while len(times) < repeats and (not times or time.perf_counter() - start < budget_s):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return {"median_s": statistics.median(times), "min_s": min(times), "times_s": times,
                "repeats": len(times), "value": value}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                             capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, text=True, capture_output=True, check=False).stdout.strip()
        return out + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def environment() -> dict:
    """Versions, the machine and the moment: what a reader needs to weigh the numbers."""
    import diffrax
    import equinox
    import jax
    import jaxlib
    import numpy
    import scipy

    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count()
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        mem = None
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "versions": {"python": platform.python_version(), "jax": jax.__version__,
                      "jaxlib": jaxlib.__version__, "numpy": numpy.__version__,
                      "scipy": scipy.__version__, "diffrax": diffrax.__version__,
                      "equinox": equinox.__version__},
        "device": {"cpu": _cpu_model(), "cores_available": cores, "memory_gib": mem,
                    "jax_backend": jax.default_backend(),
                    "jax_devices": [str(d) for d in jax.devices()],
                    "system": f"{platform.system()} {platform.release()}"},
        "load_average_start": list(os.getloadavg()),
        "git_commit": _git_commit(),
        "command": " ".join([Path(sys.argv[0]).name] + sys.argv[1:]),
        "float64": bool(jax.config.jax_enable_x64),
    }


def finish(record: dict) -> dict:
    """Stamp the end-of-run load average (other work on a shared machine slows everything)."""
    record["environment"]["load_average_end"] = list(os.getloadavg())
    return record


def write_json(path: Path, record: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1, default=_default) + "\n")
    return path


def _default(x):
    import numpy as np

    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x)}")


def log(*parts):
    """Progress on stderr (results go to the JSON)."""
    print(*parts, file=sys.stderr, flush=True)
