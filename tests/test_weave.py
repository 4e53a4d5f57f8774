"""Lift plans (DESIGN.md §7): the modulator's law per pick, the per-pick metrics, and the
steady state over a repeat.

Claims and references:

* the plan "10" is the plain weave: the crank angle to 1e-12 rad and, through the whole
  steady-state run, every metric and the time series to round-off (1e-12 relative: the same
  grid and equations, the crank angle differing in its last bits);
* the law itself: no crank motion in a pick without a move, a half turn in a pick with one,
  the frame at the top dead centre exactly in the picks with b_k = 1;
* a plan and its shift by k picks are the same periodic motion started k picks later: the
  repeat's metrics agree to the shooting tolerance (1e-6 relative periodicity → 1e-6 relative
  on the metrics; measured ~1e-9) and the per-pick ones are the same, rotated by k;
* vmapped frames (different plans and strokes) equal the single runs (1e-10 relative: the same
  program, batched);
* the per-pick metrics of a synthetic series equal their closed form.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby import Machine, OperatingPoint
from jaxdobby.errors import InputError
from jaxdobby.modulator import crank_angle, plan_period
from jaxdobby.simulate import simulate
from jaxdobby.weave.metrics import pick_metrics, pick_of
from jaxdobby.weave.plan import is_static, parse_plan, shift

SPEED = 2.0 * math.pi * 800.0 / 60.0
DWELL = math.radians(100.0)


def test_plan_10_is_the_plain_weave_law():
    t = jnp.linspace(-0.2, 0.5, 20001)
    plain = crank_angle(t, SPEED, dwell=DWELL, start_angle=0.3)
    plan = crank_angle(t, SPEED, dwell=DWELL, start_angle=0.3, plan=jnp.array([1.0, 0.0]))
    assert float(jnp.max(jnp.abs(plain - plan))) < 1e-12


def test_crank_turns_only_in_picks_with_a_move():
    plan = jnp.array([1.0, 1.0, 1.0, 0.0, 1.0, 0.0])  # moves in picks 0, 3, 4, 5
    pick = 2.0 * math.pi / SPEED
    x = jnp.linspace(0.0, 6.0, 6 * 720 + 1)  # main-shaft turns over the repeat
    t = x * pick
    phi = crank_angle(t, SPEED, dwell=DWELL, plan=plan)
    rate = jax.vmap(jax.grad(lambda tt: crank_angle(tt, SPEED, dwell=DWELL, plan=plan)))(t)
    d = DWELL / (2.0 * math.pi)
    k = pick_of(t, plan_period(SPEED, 6), 6, DWELL)
    moving = np.asarray(plan != jnp.roll(plan, 1))[np.asarray(k)]
    assert float(jnp.max(jnp.abs(rate[~moving]))) == 0.0  # dwells through the pick
    assert float(jnp.min(rate[moving & (np.abs(np.asarray(x) - np.round(np.asarray(x))) > d)])) > 0
    # at shed-open of pick k (x = k + 1) the eccentric is at the top (φ₀ + π) iff b_k = 1
    shed = crank_angle((jnp.arange(6) + 1.0) * pick, SPEED, dwell=DWELL, plan=plan)
    up = np.round(np.asarray(shed) / math.pi) % 2
    assert np.array_equal(up, np.asarray(plan))
    assert float(phi[-1] - phi[0]) == pytest.approx(4.0 * math.pi, abs=1e-12)  # 4 moves


def test_parse_plan_and_its_errors():
    assert np.array_equal(parse_plan("1100"), [1.0, 1.0, 0.0, 0.0])
    assert is_static(parse_plan("111")) and not is_static(parse_plan("10"))
    assert np.array_equal(shift(parse_plan("1100"), 1), [1.0, 0.0, 0.0, 1.0])
    for bad, words in (("", "empty"), ("1021", "other than 0 and 1")):
        with pytest.raises(InputError, match=words):
            parse_plan(bad)
    # one pick, or no change: a frame that never moves, the static case
    assert all(is_static(parse_plan(p)) for p in ("1", "0", "11", "000"))


class _Series:
    def __init__(self, t, deviation):
        self.t, self.deviation = t, deviation


def test_pick_metrics_of_a_synthetic_repeat():
    """Deviation 0.1·(k+1) + sin(2π·5x)·(k+1)/1000 in pick k's dwell, a ramp away from the
    dwell's edges in the indexes (0.5 per turn: one index sample taken into a dwell would add
    ≥ 5.8e-4, caught by the tolerance):
    the dwell vibration of pick k is 2·(k+1)/1000 (the dwell holds 5·100/360 ≈ 1.4 periods),
    the shed-open deviation 0.1·(k+1)."""
    picks, n = 4, 4 * 864
    period = plan_period(SPEED, picks)
    t = jnp.linspace(0.0, period, n + 1)
    x = picks * t / period
    centre = jnp.round(x)
    owner = jnp.mod(centre - 1, picks)
    in_dwell = jnp.abs(x - centre) <= 0.5 * DWELL / (2 * math.pi)
    dwell_value = 0.1 * (owner + 1) + jnp.sin(2 * math.pi * 5 * x) * (owner + 1) / 1000
    ramp = 0.1 * (owner + 1) + 0.5 * (jnp.abs(x - centre) - 0.5 * DWELL / (2 * math.pi))
    dev = jnp.where(in_dwell, dwell_value, ramp)
    out = pick_metrics(_Series(t, dev), jnp.array([1.0, 1.0, 0.0, 0.0]), DWELL)
    k = np.arange(picks) + 1.0
    np.testing.assert_allclose(out["shed_deviation"], 0.1 * k, atol=1e-12)
    np.testing.assert_allclose(out["dwell_vibration"], 2e-3 * k, rtol=1e-4)  # sampling of a sine
    assert float(out["dwell_vibration_max"]) == pytest.approx(8e-3, rel=1e-4)
    np.testing.assert_array_equal(out["moves"], [1.0, 0.0, 1.0, 0.0])


# -- steady states over a repeat (two modes: small programs; the claims hold for any) -------
MACHINE = Machine.default().replace(n_modes=2)
OPERATING = OperatingPoint.from_users_units(speed_rpm=1000.0)
COMPARED = ("deviation_pp", "deviation_max", "deviation_min", "acceleration_amp",
            "velocity_deviation_amp", "link11_force_max", "ring_link_force_max")


@pytest.fixture(scope="module")
def runs():  # four compiled programs, ~40-70 s each on a loaded 2-core machine: slow tests
    return {plan: simulate(MACHINE, OPERATING, lift_plan=plan)
            for plan in (None, "10", "1100", "0110")}


@pytest.mark.slow
def test_plan_10_reproduces_the_plain_weave_run(runs):
    plain, ten = runs[None], runs["10"]
    assert bool(plain.converged) and bool(ten.converged)
    for key in plain.metrics:
        assert float(ten.metrics[key]) == pytest.approx(float(plain.metrics[key]), rel=1e-12,
                                                        abs=1e-15), key
    np.testing.assert_allclose(ten.series.deviation, plain.series.deviation, rtol=0, atol=1e-15)


@pytest.mark.slow
def test_a_shifted_plan_gives_the_same_repeat(runs):
    a, b = runs["1100"], runs["0110"]  # "0110" is "1100" started one pick earlier
    assert bool(a.converged) and bool(b.converged)
    for key in COMPARED:
        assert float(b.metrics[key]) == pytest.approx(float(a.metrics[key]), rel=1e-6), key
    np.testing.assert_allclose(np.roll(b.pick_metrics["dwell_vibration"], -1),
                               a.pick_metrics["dwell_vibration"], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(np.roll(b.pick_metrics["shed_deviation"], -1),
                               a.pick_metrics["shed_deviation"], rtol=1e-5, atol=1e-10)
    # a twill's repeat differs from plain weave's: dwell picks without a move exist
    np.testing.assert_array_equal(a.pick_metrics["moves"], [1.0, 0.0, 1.0, 0.0])


@pytest.mark.slow
def test_vmapped_frames_equal_single_runs(runs):
    plans = jnp.array([parse_plan("1100"), parse_plan("0110")])
    strokes = jnp.array([0.13, 0.12])

    def one(plan, stroke):
        run = simulate(MACHINE.with_stroke(stroke), OPERATING, lift_plan=plan)
        return run.metrics, run.pick_metrics

    metrics, picks = jax.vmap(one)(plans, strokes)
    for j, (plan, stroke) in enumerate((("1100", 0.13), ("0110", 0.12))):
        single = simulate(MACHINE.with_stroke(stroke), OPERATING, lift_plan=plan)
        for key in COMPARED:
            assert float(metrics[key][j]) == pytest.approx(float(single.metrics[key]),
                                                           rel=1e-10), (plan, key)
        np.testing.assert_allclose(picks["dwell_vibration"][j],
                                   single.pick_metrics["dwell_vibration"], rtol=1e-10)
