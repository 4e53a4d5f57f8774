"""``jaxdobby sobol`` on the dobby: a small study completes, ranks the parameters as the physics
says, and bad input is refused with a message naming the field.

The ranking reference is the one-at-a-time sweeps (tests/test_sweep.py, notebook 04, and the
source study): over the default box the deviation's peak-to-peak grows ×17 from 400 to
1200 r/min (0.50 → 8.39 mm), changes by −12 % with warp force, ×0.06 from 140 to 80 mm of
stroke and −21 % from 6 to 8 mm thickness, so speed and stroke must dominate it and the warp
force must come last. N = 32 base samples (192 runs): the indices are rough (intervals
~±0.1-0.2) but the gaps asserted are several times larger.
"""

import json

import numpy as np
import pytest

from jaxdobby.cli import main
from jaxdobby.sensitivity import DOBBY, SobolConfig, run_sobol


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sobol")
    return run_sobol(SobolConfig(n=32, seed=3, out=out, chunk_size=64, num_resamples=50))


def test_dobby_is_the_default_model_with_the_source_studys_problem(small_run):
    assert small_run.space.names == ("speed", "warp_force", "stroke", "thickness")
    assert small_run.space.bounds == ((400.0, 1200.0), (345.0, 1035.0), (80.0, 140.0),
                                      (6.0, 8.0))
    assert DOBBY.name == "dobby"


def test_small_dobby_study_completes_and_ranks_the_parameters(small_run):
    ev = small_run.evaluation
    assert ev.outputs["deviation_pp_mm"].shape == (32 * 6,)
    assert np.all(ev.outputs["ok"])
    assert np.all(ev.outputs["deviation_pp_mm"] > 0.0)
    st = small_run.result.metrics["deviation_pp_mm"].ST
    names = list(small_run.space.names)
    order = [names[i] for i in np.argsort(-np.asarray(st))]
    assert set(order[:2]) == {"speed", "stroke"}, order
    assert order[-1] == "warp_force", order
    assert st[names.index("warp_force")] < 0.1


def test_written_indices_and_figures(small_run):
    out = small_run.out
    data = json.loads((out / "indices.json").read_text())
    assert "deviation_pp_mm" in data["metrics"] and "acceleration_amp_m_s2" in data["metrics"]
    assert (out / "indices.csv").read_text().count("\n") > 4
    assert any(p.suffix == ".png" for p in (out / "figures").iterdir())


def test_validity_warnings_name_the_rows_a_single_run_flags(small_run):
    # the per-sample validity outputs are not metrics (no indices) and the rows they flag are
    # those whose machine simulate warns about (the same resonance condition on the same
    # frequencies; the deviation from another solver, equal to ~1e-6): every flagged row and
    # the two fastest unflagged ones, re-run through the command line's stored program
    from jaxdobby.cli import programs_dir
    from jaxdobby.config import RunOptions
    from jaxdobby.parameters import Setup
    from jaxdobby.sensitivity.dobby import setup_of_row
    from jaxdobby.simulate import stored_report_arrays
    from jaxdobby.validity import warnings_of

    data = json.loads((small_run.out / "indices.json").read_text())
    assert not any(k.startswith("validity.") for k in data["metrics"])
    warned = {code: set(w["samples"]) for code, w in data["warnings"].items()}
    assert set(warned) <= {"deviation_of_stroke", "resonance"}  # measured: rows 91, 123 both
    samples = np.load(small_run.out / "outputs.npz")["samples"]
    flagged = sorted(set().union(*warned.values()))
    fastest = [int(i) for i in np.argsort(-samples[:, 0]) if i not in flagged][:2]
    assert flagged and all(samples[i, 0] > 1000.0 for i in flagged)
    for row in flagged + fastest:
        setup, _ = setup_of_row(Setup(), small_run.space.names, small_run.space.si_scales,
                                samples[row])
        arrays = stored_report_arrays(setup, RunOptions(), directory=programs_dir())
        codes = {w["code"] for w in warnings_of({k: np.asarray(v) for k, v in arrays.items()})}
        for code in ("deviation_of_stroke", "resonance"):
            assert (code in codes) == (row in warned.get(code, ())), (row, code, codes)


@pytest.mark.parametrize("text, expected", [
    ("[parameters]\nthickness = [-1, 8]", "parameter 'thickness': bounds must lie in (0.0, inf) "
     "[mm]"),
    ("[parameters]\ndwell = [100, 400]", "parameter 'dwell': bounds must lie in (0.0, 360.0) "
     "[deg]"),
    ("[parameters]\nyoungs_modulus = { bounds = [190, 210], unit = 'GPa' }",
     "parameter 'youngs_modulus': unit must be 'Pa'"),
    ("[parameters]\nheald_frame_mass = [20, 30]\nbogus = [1, 2]", "parameter 'bogus': unknown"),
])
def test_bad_dobby_problem_files_are_refused_by_the_cli(tmp_path, capsys, text, expected):
    problem = tmp_path / "problem.toml"
    problem.write_text(text)
    assert main(["sobol", "--params", str(problem), "--n", "8", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not (tmp_path / "o" / "chunks").exists()


def test_parameters_without_default_bounds_need_bounds(tmp_path, capsys):
    assert main(["sobol", "--params", "speed,heald_frame_mass", "--n", "8", "--out",
                 str(tmp_path / "o")]) == 2
    assert "parameter 'heald_frame_mass': no bounds given" in capsys.readouterr().err


def test_unreachable_stroke_bounds_are_refused_before_running(tmp_path, capsys):
    problem = tmp_path / "problem.toml"
    problem.write_text("[parameters]\nstroke = [60, 200]\n")
    assert main(["sobol", "--params", str(problem), "--n", "8", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "parameter 'stroke': bounds must lie in the reachable range" in err


@pytest.mark.parametrize("argv, expected", [
    (["--steps", "71"], "--steps must be an integer 72…4320 (collocation steps per cycle; "
                        "default 432); got 71"),
    (["--steps", "4321"], "--steps must be an integer 72…4320"),
    (["--model", "ishigami", "--steps", "216"], "--steps: model 'ishigami' has no time steps"),
])
def test_bad_steps_are_refused_before_anything_is_written(tmp_path, capsys, argv, expected):
    assert main(["sobol", *argv, "--n", "8", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_steps_other_than_the_default_key_their_own_stored_program():
    # the default's key is what the shipped program was stored under (tests/test_programs.py)
    from jaxdobby.sensitivity.command import stored_model
    from jaxdobby.sensitivity.space import ParameterSpace

    space = ParameterSpace.from_names(DOBBY.default_names, DOBBY.parameters)
    default = stored_model(DOBBY, space).static_key
    assert stored_model(DOBBY, space, None).static_key == default
    assert stored_model(DOBBY, space, 216).static_key != default
    assert DOBBY.builder(None) is DOBBY.build
    # the default build's steps follow each row's speed: 432 for every row is another build
    assert DOBBY.builder(432) is not DOBBY.build
    assert stored_model(DOBBY, space, 432).static_key != default


def test_default_study_groups_rows_by_their_steps_per_cycle(small_run):
    # jaxdobby.periodic.steady.STEPS_BY_SPEED: 432 steps below 450 r/min, 360 below 650, 288
    # below 1000, 216 from there; a chunk holds rows of one count (padded), and the run says so
    from jaxdobby.sensitivity.batch import chunk_order

    samples = np.load(small_run.out / "outputs.npz")["samples"]
    groups = DOBBY.row_groups(small_run.space, samples)
    speed = samples[:, 0]
    expected = np.select([speed < 450, speed < 650, speed < 1000], [432, 360, 288], 216)
    assert groups.tolist() == expected.tolist() and len(set(groups.tolist())) == 4
    order = chunk_order(groups, 64)
    assert len(order) % 64 == 0 and sorted(set(order.tolist())) == list(range(len(samples)))
    for chunk in order.reshape(-1, 64):
        assert len(set(groups[chunk].tolist())) == 1
    manifest = json.loads((small_run.out / "manifest.json").read_text())
    assert manifest["chunk_order"] == "steps per cycle by speed" and "steps" not in manifest
    assert json.loads((small_run.out / "indices.json").read_text())["run"]["steps"] == "by speed"


@pytest.mark.slow  # ~40 s: compiles the batch at 216 steps
def test_fewer_steps_give_the_default_study_to_the_stated_accuracy(small_run, tmp_path):
    # jaxdobby sobol --steps 216: every metric of these 192 rows within 1e-3 relative of the
    # default's (steps by speed, within 3e-5 of the adaptive reference). The --steps help
    # states 1.3e-3 over the default study's 10 240 rows (the velocity deviation's
    # amplitude; ≤ 1.3e-4 on the others) and 8e-4 at the corners of the box against the
    # adaptive reference (benchmarks/sobol_throughput.py --steps 216 --accuracy)
    run = run_sobol(SobolConfig(n=32, seed=3, out=tmp_path, chunk_size=64, num_resamples=50,
                                steps=216))
    assert json.loads((tmp_path / "manifest.json").read_text())["steps"] == 216
    assert json.loads((tmp_path / "indices.json").read_text())["run"]["steps"] == 216
    fast, ref = run.evaluation.outputs, small_run.evaluation.outputs
    assert np.all(fast["ok"])
    for name in ("deviation_pp_mm", "deviation_max_mm", "deviation_min_mm",
                 "velocity_deviation_amp_m_s", "acceleration_amp_m_s2"):
        np.testing.assert_allclose(fast[name], ref[name], rtol=1e-3, err_msg=name)


@pytest.mark.slow  # ~100 s: a fresh process compiles the dobby batch; the two-process
# equality itself is in the default suite (test_sensitivity_parallel, on the Ishigami model)
def test_dobby_study_joins_jax_distributed_before_building_the_model(tmp_path):
    """Building the dobby (default machine, reachable strokes) runs JAX, which starts the
    backend; jax.distributed must be joined before that or it refuses. A one-process
    coordinator run of a tiny study (N = 4: 24 rows) must therefore complete (it failed with
    "initialize() must be called before any JAX calls" when the model was built first)."""
    import os
    import socket
    import subprocess
    import sys
    from pathlib import Path

    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(root), JAX_PLATFORMS="cpu")
    env.pop("XLA_FLAGS", None)
    p = subprocess.run([sys.executable, "-m", "jaxdobby.sensitivity", "--n", "4", "--no-figures",
                        "--json", "--coordinator", f"localhost:{port}", "--num-processes", "1",
                        "--process-id", "0", "--out", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=300, env=env, check=False)
    assert p.returncode == 0, p.stderr[-2000:]
    assert json.loads(p.stdout)["run"]["processes"] == 1
