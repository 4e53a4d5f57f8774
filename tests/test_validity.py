"""Validity warnings (jaxdobby.validity) and the command line at the edges of the model.

Claims: the transmission angle from the traced closure equals the law of cosines on the
triangle D0–C–P; the deflection ratio equals |Φ_P q|/|p| from the modal coordinates; the
resonance and deviation checks fire exactly where their closed-form conditions say; a speed
outside the supported range is one line and exit 2; a solver failure is one line and exit 1
with nothing on stdout (never a table of nan).
"""

import json
import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import equinox as eqx

from jaxdobby.cli import main, programs_dir
from jaxdobby.config import RunOptions
from jaxdobby.dobby import LINK, build_model, rigid_joint_position
from jaxdobby.parameters import SPEED_RANGE, Setup, apply
from jaxdobby.simulate import simulate, stored_report_arrays, summary, summary_of
from jaxdobby.sensitivity.validity import sample_resonances, sample_warnings
from jaxdobby.validity import (DEFLECTION_LIMIT, DEVIATION_LIMIT, RESONANCE_BAND, failure,
                               tally, tally_lines, warnings_of)


def _report(setup):
    """Report arrays of ``setup`` through the command line's stored program (shared with the
    command-line tests: no tracing of the dynamics once stored; any float values)."""
    arrays = stored_report_arrays(setup, RunOptions(), directory=programs_dir())
    return {k: np.asarray(v) for k, v in arrays.items()}


@pytest.fixture(scope="module")
def default_run():
    """(model, report arrays) of the default run."""
    setup = Setup()
    model = eqx.filter_jit(build_model)(setup.machine, setup.operating)
    return model, _report(setup)


def test_default_machine_is_inside_every_limit(default_run):
    model, arrays = default_run
    # the default machine (DESIGN §6, 800 r/min) is the study's design point: inside every
    # limit of the model's validity; its arm is not a design to build, though (DESIGN §7): the
    # one warning is the fatigue check (Goodman factor 0.84 against the polished-specimen limit)
    codes = [w["code"] for w in summary_of(arrays, model.machine)["warnings"]]
    assert codes == ["fatigue_limit_exceeded"]
    # deflection ratio: |Φ_P q| in the body frame (rotation-free) over |p|, from the modal
    # coordinates rather than the inertial link-point deviation the check uses
    q = arrays["series.modal"]
    rows = np.asarray(model.body.points[LINK])
    ratio = np.max(np.linalg.norm(q @ rows.T, axis=1)) / np.linalg.norm(model.link_joint)
    np.testing.assert_allclose(arrays["validity.deflection_ratio"], ratio, rtol=1e-10)
    assert 0.5 * DEFLECTION_LIMIT < ratio < DEFLECTION_LIMIT  # measured 0.86 %


def test_transmission_angle_is_the_law_of_cosines(default_run):
    model, arrays = default_run
    chain = model.chain
    joint = jax.vmap(lambda t: rigid_joint_position(model, t))(arrays["series.t"])
    joint = np.asarray(joint) + arrays["series.link_point_deviation"]
    # triangle D0 (blade pivot), C (blade pin), P (link-11 joint): sides r_in, L11, |P − D0|
    d = np.linalg.norm(joint - np.asarray(chain.blade_pivot), axis=1)
    r, l11 = float(chain.blade_input_arm), float(chain.link11_length)
    cos_mu = (r**2 + l11**2 - d**2) / (2 * r * l11)
    np.testing.assert_allclose(arrays["validity.sin_transmission"],
                               np.min(np.sqrt(1 - cos_mu**2)), rtol=1e-9)


def _arrays(**changes):
    """Synthetic report arrays inside every limit (speed 800 r/min, f₁ 100…110 Hz)."""
    base = {"converged": np.array(True), "periodicity": np.array(1e-10),
            "validity.deflection_ratio": np.array(0.005), "stroke": np.array(0.14),
            "metric.deviation_pp": np.array(0.002), "validity.reach_margin": np.array(1e-2),
            "validity.sin_transmission": np.array(0.9), "speed": np.array(800 * np.pi / 30),
            "validity.frequencies": np.array([[100.0, 4000.0], [110.0, 4400.0]])}
    return dict(base, **{k: np.asarray(v) for k, v in changes.items()})


def test_resonance_fires_on_the_cycle_harmonics_in_the_band():
    # cycle frequency n/120: harmonic 10 at 1260 r/min is 105 Hz, inside 100…110 Hz
    codes = warnings_of(_arrays(speed=1260 * np.pi / 30))
    assert [w["code"] for w in codes] == ["resonance"]
    assert "harmonic 10" in codes[0]["message"] and codes[0]["value"] == pytest.approx(105.0)
    # 3 % below the band's low end: harmonic 10 at n with 10·n/120 = 100·(1 − 0.03) − 0.1 Hz
    n = 12 * (100 * (1 - RESONANCE_BAND) - 0.1)
    assert all("harmonic 10 (" not in w["message"]
               for w in warnings_of(_arrays(speed=n * np.pi / 30)))
    # an odd cycle harmonic (not a pick harmonic) counts too: harmonic 11 at 1200 r/min = 110 Hz
    assert any("harmonic 11 (110.0 Hz)" in w["message"]
               for w in warnings_of(_arrays(speed=1200 * np.pi / 30)))


def test_limits_fire_at_their_thresholds():
    assert warnings_of(_arrays()) == []
    just = {"validity.deflection_ratio": 1.01 * DEFLECTION_LIMIT,
            "metric.deviation_pp": 1.01 * DEVIATION_LIMIT * 0.14,
            "validity.sin_transmission": math.sin(math.radians(19.0)),
            "converged": False, "periodicity": 1e-3}
    got = {w["code"]: w for w in warnings_of(_arrays(**just))}
    assert set(got) == {"arm_deflection", "deviation_of_stroke", "transmission_angle",
                        "not_converged"}
    assert got["deviation_of_stroke"]["value"] == pytest.approx(5.05)
    assert got["transmission_angle"]["value"] == pytest.approx(19.0)
    assert warnings_of(_arrays(**{"validity.reach_margin": -1e-6}))[0]["code"] == "workspace"


def test_failure_names_the_non_finite_numbers():
    assert failure({"deviation_pp_mm": 1.0, "natural_frequencies_hz": [1.0]}) is None
    reason = failure({"deviation_pp_mm": math.nan, "natural_frequencies_hz": [1.0],
                      "newton_iterations": 9})
    assert "deviation_pp_mm" in reason and "\n" not in reason


def run_cli(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("speed", ["1e-3", "99", "1801", "3000"])
def test_speed_outside_the_supported_range_is_refused(capsys, speed):
    code, out, err = run_cli(capsys, "simulate", "--speed", speed)
    assert code == 2 and out == ""
    assert err.strip().splitlines() == [
        f"jaxdobby simulate: error: --speed = {float(speed):g} r/min is outside the valid range "
        f"(>= {SPEED_RANGE[0]:g} and <= {SPEED_RANGE[1]:g} r/min)"]


def test_solver_failure_is_one_line_and_exit_1(capsys):
    # a warp force of 1 MN (1450× the default) makes the shooting diverge (measured: NaN)
    code, out, err = run_cli(capsys, "simulate", "--warp-force", "1e6", "--json")
    assert code == 1 and out == "" and "nan" not in err.lower()
    lines = [line for line in err.strip().splitlines() if not line.startswith("solving")]
    assert len(lines) == 1 and "solver failed" in lines[0], err


def test_thin_arm_warns_in_json_and_text(capsys):
    code, out, _ = run_cli(capsys, "simulate", "--thickness", "1", "--json")
    s = json.loads(out)
    assert code == 0 and s["converged"]
    got = {w["code"]: w for w in s["warnings"]}
    assert {"arm_deflection", "deviation_of_stroke"} <= set(got)
    # the deviation's share of the stroke from the same summary's numbers
    assert got["deviation_of_stroke"]["value"] == pytest.approx(
        100 * s["deviation_pp_mm"] / s["stroke_mm"], rel=1e-12)
    assert all(set(w) == {"code", "message", "value", "limit"} for w in s["warnings"])
    code, out, _ = run_cli(capsys, "simulate", "--thickness", "1")
    assert "warning [arm_deflection]" in out and not re.search(r"\bnan\b", out)


@pytest.mark.slow
@pytest.mark.parametrize("thickness", [3.0, 6.0, 8.0])
@pytest.mark.parametrize("speed", SPEED_RANGE)
def test_the_supported_speed_range_converges(speed, thickness):
    """The ends of the supported range converge for thin to thick arms (README, Limits)."""
    setup = apply(Setup(), {"speed": speed * np.pi / 30, "thickness": thickness * 1e-3})
    run = simulate(setup.machine, setup.operating)
    s = summary(run)
    assert s["converged"] and failure(s) is None, (speed, thickness, s["periodicity_residual"])
    assert np.all(jnp.isfinite(run.series.heald_flexible))


def test_tally_counts_each_run_once_per_code_and_names_it():
    res = {"code": "resonance"}
    runs = [("400", []), ("1200", [res, res, {"code": "arm_deflection"}]), ("2000", [res])]
    counts = tally(runs)
    # CODES order (arm_deflection before resonance); two resonant harmonics are one run
    assert list(counts) == ["arm_deflection", "resonance"]
    assert counts["resonance"] == {"count": 2, "samples": ["1200", "2000"]}
    assert tally_lines(counts, 3).splitlines()[1] == "  warning [resonance]: 2 of 3 runs: 1200, 2000"


def test_sobol_sample_warnings_name_the_rows_of_every_check():
    # the stress model's validity outputs: row 0 inside every limit, each other row fails one
    # check just past its limit (1 %, 20°, yield ratio 1, Goodman 1), row 7 failed unconverged,
    # row 8 failed although converged (the chain left its reach: workspace)
    names, n = ("speed",), 9
    base = {"deviation_pp_mm": np.full(n, 3.0), "ok": np.ones(n, bool),
            "validity.converged": np.ones(n), "validity.deflection_ratio": np.full(n, 0.005),
            "validity.reach_margin": np.full(n, 1e-2), "validity.resonances": np.zeros(n),
            "validity.sin_transmission": np.full(n, 0.9), "validity.yield_ratio": np.full(n, 0.5),
            "fatigue_safety_factor": np.full(n, 1.5)}
    changes = {1: ("validity.deflection_ratio", 1.01 * DEFLECTION_LIMIT),
               2: ("validity.reach_margin", -1e-6),
               3: ("validity.sin_transmission", math.sin(math.radians(19.9))),
               4: ("validity.resonances", 2.0), 5: ("validity.yield_ratio", 1.001),
               6: ("fatigue_safety_factor", 0.999)}
    for row, (key, value) in changes.items():
        base[key][row] = value
    base["ok"][7:] = False
    base["validity.converged"][7] = 0.0
    base["deviation_pp_mm"][7] = np.nan
    got = sample_warnings(names, np.zeros((n, 1)), base, stroke_mm=140.0)
    assert {code: w["samples"] for code, w in got.items()} == {
        "not_converged": [7], "arm_deflection": [1], "workspace": [2, 8],
        "transmission_angle": [3], "resonance": [4], "yield_exceeded": [5],
        "fatigue_limit_exceeded": [6]}
    # the limits in the units of the single run's warnings (%, °, ratio)
    assert got["arm_deflection"]["limit"] == 100 * DEFLECTION_LIMIT
    assert got["transmission_angle"]["limit"] == 20.0


def test_a_batch_counts_the_resonances_of_the_single_run_check():
    # the batch evaluator's per-sample count (sequential assembly under vmap, frequencies at 24
    # phases) against the resonance warnings simulate reports for the same machine: 800 r/min
    # none, 1200 r/min harmonics 11 and 12 on mode 1, a 3 mm arm harmonic 12 (README, Limits)
    setups = [Setup(), apply(Setup(), {"speed": 1200 * np.pi / 30}),
              apply(Setup(), {"thickness": 3e-3})]
    expected = [sum(w["code"] == "resonance" for w in warnings_of(_report(s))) for s in setups]
    assert expected == [0, 2, 1]
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *setups)
    counts = eqx.filter_jit(jax.vmap(sample_resonances))(batch)
    np.testing.assert_array_equal(np.asarray(counts), expected)


def test_sobol_sample_warnings_name_the_rows():
    # rows: stroke sampled (third column); deviation 7.5 mm is 5.4 % of 140 mm, 3 mm is 2.1 %
    names = ("speed", "warp_force", "stroke", "thickness")
    samples = np.array([[800, 690, 140, 6], [1200, 690, 140, 6], [1200, 690, 80, 6],
                        [400, 690, 140, 6]], dtype=float)
    outputs = {"deviation_pp_mm": np.array([3.0, 7.5, 3.0, np.nan]),
               "ok": np.array([True, True, True, False])}
    got = sample_warnings(names, samples, outputs, stroke_mm=140.0)
    assert got["deviation_of_stroke"]["samples"] == [1]  # 3/80 = 3.75 % is inside
    assert got["not_converged"] == {"count": 1, "samples": [3], "limit": None}
    assert sample_warnings(names, samples, {"y": np.zeros(4)}, 140.0) == {}


def test_optimize_checks_its_designs_as_simulate_does(capsys):
    # jaxdobby optimize reports, per speed, the warnings simulate gives the design it wrote
    # (design.toml: the collocation solver, 432 steps): here a 1 mm "optimum" from the default
    from jaxdobby.optimize.command import _validity_text
    from jaxdobby.optimize.study import design_warnings, speeds_from_rpm

    summary = {"per_speed": [{"speed_rpm": 800.0, "start": {}, "optimised": {}}]}
    design_warnings(summary, Setup(), apply(Setup(), {"thickness": 1e-3}),
                    speeds_from_rpm([800.0]), 432, directory=programs_dir())
    code, out, _ = run_cli(capsys, "simulate", "--thickness", "1", "--json")
    expected = json.loads(out)["warnings"]
    got = summary["per_speed"][0]["optimised"]["warnings"]
    assert [w["code"] for w in got] == [w["code"] for w in expected]
    assert {"arm_deflection", "deviation_of_stroke"} <= {w["code"] for w in got}
    # the same run up to the speed's last bit (r/min to rad/s by two formulas)
    for a, b in zip(got, expected):
        assert a["value"] == pytest.approx(b["value"], rel=1e-9)
    assert [w["code"] for w in summary["per_speed"][0]["start"]["warnings"]] == [
        "fatigue_limit_exceeded"]  # the default machine's one (test above)
    assert all(set(w) == {"code", "message", "value", "limit"}
               and w["message"].startswith("at 800 r/min: ") for w in summary["warnings"])
    text = _validity_text(summary)
    assert "warning [arm_deflection]: at 800 r/min:" in text
    assert "starting design's: fatigue_limit_exceeded" in text
