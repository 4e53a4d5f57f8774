"""The notebooks run at a reduced size (JAXDOBBY_NOTEBOOK_QUICK=1) and assert the numbers they
show (their assert cells). 01 and 02 run in the default suite; the sweeps of 03-06 and the
fit of 08 take minutes and run with ``-m slow``."""

import sys
from pathlib import Path

import pytest

NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"
sys.path.insert(0, str(NOTEBOOKS))

from make_notebooks import build  # noqa: E402

FAST = ["01_bending_arm", "02_one_cycle"]
SLOW = ["03_modal_truncation", "04_parameters", "05_sobol", "06_design", "07_weave",
        "08_identify"]


def run(name):
    source = NOTEBOOKS / "src" / f"{name}.py"
    if not source.exists():
        pytest.skip(f"{name} not written yet")
    build(source, execute=True, quick=True)  # raises CellExecutionError if an assert fails


@pytest.mark.parametrize("name", FAST)
def test_notebook(name):
    run(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW)
def test_notebook_slow(name):
    run(name)
