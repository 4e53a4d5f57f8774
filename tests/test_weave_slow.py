"""Slow claims of lift plans (each compiles a steady-state program over a repeat).

* **Dwell decay.** In a long dwell the crank stands still: the mechanism is a frozen linear
  system about its static deflection, and the deviation rings down at its first mode's rate.
  Reference: the eigenvalues of the equations of :mod:`jaxdobby.dobby` (the adaptive path's
  vector field, autodiff kinematics — not the collocation code that produced the run)
  linearised about the static equilibrium in that dwell. The run's decay rate σ (regression of
  the log of successive peak-to-peak half-swings) and damped frequency (spacing of the
  extremes) must match to 0.5 % and 0.1 % (sampling: ~105 samples per period, an extreme
  located to a sample, but the regression runs over ~60 half-swings; measured < 3e-4 and 1e-4).
  The coupled first mode's damping ratio is not the arm's 2 %: the chain adds inertia and no
  damping, so it is σ/|λ| ≈ 0.23 % on the default machine (asserted in (0, 2 %]).
* **Gradients through a plan** against central finite differences (h = 1e-4 relative,
  periodicity tolerance 1e-11: truncation ~1e-8, shooting noise ~1e-11/1e-4 = 1e-7 → 1e-5
  relative).
* ``jaxdobby simulate --lift-plan`` and ``jaxdobby loom`` end to end (``--animate`` too).
* The RK4 and adaptive paths take a plan as the default collocation path does.
* A plan that never moves is the static deflection (full-FE statics), with a moving plan's
  summary keys, and differentiable.
"""

from __future__ import annotations

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby import Machine, OperatingPoint
from jaxdobby.cli import main
from jaxdobby.dobby import vector_field
from jaxdobby.simulate import simulate

pytestmark = pytest.mark.slow


def _frozen_eigenvalues(model, t):
    """Eigenvalues of the equations linearised about the static equilibrium at time t (a
    dwell: the rigid motion at rest)."""
    k = model.n_modes

    def accel(q, v):
        return vector_field(t, (q, v), model)[1]

    q = jnp.zeros(k)
    for _ in range(8):  # Newton on the static equilibrium a(q, 0) = 0
        q = q - jnp.linalg.solve(jax.jacfwd(accel)(q, jnp.zeros(k)), accel(q, jnp.zeros(k)))
    a_q = jax.jacfwd(accel, argnums=0)(q, jnp.zeros(k))
    a_v = jax.jacfwd(accel, argnums=1)(q, jnp.zeros(k))
    state = jnp.block([[jnp.zeros((k, k)), jnp.eye(k)], [a_q, a_v]])
    return np.linalg.eigvals(np.asarray(state))


def test_long_dwell_rings_down_at_the_first_modes_rate():
    plan = "10000000"  # up for one pick, then down and still for six picks
    run = simulate(Machine.default(), OperatingPoint.from_users_units(speed_rpm=800.0),
                   lift_plan=plan)
    assert bool(run.converged)
    t, dev = np.asarray(run.series.t), np.asarray(run.series.deviation)
    picks = len(plan)
    x = picks * t / t[-1]
    window = (x > 2.5) & (x < 6.5)  # the frame still since x = 2 − d/2 ≈ 1.86
    ts, ys = t[window], dev[window]
    inner = (ys[1:-1] - ys[:-2]) * (ys[2:] - ys[1:-1]) < 0  # slope changes sign: an extreme
    idx = np.nonzero(inner)[0] + 1
    swing = np.abs(np.diff(ys[idx]))  # successive peak-to-peak half-swings
    mid = 0.5 * (ts[idx][1:] + ts[idx][:-1])
    keep = swing > 1e-4 * swing[0]
    sigma = -np.polyfit(mid[keep], np.log(swing[keep]), 1)[0]
    f_damped = 1.0 / (2.0 * np.mean(np.diff(ts[idx])))
    lam = _frozen_eigenvalues(run.model, 5.0 * t[-1] / picks)
    osc = lam[lam.imag > 1.0]
    first = osc[np.argmin(osc.imag)]
    sigma_ref, f_ref = -first.real, first.imag / (2.0 * math.pi)
    zeta = sigma_ref / abs(first)
    print(f"dwell decay: sigma {sigma:.3f} 1/s (frozen linearisation {sigma_ref:.3f}), "
          f"f {f_damped:.2f} Hz ({f_ref:.2f}), effective damping ratio {zeta:.4f}; "
          f"{int(keep.sum())} half-swings")
    assert sigma == pytest.approx(sigma_ref, rel=0.005)
    assert f_damped == pytest.approx(f_ref, rel=0.001)
    # the arm's modal damping is 2 %: the coupled first mode's ratio is 2 % of the arm's
    # share of its energy, below 2 % (the chain adds inertia, no damping)
    assert 0.0 < zeta <= 0.02


def test_gradient_through_a_plan_matches_finite_differences():
    machine = Machine.default().replace(n_modes=2)
    plan = jnp.array([1.0, 1.0, 1.0, 0.0])

    def metric(p):
        op = OperatingPoint(speed=p[0], warp_force=p[1])
        run = simulate(machine, op, lift_plan=plan, tolerance=1e-11)
        return run.metrics["deviation_rms"]

    p0 = jnp.array([2.0 * math.pi * 1000.0 / 60.0, 690.0])
    grad = jax.grad(metric)(p0)
    h = 1e-4 * p0
    fd = np.array([(metric(p0.at[i].add(h[i])) - metric(p0.at[i].add(-h[i]))) / (2 * h[i])
                   for i in range(2)])
    print("gradient", np.asarray(grad), "finite differences", fd)
    np.testing.assert_allclose(grad, fd, rtol=1e-5)


def test_simulate_cli_with_a_lift_plan(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("JAXDOBBY_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "run"
    assert main(["simulate", "--lift-plan", "1100", "--json", "--out", str(out),
                 "--no-figures"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["lift_plan"] == "1100" and summary["picks"] == 4
    assert len(summary["dwell_vibration_pp_mm"]) == 4
    assert summary["dwell_vibration_max_mm"] == pytest.approx(max(summary["dwell_vibration_pp_mm"]))
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[1] == "pick"
    picks = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1, usecols=1)
    assert set(picks.astype(int)) == {1, 2, 3, 4}
    # 216 steps per pick, 4 outputs per step: 864 rows per pick (+ the end point)
    assert picks.shape == (4 * 864 + 1,)


def test_loom_cli_named_weave(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("JAXDOBBY_CACHE_DIR", str(tmp_path / "cache"))
    # a 2 mm arm at strokes near the default's: outside the small-deformation limits (arm
    # deflection ~2.5 %, a resonance of mode 1 at 67-75 Hz), so the warnings are there
    assert main(["loom", "--weave", "satin5", "--frames", "3", "--modes", "2", "--json",
                 "--thickness", "2", "--strokes", "130", "135", "140",
                 "--out", str(tmp_path)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert [f["lift_plan"] for f in result["frames"]] == ["10000", "00100", "00001"]
    assert result["picks"] == 5
    for name in ("loom.json", "frames.csv", "lift_plan.png", "deviation.png"):
        assert (tmp_path / name).exists()
    # each frame carries the validity warnings simulate gives the same frame (plan, stroke,
    # modes; the stress checks are simulate's alone: the loom's batch computes no stress)
    front = result["frames"][0]
    assert main(["simulate", "--lift-plan", front["lift_plan"], "--modes", "2", "--stroke",
                 repr(front["stroke_mm"]), "--thickness", "2", "--json"]) == 0
    single = json.loads(capsys.readouterr().out)
    stress_codes = {"yield_exceeded", "fatigue_limit_exceeded"}
    expected = [w for w in single["warnings"] if w["code"] not in stress_codes]
    assert [w["code"] for w in front["warnings"]] == [w["code"] for w in expected]
    assert {"arm_deflection", "resonance"} <= {w["code"] for w in expected}
    for a, b in zip(front["warnings"], expected):
        assert a["value"] == pytest.approx(b["value"], rel=1e-6)
    tallied = {code: e["samples"] for code, e in result["warnings"].items()}
    for f in result["frames"]:
        for code in {w["code"] for w in f["warnings"]}:
            assert f["frame"] in tallied[code]


TWO_MODES = Machine.default().replace(n_modes=2)
AT_1000 = OperatingPoint.from_users_units(speed_rpm=1000.0)


@pytest.fixture(scope="module")
def collocation_1100():
    return simulate(TWO_MODES, AT_1000, lift_plan="1100")


def test_rk4_takes_a_plan_as_collocation_does(collocation_1100):
    """The RK4 path reads the same modulator law through the model: its repeat agrees with the
    collocation path's (the two integrators of the plain weave agree to ~1e-4 on these
    metrics at their default steps; tests/test_dobby.py)."""
    machine, operating, col = TWO_MODES, AT_1000, collocation_1100
    rk4 = simulate(machine, operating, lift_plan="1100", method="rk4")
    assert bool(col.converged) and bool(rk4.converged)
    for key in ("deviation_pp", "deviation_max", "deviation_min", "acceleration_amp"):
        assert float(rk4.metrics[key]) == pytest.approx(float(col.metrics[key]), rel=1e-3), key
    np.testing.assert_allclose(rk4.pick_metrics["dwell_vibration"],
                               col.pick_metrics["dwell_vibration"], rtol=1e-2, atol=1e-7)


def test_adaptive_reference_takes_a_plan_as_collocation_does(collocation_1100):
    """The adaptive reference (Tsit5, rtol 1e-8, its own shooting) on the plan "1100" against
    the default collocation path (order 6, 216 steps per pick), on the same output grid
    (n_out = 864 per pick + 1: the per-pick dwell masks pick the same times). Plain weave's
    two paths agree to ≤ 1e-6 relative on every metric (tests/test_dobby.py, tolerance 1e-5):
    the same here, per pick the same rate of error on each pick's dwell vibration and
    shed-open deviation, taken relative to the repeat's deviation peak to peak (the dwell
    vibration of a dwell pick is small, its own relative error larger)."""
    col = collocation_1100
    ref = simulate(TWO_MODES, AT_1000, lift_plan="1100", method="adaptive",
                   n_out=col.series.t.shape[0])
    assert bool(col.converged) and bool(ref.converged)
    np.testing.assert_allclose(ref.series.t, col.series.t, rtol=1e-14, atol=0)
    for key in col.metrics:
        assert float(ref.metrics[key]) == pytest.approx(float(col.metrics[key]), rel=1e-5), key
    scale = 1e-5 * float(col.metrics["deviation_pp"])
    for key in ("dwell_vibration", "shed_deviation"):
        diff = np.abs(np.asarray(ref.pick_metrics[key]) - np.asarray(col.pick_metrics[key]))
        print(key, np.asarray(col.pick_metrics[key]), "max difference", diff.max(),
              "of the deviation pp", diff.max() / float(col.metrics["deviation_pp"]))
        np.testing.assert_allclose(ref.pick_metrics[key], col.pick_metrics[key], rtol=0,
                                   atol=scale)


def test_a_frame_that_never_moves_is_the_static_deflection():
    """Plans "1" and "0" (and "000": any that never moves) are static: the rigid mechanism
    stands still at the top or bottom of the stroke, and the run is the equilibrium
    (jaxdobby.weave.static), constant over the repeat (its deviation peak to peak, dwell
    vibration, velocity and acceleration exactly 0). Reference: the full finite-element statics
    of the arm (all 31 DOFs, no modal reduction, geometric stiffness) under its weight and the
    link-11 force of rigid inverse dynamics at rest (the frame's weight and the warp force
    ±F_w), mapped to the heald frame through the exact closure (tests/dobby_reference.py, the
    quasi-static limit's reference). The difference is the modal truncation of the static
    deflection: measured 0.42 % (top) and 0.96 % (bottom) with 4 modes, 0.20 % and 0.33 %
    with 8 — tolerances 1.2 % (as the quasi-static limit's, test_dobby_slow) and 0.5 %, and
    8 modes must be the closer."""
    import jax.numpy as jnp
    from dobby_reference import quasi_static_deviation

    errors = {}
    for modes in (4, 8):
        for plan in ("1", "0"):
            run = simulate(Machine.default(n_modes=modes), OperatingPoint(), lift_plan=plan)
            assert bool(run.converged) and int(run.num_steps) == 0
            dev = np.asarray(run.series.deviation)
            assert np.ptp(dev) == 0.0 and dev.shape == (864 + 1,)
            for key in ("deviation_pp", "velocity_deviation_amp", "acceleration_amp",
                        "acceleration_rigid_amp"):
                assert float(run.metrics[key]) == 0.0, key
            assert float(run.pick_metrics["dwell_vibration_max"]) == 0.0
            ref = float(quasi_static_deviation(run.model, jnp.array([0.0]))[0])
            errors[modes, plan] = abs(dev[0] - ref) / abs(ref)
            print(modes, plan, dev[0], ref, errors[modes, plan])
            # up: the warp force pulls the frame down (deviation < 0); down: it pushes it up
            assert np.sign(dev[0]) == (-1.0 if plan == "1" else 1.0)
    for plan in ("1", "0"):
        assert errors[4, plan] < 0.012 and errors[8, plan] < 0.005
        assert errors[8, plan] < errors[4, plan]
    longer = simulate(Machine.default(n_modes=8), OperatingPoint(), lift_plan="000")
    np.testing.assert_allclose(longer.pick_metrics["shed_deviation"],
                               np.full(3, float(run.series.deviation[0])), rtol=1e-12)


def test_simulate_cli_with_a_static_plan_has_a_moving_plans_keys(tmp_path, capsys,
                                                                  monkeypatch):
    monkeypatch.setenv("JAXDOBBY_CACHE_DIR", str(tmp_path / "cache"))
    assert main(["simulate", "--lift-plan", "11", "--json", "--modes", "2"]) == 0
    static = json.loads(capsys.readouterr().out)
    assert main(["simulate", "--lift-plan", "1100", "--json", "--modes", "2"]) == 0
    moving = json.loads(capsys.readouterr().out)
    assert set(static) == set(moving)
    assert static["static"] is True and moving["static"] is False
    assert static["dwell_vibration_pp_mm"] == [0.0, 0.0] and static["moves"] == [False, False]
    assert static["deviation_pp_mm"] == 0.0 and static["converged"] is True
    assert static["deviation_min_mm"] == static["deviation_max_mm"] < 0.0  # up: pulled down


def test_loom_cli_animates_a_frame(tmp_path, capsys, monkeypatch):
    from PIL import Image

    from jaxdobby.weave.command import FRAMES_PER_PICK

    monkeypatch.setenv("JAXDOBBY_CACHE_DIR", str(tmp_path / "cache"))
    assert main(["loom", "--weave", "twill22", "--frames", "2", "--modes", "2",
                 "--animate", "2", "--out", str(tmp_path)]) == 0
    with Image.open(tmp_path / "loom_frame2.gif") as im:
        assert im.n_frames == 4 * FRAMES_PER_PICK


def test_gradient_through_a_static_plan_matches_finite_differences():
    """The static path is differentiable (fixed Newton iterations on the equilibrium): the
    static deflection's derivatives in the warp force and the speed (which only sets the
    repeat's duration: exactly zero) against central differences (h = 1e-4 relative; the
    deflection is nearly linear in the force, truncation ~1e-9 → 1e-6 relative)."""
    machine = Machine.default().replace(n_modes=2)
    plan = jnp.array([1.0, 1.0])

    def deflection(p):
        run = simulate(machine, OperatingPoint(speed=p[0], warp_force=p[1]), lift_plan=plan)
        return run.metrics["deviation_max"]

    p0 = jnp.array([2.0 * math.pi * 800.0 / 60.0, 690.0])
    grad = jax.grad(deflection)(p0)
    h = 1e-4 * p0[1]
    fd = (deflection(p0.at[1].add(h)) - deflection(p0.at[1].add(-h))) / (2 * h)
    print("static gradient", np.asarray(grad), "finite difference (force)", float(fd))
    assert float(grad[0]) == 0.0
    assert float(grad[1]) == pytest.approx(float(fd), rel=1e-6)
    assert float(grad[1]) < 0.0  # up: more warp force pulls the frame further down
