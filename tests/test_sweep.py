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


def test_vmapped_sweep_equals_the_runs_one_by_one():
    """The two ways a float sweep runs (jaxdobby.sweep): one vmapped batch of simulate(), and
    one value after another through the command line's stored programs (what `jaxdobby
    simulate` reports for each value, compiled once). Same equations, same step count: equal
    to round-off of the batched arithmetic and of the stored programs' LLVM level 0."""
    values = [6.0, 8.0]
    batch = run_sweep(Setup(), "thickness", values, batched=True)
    loop = run_sweep(Setup(), "thickness", values, directory=programs_dir())
    assert loop.steps == batch.steps == 432
    for v, a, b in zip(values, batch.rows, loop.rows):
        s = apply(Setup(), {"thickness": v * PARAMETERS["thickness"].scale})
        single, _, _ = stored_report(s, RunOptions(), directory=programs_dir())
        assert b == single  # the loop is `jaxdobby simulate` value by value
        for key in KEYS:
            np.testing.assert_allclose(a[key], b[key], rtol=1e-9, err_msg=key)
    np.testing.assert_allclose(batch.series[1].deviation, loop.series[1].deviation, rtol=0,
                               atol=1e-9 * float(np.ptp(batch.series[1].deviation)))
    # The source study's trend (thicker arm, smaller deviation) holds.
    assert loop.rows[1]["deviation_pp_mm"] < loop.rows[0]["deviation_pp_mm"]


def test_a_sweep_of_sizes_compiles_them_side_by_side_and_keeps_them_apart():
    """`jaxdobby sweep modes`: each size's programs compile in the background while the next
    is traced (jaxdobby.simulate.compile_reports); every row must still be its own size's run.
    Independent of the plumbing: the arm's own frequencies are eigenvalues of one finite-element
    model, so that of k = 1 is the first of k = 4 (to 1e-9 relative: round-off of eigh), and
    each row lists k of them; and each row is what `jaxdobby simulate --modes k` reports.
    Sizes 1 and 4: the default size's programs are those of every default run of this group of
    test files (tests/conftest.py), compiled once, so that only k = 1 adds a compilation."""
    sizes = [1, 4]
    result = run_sweep(Setup(), "modes", sizes, directory=programs_dir())
    for k, row in zip(sizes, result.rows):
        assert row["n_modes"] == k and len(row["arm_frequencies_hz"]) == k
        s = Setup(machine=Setup().machine.replace(n_modes=k))
        assert row == stored_report(s, RunOptions(), directory=programs_dir())[0]
    np.testing.assert_allclose(result.rows[0]["arm_frequencies_hz"][0],
                               result.rows[1]["arm_frequencies_hz"][0], rtol=1e-9)


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
