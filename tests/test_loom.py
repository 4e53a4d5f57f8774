"""``jaxdobby loom``'s inputs: named weaves, WIF files (read by dtx-to-wif), strokes, and
its one-line errors. Fast: nothing here solves dynamics (the CLI errors come before any
compile); the whole frame set's run is in ``test_weave_slow.py``.

References: the weaves' closed forms (a 2/2 twill's frame i is "1100" started i picks later;
a 5-end satin raises each frame once in five picks and one frame per pick); the four WIF test
files (tests/data/wif) are one 2/2 twill written four ways — lift plan, tie-up + treadling,
sinking shed (complement lists), a header with more shafts than the data — so each must read
as the named twill on 4 frames; the clean-shed rule H_i = H₁·L_i/L₁.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jaxdobby.cli import main
from jaxdobby.errors import InputError
from jaxdobby.weave.loom import clean_shed_strokes
from jaxdobby.weave.named import named_plan
from jaxdobby.weave.plan import moves, parse_plan, shift
from jaxdobby.weave.wif import read_wif

WIF = Path(__file__).parent / "data" / "wif"


def test_named_weaves_closed_forms():
    twill = named_plan("twill22", 8)
    for i in range(8):
        np.testing.assert_array_equal(twill[:, i], shift(parse_plan("1100"), -i))
    satin = named_plan("satin5", 5)
    np.testing.assert_array_equal(satin.sum(axis=0), np.ones(5))
    np.testing.assert_array_equal(satin.sum(axis=1), np.ones(5))
    plain = named_plan("plain", 4)
    assert all(np.all(moves(plain[:, i])) for i in range(4))
    basket = named_plan("basket22", 4)
    np.testing.assert_array_equal(basket[:, 0], basket[:, 1])
    np.testing.assert_array_equal(basket[:, 0], parse_plan("1100"))
    np.testing.assert_array_equal(named_plan("twill31", 4)[:, 0], parse_plan("1110"))


@pytest.mark.parametrize("name", ["twill22_liftplan", "twill22_tieup", "twill22_sinking",
                                  "header_says_8"])
def test_wif_files_read_as_the_twill(name):
    np.testing.assert_array_equal(read_wif(WIF / f"{name}.wif"), named_plan("twill22", 4))


def test_wif_without_a_plan_is_an_input_error():
    with pytest.raises(InputError, match="no \\[LIFTPLAN\\] and no \\[TIEUP\\]"):
        read_wif(WIF / "no_plan.wif")


def test_clean_shed_strokes():
    h = clean_shed_strokes(4, 80.0, 12.0, 250.0)
    np.testing.assert_allclose(h, 80.0 * np.array([250.0, 262.0, 274.0, 286.0]) / 250.0,
                               rtol=1e-15)


@pytest.mark.parametrize("args, words", [
    (["loom", "--weave", "satin5", "--frames", "0"], "--frames"),
    (["loom", str(WIF / "no_plan.wif")], "no [LIFTPLAN]"),
    (["loom", str(WIF / "twill22_tieup.wif"), "--frames", "9"], "has 4 shafts"),
    (["loom", "--weave", "plain", "--frames", "2", "--strokes", "80", "200"],
     "frame 2: stroke 200.0 mm"),
    (["loom", "--weave", "plain", "--strokes", "80"], "--strokes has 1 values for 8 frames"),
    (["loom"], "either a WIF file or --weave"),
    (["simulate", "--lift-plan", "10a1"], "other than 0 and 1"),
    (["loom", "--weave", "plain", "--frames", "2", "--animate", "3"],
     "--animate = 3 is outside the valid range (a frame 1…2)"),
    (["simulate", "--lift-plan", ""], "empty"),
])
def test_bad_input_is_one_line_and_exit_2(args, words, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"jaxdobby {args[0]}: error:") and words in err[-1]


def test_a_frame_row_is_checked_as_a_single_run():
    # a row of run_frames (SI: deviation and stroke in m) gives the warnings warnings_of gives
    # the same numbers as a simulate report: 8 mm of a 140 mm stroke is 5.7 % (> 5 %), the
    # joint's deflection 1.5 % of its radius (> 1 %), converged, no resonance at 800 r/min
    # (mode 1 at 100-110 Hz: harmonics 10·800/120 = 66.7 Hz … 12 → 80 Hz stay below 97 Hz)
    from jaxdobby.validity import warnings_of
    from jaxdobby.weave.loom import frame_warnings

    row = {"deviation_pp": 0.008, "stroke": 0.14, "converged": True, "periodicity": 1e-9,
           "validity.deflection_ratio": 0.015, "validity.reach_margin": 1e-2,
           "validity.sin_transmission": 0.9,
           "validity.frequencies": np.array([[100.0, 4000.0], [110.0, 4400.0]])}
    speed = 800 * np.pi / 30
    got = frame_warnings(row, speed)
    assert [w["code"] for w in got] == ["arm_deflection", "deviation_of_stroke"]
    assert got[1]["value"] == pytest.approx(100 * 0.008 / 0.14, rel=1e-12)
    same = {k: v for k, v in row.items() if k.startswith("validity.")}
    same.update({"converged": True, "periodicity": 1e-9, "stroke": 0.14, "speed": speed,
                 "metric.deviation_pp": 0.008})
    assert got == warnings_of(same)
