"""``jaxdobby sweep``: a vmapped batch equals the runs one by one; files and table."""

import json

import numpy as np
import pytest

from jaxdobby.cli import main
from jaxdobby.command_line import programs_dir
from jaxdobby.config import RunOptions
from jaxdobby.parameters import PARAMETERS, Setup, apply
from jaxdobby.simulate import stored_report
from jaxdobby.sweep import run_sweep

KEYS = ("deviation_pp_mm", "deviation_min_mm", "deviation_max_mm", "acceleration_amp_m_s2",
        "stress_max_mpa", "fatigue_safety_factor")


def test_vmapped_sweep_equals_single_runs():
    values = [6.0, 8.0]
    result = run_sweep(Setup(), "thickness", values)
    for v, row in zip(values, result.rows):
        s = apply(Setup(), {"thickness": v * PARAMETERS["thickness"].scale})
        # the single run as `jaxdobby simulate` reports it (the command line's stored program:
        # simulate() and summary() in one program, held to them in test_programs.py)
        single, _, _ = stored_report(s, RunOptions(steps=result.steps), directory=programs_dir())
        # Same equations, same step count (the sweep uses the most demanding value's): equal
        # to round-off of the batched arithmetic (and of the stored program's LLVM level 0).
        for key in KEYS:
            np.testing.assert_allclose(row[key], single[key], rtol=1e-9, err_msg=key)
    # The source study's trend (thicker arm, smaller deviation) holds.
    assert result.rows[1]["deviation_pp_mm"] < result.rows[0]["deviation_pp_mm"]


def test_sweep_command_writes_table_and_figures(tmp_path, capsys):
    code = main(["sweep", "thickness", "--values", "6", "8", "--out", str(tmp_path), "--json"])
    assert code == 0
    rows = json.loads(capsys.readouterr().out)["runs"]
    assert [r["thickness_mm"] for r in rows] == pytest.approx([6.0, 8.0])
    md = (tmp_path / "sweep.md").read_text()
    assert md.startswith("| thickness [mm] |") and md.count("\n") == 4
    assert (tmp_path / "sweep.csv").read_text().count("\n") == 3
    for name in ("sweep_deviation", "sweep_trends", "sweep_acceleration_flexible"):
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000


@pytest.mark.parametrize("args, text", [
    (["sweep", "thickness", "--values", "6", "-1"], "thickness = -1 mm is outside"),
    (["sweep", "modes", "--values", "0"], "modes = 0 is outside"),
    (["sweep", "stroke", "--values", "150"], "reachable range"),
    (["sweep", "colour", "--values", "1"], "unknown sweep parameter 'colour'"),
])
def test_sweep_bad_input(args, text, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert text in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
