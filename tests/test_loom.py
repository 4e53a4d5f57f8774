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

