"""Where the default test suite's time goes: every XLA compilation of a run, by program and test.

A pytest plugin (this module, loaded with ``-p benchmarks.suite_compiles``; pytest-xdist loads
it in every worker) turns on ``jax_log_compiles`` and records, from JAX's log, each finished XLA
compilation (program, seconds, the test running), each jaxpr-to-MLIR lowering and each
persistent-cache hit. ``main`` runs the suite that way from an empty cache and writes
``results/suite_compiles.json`` and ``.md``: the totals (big programs and small eager ones
apart), and the biggest compilations with their tests — what to share or shrink first.

Run:  python benchmarks/suite_compiles.py [--out benchmarks/results] [-- extra pytest arguments]
      (e.g. ``-- tests/test_batch.py`` for one file)
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/suite_compiles.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

LOG_DIR = "JAXDOBBY_COMPILE_LOG_DIR"
"""Environment variable: the folder the plugin writes one log per pytest process into."""
SMALL_S = 1.5
"""Compilations below this many seconds count as small (mostly eager operations)."""
PATTERNS = {"compile": re.compile(r"Finished XLA compilation of (.*) in ([0-9.e-]+) sec"),
            "lower": re.compile(r"Finished jaxpr to MLIR module conversion (.*) in "
                                r"([0-9.e-]+) sec"),
            "hit": re.compile(r"Persistent compilation cache hit for '([^']*)'")}


class _Recorder(logging.Handler):
    def __init__(self, path: Path):
        super().__init__(logging.DEBUG)
        self.file = open(path, "a", buffering=1)

    def emit(self, record):
        msg = record.getMessage()
        for kind, pattern in PATTERNS.items():
            m = pattern.search(msg)
            if m:
                test = os.environ.get("PYTEST_CURRENT_TEST", "-").split(" ")[0]
                seconds = float(m.group(2)) if kind != "hit" else 0.0
                self.file.write(json.dumps({"kind": kind, "program": m.group(1),
                                            "seconds": seconds, "test": test}) + "\n")
                return


def pytest_configure(config):
    folder = os.environ.get(LOG_DIR)
    if not folder:
        return
    import jax

    jax.config.update("jax_log_compiles", True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    logger = logging.getLogger("jax")
    logger.addHandler(_Recorder(Path(folder) / f"{worker}.jsonl"))
    logger.setLevel(logging.DEBUG)


def summarise(records: list[dict], top: int = 25) -> dict:
    """Totals and the biggest compilations of a run's records."""
    compiles = [r for r in records if r["kind"] == "compile"]
    big = sorted((r for r in compiles if r["seconds"] >= SMALL_S), key=lambda r: -r["seconds"])
    small = [r for r in compiles if r["seconds"] < SMALL_S]
    return {"compilations": len(compiles),
            "compile_s": sum(r["seconds"] for r in compiles),
            "big": {"count": len(big), "seconds": sum(r["seconds"] for r in big)},
            "small": {"count": len(small), "seconds": sum(r["seconds"] for r in small)},
            "lowering_s": sum(r["seconds"] for r in records if r["kind"] == "lower"),
            "cache_hits": sum(r["kind"] == "hit" for r in records),
            "biggest": big[:top],
            "small_by_test": _grouped(small, "test", top),
            "small_by_program": _grouped(small, "program", top)}


def _grouped(records: list[dict], field: str, top: int) -> list[dict]:
    """The ``top`` values of ``field`` whose records take the most seconds, with count and sum."""
    groups: dict[str, list[float]] = {}
    for r in records:
        groups.setdefault(r[field], []).append(r["seconds"])
    rows = [{field: k, "count": len(v), "seconds": sum(v)} for k, v in groups.items()]
    return sorted(rows, key=lambda r: -r["seconds"])[:top]


def markdown(s: dict, wall: float, summary_line: str) -> str:
    lines = [f"`python3 -m pytest` with every compilation logged, empty cache: {wall / 60:.1f} min "
             f"wall ({summary_line}; logging slows it a little).", "",
             f"XLA compilations: {s['compilations']}, {s['compile_s']:.0f} s in all (worker "
             f"seconds): {s['big']['count']} of at least {SMALL_S} s take "
             f"{s['big']['seconds']:.0f} s, "
             f"{s['small']['count']} smaller ones (mostly eager operations) "
             f"{s['small']['seconds']:.0f} s; lowering to MLIR {s['lowering_s']:.0f} s; "
             f"persistent-cache hits {s['cache_hits']}.", "",
             "| seconds | program | test |", "|---|---|---|"]
    lines += [f"| {r['seconds']:.1f} | `{r['program']}` | `{r['test']}` |" for r in s["biggest"]]
    for field in ("test", "program"):
        lines += ["", f"Small compilations by {field}:", "", f"| seconds | count | {field} |",
                  "|---|---|---|"]
        lines += [f"| {r['seconds']:.1f} | {r['count']} | `{r[field]}` |"
                  for r in s[f"small_by_{field}"]]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    from benchmarks import _common as common

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(common.RESULTS))
    p.add_argument("pytest_args", nargs="*")
    ns = p.parse_args(argv)
    shutil.rmtree(common.ROOT / ".pytest_cache", ignore_errors=True)
    with tempfile.TemporaryDirectory() as folder:
        env = dict(os.environ, **{LOG_DIR: folder})
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p",
                               "benchmarks.suite_compiles", *ns.pytest_args], cwd=common.ROOT,
                              env=env, text=True, capture_output=True)
        wall = time.perf_counter() - t0
        records = [json.loads(line) for path in Path(folder).glob("*.jsonl")
                   for line in path.read_text().splitlines()]
    tail = proc.stdout.strip().splitlines()
    summary_line = next((line.strip("= ") for line in reversed(tail)
                         if re.search(r"\d+ (passed|failed)", line)), "")
    s = summarise(records)
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    text = markdown(s, wall, summary_line)
    common.write_json(out / "suite_compiles.json",
                      {"benchmark": "suite_compiles", "environment": common.environment(),
                       "wall_s": wall, "summary": summary_line, "returncode": proc.returncode,
                       "pytest_args": ns.pytest_args, **s, "markdown": text})
    (out / "suite_compiles.md").write_text("# Where the default suite's time goes (generated by "
                                           "benchmarks/suite_compiles.py)\n\n" + text)
    print(text)
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
