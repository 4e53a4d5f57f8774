"""Property-based robustness of the configuration loader and the command line (hypothesis).

Claims, over random inputs:

* loader: a value inside a parameter's registered range is accepted and read back exactly
  (scale round trip to 1e-12; the stroke, solved by Newton for the joint position, to 1e-6 mm),
  or refused with an :class:`InputError` (a geometry that does not close); a value outside it,
  a non-number or an unknown key is an ``InputError`` naming ``[section] key``; nothing else is
  ever raised. No dynamics run (milliseconds per example).
* command line: a valid operating point (speed, warp force, thickness, stroke in the ranges the
  source study explores and beyond) exits 0 with finite numbers, or 1 with a finite table and a
  ``not_converged`` warning, or 1 with the one-line solver failure — never a NaN on stdout; an
  invalid flag value exits 2 with one line naming the flag. The runs reuse one stored program
  (same static configuration, float values vary), so each costs a fraction of a second.
"""

import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxdobby.cli import main
from jaxdobby.config import from_mapping
from jaxdobby.errors import InputError
from jaxdobby.parameters import PARAMETERS, SPEED_RANGE

SCALARS = [p for p in PARAMETERS.values() if p.name not in ("depth", "depth_positions")]


def _inside(p):
    """Floats inside the parameter's valid range (finite, capped at 1e6 of its unit)."""
    low, high = p.limits
    lo, hi = max(low, -1e6), min(high, 1e6)
    return st.floats(min_value=lo, max_value=hi, exclude_min=lo == low and not p.low_closed,
                     exclude_max=hi == high and not p.high_closed, allow_nan=False)


def _outside(p):
    low, high = p.limits
    bad = [st.just(math.nan), st.just(math.inf), st.just(-math.inf), st.text(max_size=3),
           st.booleans()]
    if math.isfinite(low):
        bad.append(st.floats(max_value=low, exclude_max=p.low_closed, allow_nan=False,
                             allow_infinity=False, min_value=-1e9))
    if math.isfinite(high):
        bad.append(st.floats(min_value=high, exclude_min=p.high_closed, allow_nan=False,
                             allow_infinity=False, max_value=1e9))
    return st.one_of(bad)


@st.composite
def valid_entry(draw):
    p = draw(st.sampled_from(SCALARS))
    return p, draw(_inside(p))


@st.composite
def invalid_entry(draw):
    p = draw(st.sampled_from(SCALARS))
    return p, draw(_outside(p))


@settings(max_examples=60, deadline=None)
@given(valid_entry())
def test_loader_reads_back_valid_values_or_names_the_field(entry):
    p, value = entry
    try:
        setup, _ = from_mapping({p.section: {p.key: value}})
    except InputError as err:  # a valid number whose geometry does not close
        assert "\n" not in str(err)
        return
    got = float(p.get(setup)) / p.scale
    tol = 1e-6 if p.name == "stroke" else 1e-12 * max(1.0, abs(value))
    assert abs(got - value) <= tol, (p.name, value, got)


@settings(max_examples=60, deadline=None)
@given(invalid_entry())
def test_loader_refuses_invalid_values_naming_the_field(entry):
    p, value = entry
    with pytest.raises(InputError) as err:
        from_mapping({p.section: {p.key: value}})
    assert f"[{p.section}] {p.key}" in str(err.value) and "\n" not in str(err.value)


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(sorted({p.section for p in SCALARS})),
       st.text(alphabet="abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12))
def test_loader_refuses_unknown_keys_naming_them(section, key):
    if any(p.section == section and p.key == key for p in PARAMETERS.values()):
        return
    try:
        from_mapping({section: {key: 1.0}})
    except InputError as err:
        assert key in str(err)
    else:  # an option key of the section (model/solver), not a parameter
        assert section in ("model", "solver")


def _run(capsys, args):
    code = main(["simulate", *args])
    out, err = capsys.readouterr()
    return code, out, err


CLI = settings(max_examples=6, deadline=None, derandomize=True,
               suppress_health_check=[HealthCheck.function_scoped_fixture])


@CLI
@given(speed=st.floats(*SPEED_RANGE), warp=st.floats(0.0, 5000.0), thickness=st.floats(2.0, 10.0),
       stroke=st.floats(80.0, 140.0))
def test_cli_valid_inputs_give_finite_numbers_or_a_named_failure(capsys, speed, warp, thickness,
                                                                stroke):
    code, out, err = _run(capsys, ["--speed", repr(speed), "--warp-force", repr(warp),
                                   "--thickness", repr(thickness), "--stroke", repr(stroke),
                                   "--json"])
    assert "Traceback" not in err
    if out == "":  # the solver failed: one line, exit 1
        lines = [x for x in err.splitlines() if not x.startswith("solving")]
        assert code == 1 and len(lines) == 1 and "solver failed" in lines[0]
        return
    s = json.loads(out)
    numbers = [v for v in s.values() if isinstance(v, float)]
    numbers += [f for v in s.values() if isinstance(v, list) for f in v if isinstance(f, float)]
    assert all(math.isfinite(v) for v in numbers)
    codes = {w["code"] for w in s["warnings"]}
    assert code == (0 if s["converged"] else 1)
    assert s["converged"] or "not_converged" in codes


FLAGS = {"--speed": PARAMETERS["speed"], "--warp-force": PARAMETERS["warp_force"],
         "--thickness": PARAMETERS["thickness"]}


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(sorted(FLAGS)), st.data())
def test_cli_invalid_values_exit_2_naming_the_flag(capsys, flag, data):
    p = FLAGS[flag]
    value = data.draw(_outside(p).filter(lambda v: not isinstance(v, (bool, str))))
    code, out, err = _run(capsys, [flag, repr(value)])
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and flag in lines[0] and "valid range" in lines[0], err


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.integers(-100, 100).filter(lambda k: not 1 <= k <= 30))
def test_cli_invalid_modes_exit_2(capsys, modes):
    code, _, err = _run(capsys, ["--modes", str(modes)])
    assert code == 2 and "--modes" in err and len(err.strip().splitlines()) == 1
