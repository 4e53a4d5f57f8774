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


def test_animation_of_a_frame_follows_its_plan(tmp_path):
    """``loom --animate``'s drawing over a plan's repeat (no dynamics: the model alone, the
    arm undeformed): the drawn heald frame at every image is the model's rigid height at
    that time — the crank follows the plan "1100" (at the top through picks 1–2, at the bottom
    through 3–4), not plain weave, to round-off (1e-12 m, closed-form loop closures against
    the model's) — and the GIF has one image per requested frame."""
    from types import SimpleNamespace

    import equinox as eqx
    import jax.numpy as jnp
    from PIL import Image

    from jaxdobby import Machine, OperatingPoint
    from jaxdobby.dobby import build_model
    from jaxdobby.outputs import rigid_outputs
    from jaxdobby.pictures.animation import animate, animation_frames, frame_times
    from jaxdobby.weave.command import FRAMES_PER_PICK, animation_images

    model = eqx.filter_jit(build_model)(Machine.default(n_modes=1), OperatingPoint(), None,
                                        jnp.asarray(parse_plan("1100")))
    n_t = 4 * 864 + 1
    t = np.linspace(0.0, float(model.period), n_t)
    run = SimpleNamespace(model=model, series=SimpleNamespace(
        t=t, modal=np.zeros((n_t, 1)), deviation=np.zeros(n_t)))
    images = 8
    _, rigid, _, _, _, _ = animation_frames(run, images, magnification=1.0)
    times = frame_times(float(model.period), images)
    expected = np.asarray(eqx.filter_jit(rigid_outputs)(model, times)["heald_rigid"])
    np.testing.assert_allclose(np.asarray(rigid.heald_frame)[:, 1], expected, rtol=0,
                               atol=1e-12)
    # x = turns from the middle of pick 4's dwell: "1100" rises in pick 1, holds the top
    # through pick 2 (x from 1 − d/2 to 2 + d/2, d = 100°/360°), falls in pick 3 and holds the
    # bottom through pick 4 (x from 3 − d/2 on)
    x = 4.0 * times / float(model.period)
    top, bottom = expected[(x > 0.9) & (x < 2.1)], expected[x > 2.9]
    assert np.ptp(top) < 1e-12 and np.ptp(bottom) < 1e-12
    assert top[0] == pytest.approx(expected.max(), abs=1e-12)
    # the stroke between the dead centres, to 1e-8 m: the crank dwells half a turn from the
    # bottom dead centre, 0.011° from the top one (kinematics.dead_centres), where the height
    # is stationary (second order in the angle: measured 1e-9 m)
    assert top[0] - bottom[0] == pytest.approx(float(model.stroke), abs=1e-8)
    path = animate(run, tmp_path / "frame.gif", n_frames=images, magnification=1.0)
    with Image.open(path) as im:
        assert im.n_frames == images
    assert animation_images(4) == 4 * FRAMES_PER_PICK and animation_images(100) == 360
