"""Design optimisation on the full model: gradients against finite differences, vmap against a
loop, the thickness and depth studies, and the CLI round trip to ``simulate --config``.

All slow (each gradient compiles for 2-5 minutes on 2 cores and costs 10-60 s): run with
``pytest -m slow tests/test_optimize_studies.py``.
"""

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby import Machine, OperatingPoint, simulate
from jaxdobby.arm import ArmDesign
from jaxdobby.cli import main
from jaxdobby.optimize import Constraints, DesignSpace, Objective, Settings
from jaxdobby.optimize.objective import batch_values, cycle_values
from jaxdobby.optimize.study import Study, run_study
from jaxdobby.parameters import Setup

pytestmark = pytest.mark.slow
RPM = math.pi / 30.0
STEPS = 432  # collocation steps per cycle (the optimiser's default, jaxdobby.periodic.DEFAULT_STEPS)


def _vertex(x, i):
    """Vertex of the parabola through samples i − 1, i, i + 1 of a periodic series (the last
    sample repeats the first): the refined extreme of jaxdobby.metrics.extremes at a fixed i."""
    y = x[:-1]
    a, b, c = y[i - 1], y[i], y[(i + 1) % y.shape[0]]
    return b - (a - c) ** 2 / (8.0 * (a - 2.0 * b + c))


def metric_vector(space, u, steps, peaks=None, reverse_only=False):
    """Every steady-state metric the optimiser can use, at 800 r/min (scaled to order 1).

    The true peak-to-peak (refined max − min over the cycle's samples) is only piecewise
    smooth: its derivative is that of the refined values at the extreme samples, and a central
    difference straddling a change of those samples is not a derivative. With
    ``peaks = (i_max, i_min)`` the peak-to-peak is taken at those fixed samples instead (the
    smooth piece).
    """
    v = cycle_values(space, u, 800.0 * RPM, steps, reverse_only)
    dev = v["deviation_series"]
    pp = v["deviation_pp"] if peaks is None else _vertex(dev, peaks[0]) - _vertex(dev, peaks[1])
    metrics = jnp.stack([1e3 * v["deviation"], 1e3 * pp, 1e4 * v["deviation_rms"],
                         v["acceleration"] / 1e3])
    return metrics, jnp.stack([jnp.argmax(dev[:-1]), jnp.argmin(dev[:-1])])


def test_gradients_match_finite_differences_for_every_design_variable():
    # Every kind of variable at once; stroke 120 mm so that the arc radius can move.
    base = Setup(machine=Machine.default().with_stroke(0.120))
    space = DesignSpace.create(base, ["thickness", "depth", "arc_radius", "heald_frame_mass"],
                               bounds={"arc_radius": (300.0, 600.0)})
    steps = STEPS
    u0 = space.initial + 0.05  # off the default point (depths 43 mm, t = 6.2 mm, ...)
    fn = lambda u: metric_vector(space, u, steps)[0]
    fwd = np.asarray(jax.jit(jax.jacfwd(fn))(u0))
    rev = np.asarray(jax.jit(jax.jacrev(fn))(u0))
    # the optimiser's reverse mode: one pullback of the recorded pass for the whole steady
    # cycle (jaxdobby.periodic.dense._steady_reverse) instead of jax.lax.custom_root's
    rev_only = np.asarray(jax.jit(jax.jacrev(
        lambda u: metric_vector(space, u, steps, reverse_only=True)[0]))(u0))
    value = jax.jit(lambda u, peaks: metric_vector(space, u, steps, peaks))
    _, peaks = value(u0, jnp.zeros(2, dtype=int))
    h = 1e-4
    plus = [value(u0.at[i].add(h), peaks) for i in range(space.size)]
    minus = [value(u0.at[i].add(-h), peaks) for i in range(space.size)]
    fd = np.stack([np.asarray(p[0] - m[0]) / (2 * h) for p, m in zip(plus, minus)], axis=1)
    # For the record (pytest -rA): where the extreme samples move within ±h.
    print("extreme samples at u0:", np.asarray(peaks).tolist(), "at u0 ± h:",
          [(np.asarray(p[1]).tolist(), np.asarray(m[1]).tolist()) for p, m in zip(plus, minus)])
    # Forward and reverse mode are the same derivative computed two ways: round-off.
    np.testing.assert_allclose(rev, fwd, rtol=1e-8, atol=1e-9 * np.abs(fwd).max())
    np.testing.assert_allclose(rev_only, fwd, rtol=1e-8, atol=1e-9 * np.abs(fwd).max())
    # Central differences at h = 1e-4 of each variable's range: truncation ~h² ~1e-8 of the
    # curvature; the periodic state is converged to 1e-9, so the values carry ~1e-9 relative
    # noise, ~1e-5 after dividing by 2h. Per row (metric), 1e-4 of its largest entry. The
    # peak-to-peak (row 1) is differenced at the extreme samples of u0 (see metric_vector):
    # differencing max − min itself, the depth at 80 mm came out 1.5e-3 off (-2.19044 against
    # the derivative's -2.18717), the two sides of a change of the extreme sample.
    for row in range(fwd.shape[0]):
        np.testing.assert_allclose(fwd[row], fd[row], rtol=1e-4,
                                   atol=1e-4 * np.abs(fd[row]).max(), err_msg=f"metric {row}")


def test_vmap_of_the_gradient_equals_a_loop():
    space = DesignSpace.create(Setup(), ["thickness", "heald_frame_mass"])
    speeds = jnp.array([800.0, 1000.0, 1200.0]) * RPM

    def metric(u, w):
        return cycle_values(space, u, w, STEPS)["deviation"]

    grad = jax.jit(jax.jacfwd(metric))
    batched = jax.jit(jax.vmap(jax.jacfwd(metric), in_axes=(None, 0)))(space.initial, speeds)
    loop = np.stack([grad(space.initial, w) for w in speeds])
    # Same arithmetic batched or not: agreement to round-off.
    np.testing.assert_allclose(batched, loop, rtol=1e-10, atol=1e-14)
    # And the batch of values the objective uses is the same vmap: lanes are independent, but
    # XLA orders the sums of batched contractions differently (measured 3e-12 relative after
    # the shooting, as the batch evaluator's 4e-14 per cycle in test_batch.py), so 1e-10.
    values = jax.jit(lambda u: batch_values(space, u, speeds, STEPS))(space.initial)
    np.testing.assert_allclose(values["deviation"],
                               [metric(space.initial, w) for w in speeds], rtol=1e-10)


def test_deviation_against_thickness_falls_but_not_monotonically():
    """Our model: the deviation falls with t overall (−21 % from 6 to 8 mm at 800 r/min), but
    narrow resonance peaks stand on that trend wherever the first coupled frequency meets a
    harmonic of the heald-frame cycle (6.67 Hz at 800 r/min): e.g. t = 6.2 mm, f₁ = 108 Hz."""
    op = OperatingPoint.from_users_units(speed_rpm=800.0)
    pp, f1 = {}, {}
    for t in (6.0, 6.2, 6.4, 8.0):
        run = simulate(Machine.default(arm=ArmDesign(thickness=t * 1e-3)), op, steps=STEPS)
        pp[t], f1[t] = float(run.metrics["deviation_pp"]), float(run.natural_frequencies[0])
    assert pp[8.0] < 0.85 * pp[6.0]  # measured 2.146 vs 2.709 mm
    assert pp[6.2] > 1.05 * pp[6.0] and pp[6.2] > 1.1 * pp[6.4]  # 2.914 vs 2.709, 2.593 mm
    assert abs(f1[6.2] / (800.0 / 120.0) - 16.2) < 0.1  # 107.95 Hz = 16.19 × 6.67 Hz


def thickness_study(limits, steps=12, starts=1):
    space = DesignSpace.create(Setup(), ["thickness"])
    return run_study(Study(space=space, objective=Objective(), limits=limits,
                           settings=Settings(optimizer="lbfgs", steps=steps, tolerance=1e-6),
                           steps=STEPS, starts=starts))


def test_thickness_alone_goes_to_the_upper_bound():
    # From 6 mm the gradient stops in a local minimum (7.15 mm, deviation 2.344 mm): a
    # resonance of the frame-on-arm mode with a harmonic of the pick rate raises the deviation
    # around 7.35 mm (see the test above). A batched scan of 10 starting thicknesses (the given
    # 6 mm, then 4, 4.5, …, 8 mm over the default bounds; one vmapped solve) picks the basin of
    # the bound, and the optimiser ends exactly on it with the gradient pointing outwards.
    local = thickness_study(Constraints()).summary
    assert 7.0 < local["optimised"]["design"]["thickness_mm"] < 7.3
    assert local["converged"] and local["optimality"]["projected_gradient"] < 1e-5
    out = thickness_study(Constraints(), starts=10)
    s = out.summary
    assert s["optimised"]["design"]["thickness_mm"] == 8.0  # exactly on the bound (projection)
    assert s["optimality"]["projected_gradient"] == 0.0  # and the gradient points outwards
    assert out.result.history[-1].values["deviation_pp"][0] < 0.8 * 2.709e-3


def test_thickness_with_a_mass_budget_stops_where_it_binds():
    budget = 0.48  # kg: binds at t = 6 mm × 0.48/0.42304 = 6.808 mm (8 mm would be 0.564 kg)
    out = thickness_study(Constraints(mass_budget=budget), steps=30)
    s = out.summary
    t_bind = 6.0 * budget / s["start"]["arm_mass_kg"]
    assert s["optimised"]["design"]["thickness_mm"] == pytest.approx(t_bind, abs=2e-3)
    assert s["optimised"]["arm_mass_kg"] <= budget * (1 + 1e-4)
    assert s["multipliers"]["mass"] > 0.0  # the budget is active
    assert s["optimality"]["projected_gradient"] < 1e-3 * s["optimality"]["objective_gradient"] \
        + 1e-6


def test_depth_profile_with_mass_budget_beats_the_uniform_arm_of_equal_mass(tmp_path):
    """5 control depths (20-80 mm), thickness 6 mm, mass ≤ the default uniform 40 mm arm's."""
    uniform_mass = float(ArmDesign().mass())
    space = DesignSpace.create(Setup(), ["depth"])
    out = run_study(Study(space=space, objective=Objective(),
                          limits=Constraints(mass_budget=uniform_mass),
                          settings=Settings(optimizer="lbfgs", steps=40, tolerance=1e-4)))
    s = out.summary
    o = s["optimality"]
    # Optimality: feasible, stationary on the box with the mass multiplier (the reduced gradient,
    # of the model simulate runs: each design on its own modes).
    assert o["violation"] < 1e-4
    assert o["projected_gradient"] < 1e-2 * o["objective_gradient"]
    # The optimised profile beats the uniform arm of equal mass (the start) on the modal model
    # (measured: 20.7/64.4/38.1/20/20 mm at 0.4230 kg, 2.709 → 1.700 mm, −37.2 %, KKT with
    # |pg| 2e-5 after 7 iterations), with the budget binding (its multiplier positive).
    start = s["per_speed"][0]["start"]["deviation_pp_mm"]
    best = s["per_speed"][0]["optimised"]["deviation_pp_mm"]
    assert best < 0.8 * start
    assert s["multipliers"]["mass"] > 0.0
    assert s["optimised"]["arm_mass_kg"] == pytest.approx(uniform_mass, rel=1e-9)
    (tmp_path / "result.json").write_text(json.dumps(s, indent=2))


def test_cli_design_reruns_with_simulate_config(tmp_path, capsys):
    out = tmp_path / "opt"
    rc = main(["optimize", "--vars", "thickness", "--speeds", "800", "--steps", "3",
               "--mass-budget", "0.5", "--out", str(out), "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    for name in ("history.csv", "history.json", "result.json", "design.toml", "history.png",
                 "depth_profile.png", "deviation.png"):
        assert (out / name).stat().st_size > 0
    reported = summary["per_speed"][0]["optimised"]["deviation_pp_mm"]
    assert main(["simulate", "--config", str(out / "design.toml"), "--json"]) == 0
    rerun = json.loads(capsys.readouterr().out)
    # Same model (the design on its own modes), same RK4 steps (written in [solver]); the
    # periodic states differ only within the shooting tolerances (1e-9 here, 1e-6 relative
    # periodicity in simulate), so the peak-to-peak agrees to ~1e-6 relative or better.
    assert rerun["deviation_pp_mm"] == pytest.approx(reported, rel=1e-5)
    # the optimised design carries the validity warnings simulate gives it (same codes)
    assert ([w["code"] for w in summary["per_speed"][0]["optimised"]["warnings"]]
            == [w["code"] for w in rerun["warnings"]])
    assert [w["code"] for w in summary["warnings"]] == [w["code"] for w in rerun["warnings"]]
    assert rerun["thickness_mm"] == pytest.approx(summary["optimised"]["design"]["thickness_mm"],
                                                  rel=1e-12)
