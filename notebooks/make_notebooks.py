"""Build the notebooks from their diffable sources and execute them.

Each ``src/NN_name.py`` is a Python script split into cells by ``# %%`` lines (``# %% [markdown]``
for text cells, whose lines start with ``# ``). This script turns each into ``NN_name.ipynb``
and executes it with nbclient, so the committed notebooks show their figures to a reader who
does not run them.

    python notebooks/make_notebooks.py            # all, full size
    python notebooks/make_notebooks.py 02 --quick # one, reduced size (as the tests do)
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

HERE = Path(__file__).resolve().parent


def cells_from_source(text: str) -> list:
    cells, kind, lines = [], None, []

    def flush():
        body = "\n".join(lines).strip("\n")
        if kind is None or not body:
            return
        if kind == "markdown":
            body = "\n".join(line[2:] if line.startswith("# ") else line.lstrip("#")
                             for line in body.splitlines())
            cells.append(nbformat.v4.new_markdown_cell(body))
        else:
            cells.append(nbformat.v4.new_code_cell(body))

    for line in text.splitlines():
        if line.startswith("# %%"):
            flush()
            kind, lines = ("markdown" if "[markdown]" in line else "code"), []
        else:
            lines.append(line)
    flush()
    return cells


def without_compiler_alarms(nb) -> None:
    """Drop XLA's "Very slow compile?" alarms (C++ log lines on stderr, not the notebook's
    output) from the executed cells, so the committed notebook shows what it computes."""
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        kept = []
        for out in cell.get("outputs", []):
            if out.get("output_type") == "stream" and out.get("name") == "stderr":
                text = out["text"]
                if "slow_operation_alarm" in text or "Very slow compile?" in text:
                    lines = [ln for ln in text.splitlines() if not (
                        "slow_operation_alarm" in ln or "Very slow compile?" in ln
                        or ln.strip("*").strip() == "" and ln.strip())]
                    text = "\n".join(ln for ln in lines if ln.strip()) + "\n"
                    if not text.strip():
                        continue
                    out["text"] = text
            kept.append(out)
        cell.outputs = kept


def build(source: Path, execute: bool = True, quick: bool = False, timeout: int = 1800) -> Path:
    nb = nbformat.v4.new_notebook()
    nb.cells = cells_from_source(source.read_text(encoding="utf-8"))
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    target = HERE / f"{source.stem}.ipynb"
    if execute:
        # The kernel inherits the environment: the size flag, and this checkout's package first
        # on the path (a relative PYTHONPATH would resolve against notebooks/, the kernel's
        # directory, and an installed jaxdobby could be another checkout's).
        path = os.pathsep.join([str(HERE.parent)] + [p for p in os.environ.get(
            "PYTHONPATH", "").split(os.pathsep) if p and p != "."])
        env = {"JAXDOBBY_NOTEBOOK_QUICK": "1" if quick else "0", "PYTHONPATH": path}
        before = {k: os.environ.get(k) for k in env}
        os.environ.update(env)
        try:
            NotebookClient(nb, timeout=timeout, kernel_name="python3",
                           resources={"metadata": {"path": str(HERE)}}).execute()
            without_compiler_alarms(nb)
        finally:
            for k, v in before.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
    return target, nb


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("which", nargs="*", help="notebook numbers (default: all)")
    parser.add_argument("--quick", action="store_true", help="reduced size")
    parser.add_argument("--no-execute", action="store_true")
    ns = parser.parse_args(argv)
    for source in sorted((HERE / "src").glob("*.py")):
        if ns.which and not any(source.stem.startswith(w) for w in ns.which):
            continue
        target, nb = build(source, execute=not ns.no_execute, quick=ns.quick)
        nbformat.write(nb, target)
        print(f"wrote {target.relative_to(HERE.parent)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
