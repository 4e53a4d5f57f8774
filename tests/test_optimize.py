"""Design optimisation: the design space, constraints, the optimiser on problems with known
answers, and the command line's input checks (fast; the full studies are in
test_optimize_studies.py, marked slow)."""

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize

from jaxdobby.cli import main
from jaxdobby.errors import InputError
from jaxdobby.optimize import (
    Constraints,
    DesignSpace,
    Settings,
    constraint_jacobian,
    optimize,
)
from jaxdobby.optimize.design import affine_rows, check_mass_budget
from jaxdobby.optimize.feasible import FeasibleSet
from jaxdobby.optimize.loop import projected_gradient
from jaxdobby.parameters import Setup


@pytest.fixture(scope="module")
def space():
    return DesignSpace.create(Setup(), ["thickness", "depth", "heald_frame_mass"])


def test_design_space_maps_and_inverts(space):
    assert space.labels() == ["thickness", "depth@0mm", "depth@80mm", "depth@153mm",
                              "depth@201mm", "depth@226mm", "heald_frame_mass"]
    # The default machine: 6 mm, uniform 40 mm interpolated onto the control points, 12 kg.
    np.testing.assert_allclose(space.physical(space.initial),
                               [0.006] + [0.040] * 5 + [12.0], rtol=1e-14)
    u = jnp.asarray(np.random.default_rng(0).uniform(size=space.size))
    np.testing.assert_allclose(space.values(space.setup(u)), space.physical(u), rtol=1e-14)
    lo, hi = np.asarray(space.lower), np.asarray(space.upper)
    np.testing.assert_allclose(lo, [0.004] + [0.020] * 5 + [8.0])
    np.testing.assert_allclose(hi, [0.008] + [0.080] * 5 + [18.0])
    np.testing.assert_array_equal(space.project(jnp.array([-0.5, 0.2, 1.5] + [0.5] * 4)),
                                  [0.0, 0.2, 1.0] + [0.5] * 4)


def test_thickness_bound_is_pitch_minus_clearance():
    s = DesignSpace.create(Setup(), ["thickness"], pitch_mm=10.0, clearance_mm=3.0)
    assert float(s.upper[0]) == pytest.approx(0.007)
    with pytest.raises(InputError, match="pitch"):
        DesignSpace.create(Setup(), ["thickness"], pitch_mm=3.0, clearance_mm=4.0)
    with pytest.raises(InputError, match="unknown design variable 'width'"):
        DesignSpace.create(Setup(), ["width"])
    with pytest.raises(InputError, match="depth_positions_mm"):
        DesignSpace.create(Setup(), ["depth"], depth_positions_mm=[0.0, 300.0])


def test_arc_radius_keeps_stroke_and_arc_length():
    # The default stroke (140.07 mm) is the slot's end: another radius cannot keep it.
    with pytest.raises(InputError, match="stroke 140.07 mm cannot be kept with arc radius 300"):
        DesignSpace.create(Setup(), ["arc_radius"], bounds={"arc_radius": (300.0, 600.0)})
    base = Setup(machine=Setup().machine.with_stroke(0.120))
    s = DesignSpace.create(base, ["arc_radius"], bounds={"arc_radius": (300.0, 600.0)})
    for u in (0.0, 0.7, 1.0):
        setup = s.setup(jnp.array([u]))
        arm = setup.machine.arm
        # The root solve holds the rigid stroke to its Newton tolerance (1e-12 m measured).
        assert float(setup.machine.stroke()) == pytest.approx(float(s.target_stroke), abs=1e-9)
        assert float(arm.arc_radius * arm.arc_angle) == pytest.approx(float(s.arc_length),
                                                                      rel=1e-14)


def test_constraints_and_their_gradients(space):
    limits = Constraints(mass_budget=0.5, frequency_floor=100.0)
    u0 = space.initial
    c, jac = constraint_jacobian(space, limits, u0)
    mass0 = Setup().machine.arm.mass()
    assert float(c[0]) == pytest.approx(float(mass0) / 0.5 - 1.0, rel=1e-12)
    # Mass is linear in t (A = t·d), so its t-derivative is exact: m/t·(t_hi − t_lo)/budget.
    assert float(jac[0, 0]) == pytest.approx(float(mass0) / 0.006 * 0.004 / 0.5, rel=1e-12)
    fn = jax.jit(lambda u: constraint_jacobian(space, limits, u)[0])
    h = 1e-4
    fd = np.stack([(fn(u0.at[i].add(h)) - fn(u0.at[i].add(-h))) / (2 * h)
                   for i in range(space.size)], axis=1)
    # Central differences at h = 1e-4 of the box (4e-7 m of thickness, 6e-6 m of depth):
    # truncation ~h² = 1e-8; the first coupled frequency comes from eigenvalues spanning
    # 106 Hz … 9 kHz (λ ratio ~1e7), so its round-off is ~1e-16·1e7/h ~1e-5 at worst.
    np.testing.assert_allclose(jac, fd, rtol=1e-5, atol=1e-6)
    assert np.all(np.abs(jac[1, :-1]) > 0)  # the frequency depends on thickness and depth


def quadratic(target):
    target = np.asarray(target)

    def value_and_grad(u):
        return float(np.sum((u - target) ** 2)), 2.0 * (u - target), {}

    return value_and_grad


def linear_constraint(u):
    # u0 + u1 ≤ 1
    return np.array([u[0] + u[1] - 1.0]), np.array([[1.0, 1.0]])


def no_constraints(u):
    return np.zeros(0), np.zeros((0, u.shape[0]))


def circle_constraint(u):
    # u0² + u1² ≤ 1/2 (not linear: the augmented Lagrangian's job)
    return np.array([u[0] ** 2 + u[1] ** 2 - 0.5]), np.array([2.0 * u])


def test_lbfgs_augmented_lagrangian_reaches_the_kkt_point():
    # min |u − p|², p = (0.9, 0.8), s.t. |u|² ≤ 1/2: the projection of p onto the circle of
    # radius r = √½, u* = r·p/|p|, with λ* = |p|/r − 1 (from 2(u − p) + 2λu = 0).
    p = np.array([0.9, 0.8])
    r = math.sqrt(0.5)
    result = optimize(quadratic(p), circle_constraint, np.array([0.1, 0.1]),
                      Settings(optimizer="lbfgs", steps=100, tolerance=1e-7))
    assert result.converged
    np.testing.assert_allclose(result.u, r * p / np.linalg.norm(p), atol=1e-6)
    np.testing.assert_allclose(result.multipliers, [np.linalg.norm(p) / r - 1.0], atol=1e-5)
    assert result.optimality["projected_gradient"] < 1e-6
    assert result.optimality["violation"] < 1e-8


@pytest.mark.parametrize("optimizer", ["lbfgs", "adam"])
def test_linear_constraint_is_held_by_projection(optimizer):
    # min (u0−0.9)² + (u1−0.8)² s.t. u0 + u1 ≤ 1 on [0,1]²: u* = (0.55, 0.45), λ* = 0.7
    # (2(u − p) + λ(1, 1) = 0 on the line). Every iterate is feasible (projection).
    steps = 20 if optimizer == "lbfgs" else 400
    result = optimize(quadratic([0.9, 0.8]), linear_constraint, np.array([0.1, 0.1]),
                      Settings(optimizer=optimizer, steps=steps, tolerance=1e-7), linear=(0,))
    assert result.converged
    np.testing.assert_allclose(result.u, [0.55, 0.45], atol=1e-6)
    np.testing.assert_allclose(result.multipliers, [0.7], atol=1e-5)
    assert result.optimality["projected_gradient"] < 1e-6
    assert all(r.u.sum() <= 1.0 + 1e-12 for r in result.history)
    if optimizer == "lbfgs":  # a quadratic on a face: a handful of steps
        assert len(result.history) <= 6


def test_bound_and_linear_constraint_active_together():
    # min |u − (2, 0.5, 0.2)|² on [0,1]³ with u0 + u1 + u2 ≤ 1.2. KKT by hand: u = clip(p − μ·1)
    # with μ = λ/2; u0 = 1 at its bound, u2 = 0 at its bound, 1 + 0.5 − μ = 1.2 → μ = 0.3,
    # so u* = (1, 0.2, 0) and λ* = 0.6.
    def constraint(u):
        return np.array([u.sum() - 1.2]), np.ones((1, 3))

    result = optimize(quadratic([2.0, 0.5, 0.2]), constraint, np.full(3, 0.1),
                      Settings(optimizer="lbfgs", steps=30, tolerance=1e-9), linear=(0,))
    assert result.converged
    np.testing.assert_allclose(result.u, [1.0, 0.2, 0.0], atol=1e-9)
    np.testing.assert_allclose(result.multipliers, [0.6], atol=1e-8)


def _slsqp_projection(v, a, b):
    """argmin |x − v|² over 0 ≤ x ≤ 1, a·x ≤ b by scipy's SLSQP."""
    return scipy.optimize.minimize(
        lambda y: np.sum((y - v) ** 2), np.clip(v, 0, 1), jac=lambda y: 2 * (y - v),
        bounds=[(0.0, 1.0)] * v.shape[0], method="SLSQP",
        options={"ftol": 1e-14, "maxiter": 500},
        constraints=[{"type": "ineq", "fun": lambda y: b - a @ y, "jac": lambda y: -a}]).x


def test_projection_onto_box_and_halfspace_matches_a_qp_solver():
    # Against scipy's SLSQP on the same small QP, min |x − v|² s.t. 0 ≤ x ≤ 1, a·x ≤ b.
    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.uniform(-1.0, 2.0, size=5)
        b = float(rng.uniform(0.2, 1.5))
        v = rng.uniform(-0.5, 1.5, size=5)
        x = FeasibleSet(a=a, b=b).project(v)
        ref = _slsqp_projection(v, a, b)
        # SLSQP stops at ftol 1e-14 on |x − v|²: ~1e-7 in x; the projection is exact.
        np.testing.assert_allclose(x, ref, atol=1e-6)
        assert a @ x <= b + 1e-14 and x.min() >= 0.0 and x.max() <= 1.0


def test_infeasible_linear_constraint_is_refused():
    with pytest.raises(ValueError, match="cannot be met in the box"):
        FeasibleSet(a=np.array([1.0, 1.0]), b=-0.1)


def test_mass_is_held_by_projection_and_a_too_small_budget_is_refused():
    # The mass is linear in the depths alone (and in t alone), not in both at once.
    depth = DesignSpace.create(Setup(), ["depth"])
    both = DesignSpace.create(Setup(), ["thickness", "depth"])
    limits = Constraints(mass_budget=0.5, frequency_floor=100.0)
    assert affine_rows(depth, limits) == (0,)
    assert affine_rows(both, limits) == ()
    # Lightest arm in the default bounds: 20 mm deep, 6 mm thick (t fixed) = half the default
    # 40 mm arm's 0.42304 kg.
    with pytest.raises(InputError, match=r"mass budget = 0.2 kg is below the lightest arm "
                                         r"within the bounds \(0.2115 kg\)"):
        check_mass_budget(depth, Constraints(mass_budget=0.2))


@pytest.mark.parametrize("optimizer", ["lbfgs", "adam"])
def test_projection_holds_the_bounds(optimizer):
    # Unconstrained minimum at (1.9, 0.3): the box solution is (1, 0.3) with u0 at its bound.
    result = optimize(quadratic([1.9, 0.3]), no_constraints, np.array([0.1, 0.1]),
                      Settings(optimizer=optimizer, steps=400, tolerance=1e-6))
    assert result.converged
    assert result.u[0] == 1.0
    assert result.u[1] == pytest.approx(0.3, abs=1e-5)
    assert all(0.0 <= r.u.min() and r.u.max() <= 1.0 for r in result.history)


def test_projected_gradient():
    u = np.array([0.0, 0.0, 1.0, 1.0, 0.5])
    g = np.array([1.0, -1.0, -1.0, 1.0, 2.0])
    np.testing.assert_array_equal(projected_gradient(u, g), [0.0, -1.0, 0.0, 1.0, 2.0])


@pytest.mark.parametrize("argv, field", [
    (["--vars", "thickness,width"], "unknown design variable 'width'"),
    (["--speeds", "800,0"], "speed = 0"),
    (["--speeds", "fast"], "--speeds must be a comma-separated list"),
    (["--bounds", "thickness=8:4"], "bounds of thickness"),
    (["--bounds", "thickness=7:8"], "starting thickness = 6 mm is outside its bounds"),
    (["--bounds", "thickness"], "--bounds"),
    (["--mass-budget", "-1"], "mass budget = -1.0 kg is outside the valid range"),
    (["--pitch", "4", "--clearance", "5"], "clearance = 5.0 mm is outside the valid range"),
    (["--steps", "-3"], "--steps = -3 is outside the valid range"),
    (["--learning-rate", "0"], "learning rate"),
    (["--vars", "depth", "--depth-positions", "0,300"], "depth_positions_mm"),
])
def test_bad_input_exits_2_naming_the_field(argv, field, capsys):
    assert main(["optimize", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("jaxdobby optimize: error: ")
    assert field in err[0]


def test_bad_problem_file(tmp_path, capsys):
    path = tmp_path / "problem.toml"
    path.write_text('[constraints]\nmass_budget = 0.4\n')
    assert main(["optimize", "--problem", str(path)]) == 2
    err = capsys.readouterr().err
    assert "unknown key 'mass_budget' in [constraints]" in err and "mass_budget_kg" in err
    path.write_text('[objective]\nspeeds_rpm = [800, -5]\n')
    assert main(["optimize", "--problem", str(path)]) == 2
    assert "speed = -5" in capsys.readouterr().err


def test_problem_file_reaches_the_study(tmp_path):
    import argparse

    from jaxdobby.cli import build_parser
    from jaxdobby.optimize.command import build_study

    path = tmp_path / "problem.toml"
    path.write_text(json.dumps({}).replace("{}", "") + """
[objective]
speeds_rpm = [800, 1200]
aggregate = "mean"
[variables]
names = ["thickness"]
thickness_mm = [5.0, 7.5]
[constraints]
mass_budget_kg = 0.5
[optimizer]
name = "adam"
steps = 3
""")
    ns = build_parser().parse_args(["optimize", "--problem", str(path), "--steps", "4"])
    assert isinstance(ns, argparse.Namespace)
    study = build_study(ns)
    assert study.objective.aggregate == "mean"
    np.testing.assert_allclose(study.objective.speeds, np.array([800.0, 1200.0]) * np.pi / 30)
    assert float(study.space.upper[0]) == pytest.approx(0.0075)
    assert study.limits.mass_budget == 0.5 and study.limits.frequency_floor is None
    assert study.settings.optimizer == "adam" and study.settings.steps == 4  # the flag wins


def test_a_batched_scan_of_starts_picks_the_best_feasible_candidate():
    # J = |u − (0.9, 0.8)|² over [0,1]² with u0 + u1 ≤ 1 held by projection and a nonlinear
    # constraint u1 ≤ 0.3 (row 1): the best projected candidate meeting u1 ≤ 0.3 is the one
    # nearest the constrained optimum (0.7, 0.3) among the Sobol points (checked by brute force).
    from jaxdobby.optimize.study import best_start, start_candidates

    class Fake:
        def values_many(self, us):
            return np.sum((np.asarray(us) - np.array([0.9, 0.8])) ** 2, axis=1)

    def constraints(u):
        return (np.array([u[0] + u[1] - 1.0, u[1] - 0.3]),
                np.array([[1.0, 1.0], [0.0, 1.0]]))

    u0 = np.array([0.1, 0.1])
    best, j = best_start(Fake(), constraints, u0, 32, linear=(0,), seed=3)
    candidates = [FeasibleSet(a=np.ones(2), b=1.0).project(c)
                  for c in start_candidates(u0, 32, seed=3)]
    allowed = [c for c in candidates if c[1] <= 0.3]
    expected = min(allowed, key=lambda c: float(np.sum((c - np.array([0.9, 0.8])) ** 2)))
    np.testing.assert_array_equal(best, expected)
    assert j == pytest.approx(float(np.sum((expected - np.array([0.9, 0.8])) ** 2)))
    assert best.sum() <= 1.0 + 1e-12 and best[1] <= 0.3
    # one variable: the given design and a uniform grid over the range
    np.testing.assert_allclose(start_candidates(np.array([0.4]), 5)[:, 0],
                               [0.4, 0.0, 1 / 3, 2 / 3, 1.0])
