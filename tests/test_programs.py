"""Stored programs (jaxdobby.programs): what the command line runs through them is what
simulate computes, and the package's shipped programs of the default configuration are
current."""

import jax
import numpy as np
import pytest

from jaxdobby import programs
from jaxdobby.config import RunOptions
from jaxdobby.parameters import Setup
from jaxdobby.sensitivity.command import default_study_program
from jaxdobby.simulate import report_programs, simulate, stored_report, summary


@pytest.fixture(scope="module")
def default_setup():
    return Setup()


def test_shipped_program_of_the_default_configuration_is_current(default_setup):
    """The first `jaxdobby simulate` with an empty cache skips tracing only if the package ships
    the default configuration's program for the current sources (their fingerprint is part of
    its key). After a change of jaxdobby's code: `python -m jaxdobby.programs` makes it anew."""
    (name, run, args, static_key), (report_name, _, report_key) = report_programs(
        default_setup, RunOptions())
    # the report's arguments are the run's outputs (read from the shipped run program, or
    # traced anew if it is stale)
    leaves = [jax.ShapeDtypeStruct(a.shape, a.dtype) for a in programs.stored_program(
        name, run, args, static_key=static_key, directory=None).out_avals]
    _, sobol, share = default_study_program()
    for key in (programs.program_key(name, static_key, args),
                programs.program_key(report_name, report_key, leaves),
                programs.program_key(sobol.name, sobol.static_key, [share])):
        assert (programs.SHIPPED / key).exists(), (
            f"the shipped program {key} is stale: run `python -m jaxdobby.programs` and "
            "commit jaxdobby/data/programs")
    assert len(list(programs.SHIPPED.glob("*.jaxexport"))) == 3


def test_stored_report_equals_simulate_and_is_reused(tmp_path, default_setup, monkeypatch):
    """stored_report (an exported program, stored, then read back by a second call with other
    float values) against simulate() and summary() run directly on the same inputs: the same
    computation, but the stored program is compiled at LLVM level 0 (programs.ONE_SHOT) and
    simulate at JAX's default level, which round differently (fused multiply-adds); the periodic
    solve amplifies round-off of its 432-step cycle map by ‖(I − Φ)⁻¹‖, so equal to 1e-10
    relative (measured ≤ 1.0e-12). A stale key (other
    sources) must not find the stored file."""
    monkeypatch.setattr(programs, "SHIPPED", tmp_path / "shipped")  # none shipped
    first, _, _ = stored_report(default_setup, RunOptions(), directory=tmp_path)
    stored = sorted(tmp_path.glob("*.jaxexport"))
    assert len(stored) == 2  # the run and its report
    slower = Setup(operating=default_setup.operating.__class__.from_users_units(speed_rpm=600.0))
    got, series, stress = stored_report(slower, RunOptions(), directory=tmp_path)
    assert sorted(tmp_path.glob("*.jaxexport")) == stored  # read back, not exported anew
    run = simulate(slower.machine, slower.operating)
    want = summary(run)
    for key, value in want.items():
        if key == "periodicity_residual":
            # ‖F(x) − x‖/‖x‖ ≈ 5e-11 is itself near round-off: F is 432 collocation steps, whose
            # rounding (≈ 432 × 2.2e-16 ≈ 1e-13 of ‖x‖, amplified by the cycle's response)
            # differs between the two compilations (measured 1.2e-13)
            assert got[key] == pytest.approx(value, rel=0, abs=1e-12), key
        elif isinstance(value, float) or (isinstance(value, list) and value
                                         and all(isinstance(v, float) for v in value)):
            assert got[key] == pytest.approx(value, rel=1e-10, abs=1e-300), key
        elif key == "warnings":  # (code, message, value, limit): values to round-off
            assert [w["code"] for w in got[key]] == [w["code"] for w in value]
            for a, b in zip(got[key], value):
                assert a["value"] == pytest.approx(b["value"], rel=1e-10), a["code"]
        else:
            assert got[key] == value, key
    np.testing.assert_allclose(series.deviation, run.series.deviation, rtol=0,
                               atol=1e-10 * float(np.ptp(run.series.deviation)))
    assert float(stress.metrics["stress_max"]) * 1e-6 == pytest.approx(got["stress_max_mpa"])
    assert first["speed_rpm"] == pytest.approx(800.0) and got["speed_rpm"] == pytest.approx(600.0)
    (name, _, args, static_key), _ = report_programs(slower, RunOptions())
    assert programs.program_key(name, static_key + " changed", args) not in {
        p.name for p in stored}


def test_a_program_with_host_callbacks_runs_unstored(tmp_path):
    """jax.export does not serialise host callbacks (diffrax's adaptive solver has them:
    `jaxdobby simulate --method adaptive`): such a program is traced and compiled in every run,
    not stored, and gives what the function gives."""
    seen = []

    def fn(x):
        jax.debug.callback(lambda v: seen.append(float(v)), x[0])
        return [2.0 * x, x.sum()]

    x = jax.numpy.arange(3.0)
    got = programs.stored_program("callback", fn, [x], static_key="", directory=tmp_path)
    assert isinstance(got, programs.Unstored) and not list(tmp_path.iterdir())
    assert [(a.shape, a.dtype) for a in got.out_avals] == [((3,), x.dtype), ((), x.dtype)]
    (compiled,) = programs.compile_together([(got, [x])])
    doubled, total = compiled(x)
    np.testing.assert_array_equal(np.asarray(doubled), [0.0, 2.0, 4.0])
    assert float(total) == 3.0 and seen == [0.0]
