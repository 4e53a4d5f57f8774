"""Wall time of the default test suite as CI runs it: ``python3 -m pytest`` from a clean
state — no XLA cache (the tests' cache folder ``.pytest_cache/xla`` removed first), nothing
else running — recorded in ``results/suite_time.json``.

Run:  python benchmarks/suite_time.py [--out benchmarks/results] [-- extra pytest arguments]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/suite_time.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common as common


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(common.RESULTS))
    p.add_argument("pytest_args", nargs="*")
    ns = p.parse_args(argv)
    shutil.rmtree(common.ROOT / ".pytest_cache", ignore_errors=True)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "--durations=15",
                           *ns.pytest_args], cwd=common.ROOT, text=True, capture_output=True)
    wall = time.perf_counter() - t0
    tail = proc.stdout.strip().splitlines()
    summary = next((line.strip("= ") for line in reversed(tail)
                    if re.search(r"\d+ (passed|failed)", line)), "")
    slowest = [line for line in tail if re.match(r"^\d+\.\d+s (call|setup)", line)]
    result = {"benchmark": "suite_time", "environment": common.environment(), "wall_s": wall,
              "summary": summary, "returncode": proc.returncode,
              "markdown": (f"`python3 -m pytest` (default suite, `-n 2`, empty XLA cache): "
                           f"**{wall / 60:.1f} min** wall, {summary}.\n\nSlowest:\n\n"
                           + "\n".join(f"    {line}" for line in slowest[:15]))}
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "suite_time.json").write_text(json.dumps(result, indent=1))
    print(result["markdown"])
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
