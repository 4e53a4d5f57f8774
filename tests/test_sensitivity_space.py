"""Parameter spaces, problem files and the checks on them.

References: SALib's problem-dict contract and row counts (SALib docs, ``sobol.sample``: N(2D+2)
rows with second order, N(D+2) without); the dobby's default problem is DESIGN.md §6 ("Sobol
intervals"). Error tests assert that the message names the field and the valid range, as
issue 4 asks: a test passes only on that message, not on any ValueError.
"""

import math

import numpy as np
import pytest

from jaxdobby.sensitivity import (DOBBY_PARAMETERS, ISHIGAMI, ParameterSpace, SobolConfig,
                                  check_base_samples, main)
from jaxdobby.sensitivity.command import build_space


def write(tmp_path, text, name="problem.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_default_dobby_problem_is_design_table():
    names = ["speed", "warp_force", "stroke", "thickness"]
    space = ParameterSpace.from_names(names, DOBBY_PARAMETERS)
    assert space.problem == {"num_vars": 4, "names": names, "bounds": [
        [400.0, 1200.0], [345.0, 1035.0], [80.0, 140.0], [6.0, 8.0]]}
    assert space.units == ("r/min", "N", "mm", "mm")
    # Users' units → SI at the boundary: 600 r/min = 20π rad/s, 100 mm = 0.1 m, 7 mm = 0.007 m.
    si = space.to_si(np.array([600.0, 690.0, 100.0, 7.0]))
    np.testing.assert_allclose([si["speed"], si["warp_force"], si["stroke"], si["thickness"]],
                               [20 * math.pi, 690.0, 0.1, 0.007], rtol=1e-15)


@pytest.mark.parametrize("second_order, rows", [(True, 2 * 3 + 2), (False, 3 + 2)])
def test_sample_matrix_shape_and_bounds(second_order, rows):
    space = ParameterSpace.from_names(["x1", "x2", "x3"], ISHIGAMI.parameters)
    x = space.sample(64, second_order=second_order, seed=5)
    assert x.shape == (64 * rows, 3) and x.dtype == np.float64
    assert np.all(x >= -math.pi) and np.all(x <= math.pi)
    # Rows come grouped by base sample j as [A_j, AB_j^1..AB_j^D, (BA_j^1..BA_j^D), B_j], where
    # AB_j^i is A_j with column i from B_j (Saltelli 2002): the layout SALib's analyze reads and
    # the 'drop' failure policy relies on (it drops whole groups).
    g = x.reshape(64, rows, 3)
    a, b = g[:, 0], g[:, -1]
    for i in range(3):
        expected = a.copy()
        expected[:, i] = b[:, i]
        np.testing.assert_array_equal(g[:, 1 + i], expected)
    # Same seed, same design (resume relies on it); another seed, another design.
    np.testing.assert_array_equal(x, space.sample(64, second_order=second_order, seed=5))
    assert not np.array_equal(x, space.sample(64, second_order=second_order, seed=6))


def test_toml_problem_subset_in_file_order(tmp_path):
    path = write(tmp_path, """
[parameters]
thickness = [6.5, 7.5]
speed = { bounds = [500, 900], unit = "r/min" }
""")
    space = ParameterSpace.from_toml(path, DOBBY_PARAMETERS)
    assert space.names == ("thickness", "speed")
    assert space.bounds == ((6.5, 7.5), (500.0, 900.0))
    assert space.units == ("mm", "r/min")
    assert build_space(SobolConfig(params=str(path)), _dobby_spec()).names == ("thickness", "speed")
    space = build_space(SobolConfig(params="stroke, speed"), _dobby_spec())
    assert space.names == ("stroke", "speed")


def _dobby_spec():
    from jaxdobby.sensitivity import ModelSpec

    return ModelSpec("dobby", DOBBY_PARAMETERS, tuple(DOBBY_PARAMETERS), build=None)


@pytest.mark.parametrize("text, expected", [
    ("[parameters\nspeed = [1, 2]", "not valid TOML"),
    ("[parameters]\nspeedd = [400, 1200]", "parameter 'speedd': unknown name; valid names are "
     "['arc_angle', 'arc_radius', 'blade_inertia',"),
    ("[parameters]\nspeed = [1200, 400]", "parameter 'speed': lower bound must be < upper bound "
     "[r/min]; got [1200.0, 400.0]"),
    ("[parameters]\nstroke = [80, 80]",
     "parameter 'stroke': lower bound must be < upper bound [mm]"),
    ("[parameters]\nspeed = [400, inf]",
     "parameter 'speed': bounds must be finite numbers [r/min]"),
    ("[parameters]\nspeed = [nan, 1200]", "parameter 'speed': bounds must be finite numbers"),
    ("[parameters]\nspeed = [-100, 1200]",
     "parameter 'speed': bounds must lie in (100.0, 1800.0) [r/min]"),
    ("[parameters]\nspeed = [400]",
     "parameter 'speed': bounds must be two numbers [lower, upper] [r/min]"),
    ("[parameters]\nspeed = ['a', 'b']", "parameter 'speed': bounds must be two numbers"),
    ("[parameters]\nspeed = { bounds = [400, 1200], unit = 'rad/s' }",
     "parameter 'speed': unit must be 'r/min' (bounds are not converted); got 'rad/s'"),
    ("[parameters]\nspeed = { bound = [400, 1200] }",
     "parameter 'speed': unknown key(s) ['bound']"),
    ("speed = [400, 1200]", "unknown top-level key(s) ['speed']"),
    ("[parameters]", "needs a non-empty [parameters] table"),
])
def test_bad_problem_files(tmp_path, text, expected):
    with pytest.raises(ValueError) as e:
        ParameterSpace.from_toml(write(tmp_path, text), DOBBY_PARAMETERS)
    assert expected in str(e.value)


@pytest.mark.parametrize("n", [0, 1, 3, 1000, 1023, -4, 2.0, True, "8"])
def test_base_samples_must_be_power_of_two(n):
    with pytest.raises(ValueError, match=r"n \(base samples\) must be a power of two >= 2"):
        check_base_samples(n)


def test_good_base_samples():
    assert [check_base_samples(n) for n in (2, 4, 1024, np.int64(4096))] == [2, 4, 1024, 4096]


def test_unknown_and_duplicate_names():
    with pytest.raises(ValueError, match=r"parameter 'x4': unknown name; valid names are \['x1'"):
        ParameterSpace.from_names(["x1", "x4"], ISHIGAMI.parameters)
    with pytest.raises(ValueError, match="names must be unique"):
        ParameterSpace.from_names(["x1", "x1"], ISHIGAMI.parameters)
    with pytest.raises(ValueError, match="params: empty name"):
        build_space(SobolConfig(params="x1,,x2"), ISHIGAMI)


def test_cli_reports_bad_input_without_traceback(tmp_path, capsys):
    bad = write(tmp_path, "[parameters]\nx1 = [1, -1]")
    assert main(["--model", "ishigami", "--params", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jaxdobby sobol: error: parameter 'x1': lower bound must be < upper")
    assert "Traceback" not in err
    assert main(["--model", "ishigami", "--n", "1000", "--out", str(tmp_path / "o")]) == 2
    assert "must be a power of two" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing written for a refused run


@pytest.mark.parametrize("args, expected", [
    (["--chunk-size", "-5"], "chunk_size must be a positive multiple of the device count"),
    (["--devices", "0"], "local device(s); got 0"),
    (["--conf-level", "1.5"], "conf_level must be in (0, 1); got 1.5"),
    (["--coordinator", "localhost:1"],
     "--coordinator, --num-processes and --process-id go together"),
])
def test_cli_refuses_bad_run_settings_before_writing(tmp_path, capsys, args, expected):
    out = tmp_path / "o"
    assert main(["--model", "ishigami", "--out", str(out), *args]) == 2
    assert expected in capsys.readouterr().err
    assert not out.exists()
