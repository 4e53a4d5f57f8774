"""The batched steady-state evaluator (jaxdobby.periodic) against the model it claims to solve.

References nobody wrote into jaxdobby.periodic: the coupled equations of jaxdobby.dobby (autodiff
through atan2/sin/cos where batch uses closed forms), the exact solution of a forced damped
oscillator (for the Gauss method's order) and the adaptive diffrax solve of
jaxdobby.simulate (for the metrics). The corners of the whole default Sobol box are a slow test.
"""

import itertools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby import Machine, OperatingPoint, simulate
from jaxdobby.periodic import METRICS, steady_state_metrics
from jaxdobby.periodic import collocation as gl
from jaxdobby.periodic.chain import downstream
from jaxdobby.periodic.cycle import arm_terms, rigid_arm, tables_at
from jaxdobby.periodic.stepper import _residuals
from jaxdobby.dobby import build_model, equations_at, rigid_state, vector_field
from jaxdobby.parameters import Setup, apply
from jaxdobby.steady_state import relative_residual

RPM = math.pi / 30.0
NAMES = ("speed", "warp_force", "stroke", "thickness")


def setup_at(row):
    """Setup at (speed [rad/s], warp force [N], stroke [m], thickness [m])."""
    return apply(Setup(), dict(zip(NAMES, row)))


@pytest.mark.parametrize("warp_law", ["restoring", "opposing"])
def test_batch_equations_are_the_models_equations(warp_law):
    """With q̈ from jaxdobby.dobby.vector_field, the batch residual F − M(q)q̈ vanishes.

    Different arithmetic for the same equations (closed-form chain vs autodiff, tabulated
    Kane terms vs kane_terms): agreement to round-off, 1e-9 of the force scale."""
    machine = Machine.default(warp_law=warp_law)
    rng = np.random.default_rng(3)

    @eqx.filter_jit  # one program, not hundreds of eager operations each compiled (~6 s)
    def residual_and_scale(machine, tau, q, qd):
        model = build_model(machine, OperatingPoint.from_users_units(speed_rpm=1000.0))
        arm, ds = arm_terms(model), downstream(model)
        table = tables_at(arm, ds, rigid_arm(model, tau[None]), model.period)
        _, acc = vector_field(tau * model.period, (q, qd), model)
        res, _ = _residuals(arm, ds, table, q[None], qd[None], acc[None])
        mass, _ = equations_at(model, rigid_state(model, tau * model.period), q, qd)
        return jnp.max(jnp.abs(res)), jnp.max(jnp.abs(mass @ acc))

    k = machine.n_modes
    for tau in (0.07, 0.21, 0.38, 0.62, 0.9):
        q = jnp.asarray(rng.normal(size=k) * 1e-4)
        qd = jnp.asarray(rng.normal(size=k) * 1e-2)
        res, scale = residual_and_scale(machine, jnp.asarray(tau), q, qd)
        assert float(res) < 1e-9 * float(scale), tau


def test_gauss_collocation_is_sixth_order_on_a_forced_damped_oscillator():
    """q̈ + 2ζω q̇ + ω² q = cos(νt) from rest; exact solution in closed form (particular +
    homogeneous). Global error O(h⁶): ×64 per halving (between 50 and 70 asked)."""
    w, z, nu = 2.0 * math.pi, 0.05, 3.0
    wd = w * math.sqrt(1 - z * z)
    den = complex(w * w - nu * nu, 2 * z * w * nu)
    amp = 1.0 / den  # q_p = Re(amp e^{iνt})
    qp0, vp0 = amp.real, (1j * nu * amp).real
    c1 = -qp0
    c2 = (-vp0 + z * w * c1) / wd

    def exact(t):
        return (amp * np.exp(1j * nu * t)).real + np.exp(-z * w * t) * (
            c1 * np.cos(wd * t) + c2 * np.sin(wd * t))

    mass, damp, stiff = jnp.eye(1), jnp.eye(1) * 2 * z * w, jnp.eye(1) * w * w

    def run(n, t_end=2.0):
        h = t_end / n
        q, v = jnp.zeros(1), jnp.zeros(1)
        solver = gl.StageSolver(mass, damp, stiff, h)
        for i in range(n):
            tn = i * h
            acc = jnp.zeros((3, 1))
            for _ in range(3):  # linear problem: simplified Newton with the exact matrix
                pos, vel = gl.stage_states(q, v, acc, h)
                times = tn + h * jnp.asarray(gl.NODES)
                res = jnp.cos(nu * times)[:, None] - vel @ damp.T - pos @ stiff.T - acc
                acc = acc + solver.solve(res)
            q, v = gl.advance(q, v, acc, h)
        return float(q[0]) - exact(t_end)

    e1, e2 = run(10), run(20)
    assert abs(e2) < 1e-7
    assert 50.0 < abs(e1 / e2) < 70.0


def random_stage_system(stiffness_diagonal, seed=3):
    """A random k-mode system for the stage-solver tests: symmetric positive definite M, damping
    with a skew (gyroscopic) part, K = the given diagonal plus small random coupling."""
    rng = np.random.default_rng(seed)
    k = len(stiffness_diagonal)
    b = rng.normal(size=(k, k))
    mass = b @ b.T + k * np.eye(k)
    skew = rng.normal(size=(k, k))
    damp = 30.0 * np.eye(k) + 5.0 * (skew - skew.T)
    stiff = np.diag(stiffness_diagonal) + 1e4 * rng.normal(size=(k, k))
    return rng, mass, damp, stiff


@pytest.mark.parametrize("k", [4, 16])
def test_stage_solver_solves_the_assembled_stage_system(k):
    """StageSolver (Butcher-diagonalised blocks, inverted once) against numpy's LU solve of the
    assembled 3k × 3k matrix I⊗M + h a⊗C + h² a²⊗K, for a random system with a symmetric
    positive definite M, a damping with a skew (gyroscopic) part and the step of the default
    machine at 1200 r/min; one and eight right-hand sides. Tolerance 1e-12 relative: both are
    backward stable on a matrix of condition below 10 (6.4 at k = 4, 4.3 at k = 16), so they
    agree to a few ulps times that. k = 4 runs the unrolled eliminations and products, k = 16 (above
    collocation.UNROLL_MAX) their loop and dot forms."""
    assert (k > gl.UNROLL_MAX) == (k == 16)  # both forms are tested
    h = 0.1 / 432
    diagonal = [4e5, 2e6, 8e6, 2e7] if k == 4 else np.geomspace(4e5, 2e8, k)
    rng, mass, damp, stiff = random_stage_system(diagonal)
    a = gl.MATRIX
    big = np.kron(np.eye(3), mass) + h * np.kron(a, damp) + h * h * np.kron(a @ a, stiff)
    solver = gl.StageSolver(jnp.asarray(mass), jnp.asarray(damp), jnp.asarray(stiff), h)
    for r in (rng.normal(size=(3, k)), rng.normal(size=(3, k, 8))):
        want = np.linalg.solve(big, r.reshape(3 * k, -1)).reshape(r.shape)
        got = np.asarray(solver.solve(jnp.asarray(r)))
        assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))
    # the unrolled products the passes use, against numpy's
    x, m = rng.normal(size=(3, k)), rng.normal(size=(k, k))
    assert np.allclose(gl.matmul(jnp.asarray(x), jnp.asarray(m)), x @ m, rtol=1e-14, atol=0)
    assert np.allclose(gl.matmul(jnp.asarray(m), jnp.asarray(x[0])), m @ x[0], rtol=1e-14,
                       atol=0)
    assert np.allclose(gl.weigh(gl.MATRIX2, jnp.asarray(x)), gl.MATRIX2 @ x, rtol=1e-14, atol=0)


def test_step_map_is_the_stagewise_tangent_step():
    """jaxdobby.periodic.linear.step_map (Ψ in closed form from the inverted Butcher blocks)
    against tangent_step applied to the identity (the stage-by-stage solve, which the test
    above checks against numpy's assembled stage system), on that test's random k = 4 system
    with stiff modes (ωh up to ~20, as the arm's at 400 r/min). Two algebraic forms of one
    matrix: agreement to round-off, 1e-13 relative."""
    from jaxdobby.periodic.linear import step_map, tangent_step

    k, h = 4, 0.15 / 432
    _, mass, damp, stiff = random_stage_system([4e5, 8e8, 1.3e9, 3.6e9])
    solver = gl.StageSolver(*(jnp.asarray(m) for m in (mass, damp, stiff)), h)
    psi = step_map(solver, jnp.asarray(damp), jnp.asarray(stiff), h)
    want = tangent_step(solver, jnp.asarray(damp), jnp.asarray(stiff), jnp.eye(2 * k), h)
    assert float(jnp.max(jnp.abs(psi - want))) <= 1e-13 * float(jnp.max(jnp.abs(want)))


def test_linearisation_is_close_to_the_exact_cycle_map():
    """The monodromy matrix of the equations linearised about the rigid motion
    (jaxdobby.periodic.linear) against the exact one of the discrete cycle map at the periodic
    state: forward-mode derivatives through the integrated cycle's Newton iterations (another
    computation altogether). They differ by the frozen matrices (the middle node's for a whole
    step: O(h²) per step) and the linearisation point (the joint moves ~1 mm on ~0.4 m
    links): within 1e-2 relative at the default machine (measured 4.3e-3; 3.3e-2 at the
    1200 r/min, 1035 N, 140 mm, 6 mm corner): about what the chord iteration contracts by per
    cycle."""
    from jaxdobby.periodic.linear import linearise
    from jaxdobby.periodic.steady import prepare
    from jaxdobby.periodic.stepper import cycle_pass

    def errors(setup):
        c = prepare(setup)
        lin = linearise(c.arm, c.downstream, c.tables, c.period)
        k = c.arm.mass.shape[0]
        chord = jnp.linalg.inv(jnp.eye(2 * k) - lin.monodromy)

        def cycle(x):
            return cycle_pass(c.arm, c.downstream, c.tables, c.period, x,
                              solvers=lin.solvers).end

        # six chord iterations in a loop (one traced cycle, not six: the test 30 -> 9 s), then
        # the cycle and its Jacobian from one forward-mode pass
        x = jax.lax.fori_loop(0, 6, lambda _, x: x + chord @ (cycle(x) - x),
                              chord @ lin.rest_response)
        exact, end = jax.jacfwd(lambda x: (y := cycle(x), y), has_aux=True)(x)
        return (jnp.max(jnp.abs(lin.monodromy - exact)) / jnp.max(jnp.abs(exact)),
                relative_residual(x, end))

    phi_error, residual = jax.jit(errors)(Setup())
    assert float(residual) < 1e-12  # the periodic state the derivative is taken at
    assert float(phi_error) < 1e-2


def test_two_newton_iterations_per_step_converge_the_cycle():
    """A cycle from the periodic state with the stored (rigid-motion) Newton matrices and two
    simplified-Newton iterations per step, as the batch evaluator runs them, against six
    iterations (converged to round-off: the third already agrees to ~5e-9): the cycle's
    peak-to-peak ranges of deviation, velocity deviation and acceleration within 1e-6 relative
    (measured ≤ 3.2e-7 at these three machines; one iteration leaves 1.5e-4), at the default
    speed and at the slow and fast ends of the Sobol box."""
    from jaxdobby.periodic.linear import linearise
    from jaxdobby.periodic.steady import prepare
    from jaxdobby.periodic.stepper import cycle_pass

    def ranges(row):
        c = prepare(setup_at(row))
        lin = linearise(c.arm, c.downstream, c.tables, c.period)
        chord = jnp.linalg.inv(jnp.eye(lin.monodromy.shape[0]) - lin.monodromy)

        def run(x, iterations):
            return cycle_pass(c.arm, c.downstream, c.tables, c.period, x, solvers=lin.solvers,
                              outputs=True, iterations=iterations)

        x = jax.lax.fori_loop(0, 4, lambda _, x: x + chord @ (run(x, 2).end - x),
                              chord @ lin.rest_response)  # a loop: one traced cycle, not four
        return jnp.stack([(r.maxima - r.minima) for r in (run(x, 2), run(x, 6))])

    rows = jnp.array([[800 * RPM, 690.0, 0.140, 0.006], [400 * RPM, 345.0, 0.080, 0.008],
                      [1200 * RPM, 1035.0, 0.140, 0.006]])
    one = jax.jit(ranges)
    got = np.stack([np.asarray(one(row)) for row in rows])
    np.testing.assert_allclose(got[:, 0], got[:, 1], rtol=1e-6, atol=0)


def counted_builds(steady):
    """(builds, wrapper): a stand-in for steady.machine_parts that appends to ``builds`` at
    run time each time the machine's part of the model is built."""
    builds = []
    parts = steady.machine_parts

    def counted(machine):
        jax.debug.callback(lambda: builds.append(1))
        return parts(machine)

    return builds, counted


@pytest.fixture(scope="module")
def batch_144():
    """The batch evaluator on 12 lanes at 144 steps per cycle (cheap), compiled once for the two
    tests below that hold it against other code: with ROUND_WIDTH 3 (a round takes part of the
    lanes) and the machine's part of the model counted at run time as it is built (``builds``,
    one entry per build)."""
    from jaxdobby.periodic import steady

    builds, counted = counted_builds(steady)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(steady, "ROUND_WIDTH", 3)
        patch.setattr(steady, "machine_parts", counted)
        batch = jax.jit(jax.vmap(lambda r: steady_state_metrics(setup_at(r), steps=144)))
        program = batch.lower(jax.ShapeDtypeStruct((12, 4), jnp.float64)).compile()
    return program, builds


def test_vmap_equals_single_samples_and_failures_are_flagged(monkeypatch, batch_144):
    """The batched chord iteration integrates only pending lanes, ROUND_WIDTH of them per round
    (jaxdobby.periodic.steady._settle; 3 here, so that a round takes part of the 9 lanes): each
    lane must get the cycle count, the flag and the metrics it gets alone (the per-sample while
    loop, run by lax.map, which does not batch). Eight random rows of the default box on a
    coarse grid (144 steps, cheap) need between 3 and 7 cycles, so lanes finish in different
    rounds and some hit max_passes. A ninth row is far outside any loom's range: a 2 mm arm at
    3000 r/min (frame-on-arm mode ~62 Hz by the √t scaling of the 107 Hz one, the cycle at
    25 Hz; its solve does not give a finite periodic cycle): it is flagged (ok False), nothing
    raises, and the other lanes are unaffected. Lanes are independent, but XLA may order the
    sums of batched contractions differently (measured 6e-12 relative), so 1e-10.

    Three more rows share the machine (stroke and thickness) of the first three at other
    speeds and warp forces, as the rows of a Saltelli design do: the batch builds the machine's
    part of the model once per distinct machine (jaxdobby.periodic.steady.model_terms), 9
    times for these 12 rows (counted at run time), the per-sample loop 12 times, and every lane
    still gets what it gets alone."""
    from jaxdobby.periodic import steady

    monkeypatch.setattr(steady, "ROUND_WIDTH", 3)
    builds, counted = counted_builds(steady)
    monkeypatch.setattr(steady, "machine_parts", counted)
    rng = np.random.default_rng(1)
    lo = np.array([400 * RPM, 345.0, 0.080, 0.006])
    hi = np.array([1200 * RPM, 1035.0, 0.140, 0.008])
    far_out = np.array([[3000 * RPM, 690.0, 0.140, 0.002]])
    random = lo + (hi - lo) * rng.random((8, 4))
    shared = np.concatenate([(lo + (hi - lo) * rng.random((3, 4)))[:, :2], random[:3, 2:]], 1)
    rows = jnp.asarray(np.concatenate([random, shared, far_out]))

    def one(r):
        return steady_state_metrics(setup_at(r), steps=144)

    program, batch_builds = batch_144
    batch_builds.clear()
    batched = jax.block_until_ready(program(rows))
    assert len(batch_builds) == 9
    alone = jax.block_until_ready(jax.jit(lambda rs: jax.lax.map(one, rs))(rows))
    assert len(builds) == 12
    cycles = np.asarray(batched["cycles"])
    assert len(set(cycles.tolist())) >= 3, cycles  # lanes finish in different rounds
    assert cycles.tolist() == np.asarray(alone["cycles"]).tolist()
    assert np.asarray(batched["ok"]).tolist() == np.asarray(alone["ok"]).tolist()
    assert not bool(batched["ok"][-1]) and np.sum(np.asarray(batched["ok"])) >= 4
    for name in METRICS:
        np.testing.assert_allclose(batched[name][:-1], alone[name][:-1], rtol=1e-10,
                                   err_msg=name)


def test_a_sampled_linkage_gives_each_lane_its_own_rigid_motion(monkeypatch):
    """A batch shares the rigid motion's tables between its lanes unless the linkage is sampled
    (jaxdobby.periodic.steady.batch_tables); sampling the eccentricity and the dwell with the
    speed, each lane must get what it gets alone (the per-sample while loop under lax.map),
    to 1e-10 as above, on the coarse grid of 144 steps (dwell boundaries then fall inside
    steps: a rougher cycle, the same for both)."""
    from jaxdobby.periodic import steady

    seen = []
    batch_tables = steady.batch_tables

    def spy(terms, rigid, batched=False):
        seen.append(any(jax.tree.leaves(batched)))
        return batch_tables(terms, rigid, batched)

    monkeypatch.setattr(steady, "batch_tables", spy)
    rows = jnp.asarray([[800 * RPM, 0.030, math.radians(100.0)],
                        [1000 * RPM, 0.029, math.radians(110.0)],
                        [600 * RPM, 0.031, math.radians(90.0)]])

    def one(r):
        return steady_state_metrics(
            apply(Setup(), dict(zip(("speed", "eccentricity", "dwell"), r))), steps=144)

    batched = jax.jit(jax.vmap(one))(rows)
    alone = jax.jit(lambda rs: jax.lax.map(one, rs))(rows)
    assert seen == [True]  # tables from each lane's own rigid motion (traced once)
    assert np.asarray(batched["ok"]).all() and np.asarray(alone["ok"]).all()
    assert np.asarray(batched["cycles"]).tolist() == np.asarray(alone["cycles"]).tolist()
    for name in METRICS:
        np.testing.assert_allclose(batched[name], alone[name], rtol=1e-10, err_msg=name)


def test_steps_by_speed_integrate_the_most_steps_any_lane_needs(monkeypatch, batch_144):
    """``steps="speed"`` (what a Sobol chunk runs): each sample's steps per cycle from its speed
    (jaxdobby.periodic.steady.STEPS_BY_SPEED), a batch integrating its lanes' most in loops of a
    run-time length over tables of a fixed size. Held against the scans of a fixed step count
    (the code every other test checks), on a coarse table (216 and 144 steps, cheaper): a batch
    of fast rows equals the fixed 144-step batch (the one compiled for the test above), a batch
    with slow rows the fixed 216-step one (to 1e-10, as the lanes against their solves alone
    above: the same arithmetic, other loops), and the table's thresholds are where it says.
    Batches of 12 lanes, the size of the fixed 144-step program."""
    from jaxdobby.periodic import steady

    monkeypatch.setattr(steady, "DEFAULT_STEPS", 216)
    monkeypatch.setattr(steady, "STEPS_BY_SPEED", ((0.0, 216), (700.0, 144)))
    slow = [[500 * RPM, 400.0, 0.100, 0.007], [650 * RPM, 900.0, 0.130, 0.0065]]
    fast = [[900 * RPM, 600.0, 0.090, 0.0075], [1150 * RPM, 1000.0, 0.120, 0.006]]

    def batch(steps):
        return jax.jit(jax.vmap(lambda r: steady_state_metrics(setup_at(r), steps=steps)))

    by_speed = batch("speed")  # one program serves both batches
    for rows, fixed, reference in ((fast * 6, 144, batch_144[0]),
                                   ((slow + fast) * 3, 216, batch(216))):
        rows = jnp.asarray(rows)
        got, want = by_speed(rows), reference(rows)
        assert np.asarray(got["ok"]).all()
        assert np.asarray(got["cycles"]).tolist() == np.asarray(want["cycles"]).tolist()
        for name in METRICS:
            np.testing.assert_allclose(got[name], want[name], rtol=1e-10,
                                       err_msg=f"{name}, {fixed} steps")
    speeds = jnp.asarray([699.9, 700.0, 1200.0]) * RPM
    assert steady.steps_for_speed(speeds).tolist() == [216, 144, 144]
    with pytest.raises(ValueError, match="steps must be a positive integer or 'speed'"):
        steady_state_metrics(setup_at(jnp.asarray(slow[0])), steps="fast")


@pytest.mark.slow
def test_steps_by_speed_keep_the_accuracy_at_the_slowest_speed_of_each_step_count():
    """The thresholds of jaxdobby.periodic.steady.STEPS_BY_SPEED: at the slowest speed of each
    step count below 432 (360 steps from 450 r/min, 288 from 650, 216 from 1000) the 8 corners
    of warp force × stroke × thickness of the default box are within 3e-5 relative of the
    adaptive solve (rtol 1e-8) in every metric, as 432 steps are at 400 r/min (measured
    2026-12-07: 2.5e-5, 2.8e-5, 1.6e-5, the velocity deviation's amplitude each time; 432 steps
    at 400 r/min 2.3e-5). Above a threshold the error falls with the speed (the arm's modes get
    more steps per period: 1.7e-5 at 480 r/min with 360 steps, 2.2e-5 at 700 with 288, 1.0e-5 at
    1100 with 216)."""
    from jaxdobby.periodic.steady import STEPS_BY_SPEED

    lo, hi = (345.0, 0.080, 0.006), (1035.0, 0.140, 0.008)
    for rpm, _ in STEPS_BY_SPEED[1:]:
        rows = np.array([[rpm * RPM] + [hi[i] if b else lo[i] for i, b in enumerate(bits)]
                         for bits in itertools.product([0, 1], repeat=3)])
        batched = jax.jit(jax.vmap(lambda r: steady_state_metrics(setup_at(r), steps="speed")))(
            jnp.asarray(rows))
        assert bool(jnp.all(batched["ok"]))
        for i, row in enumerate(rows):
            s = setup_at(jnp.asarray(row))
            ref = simulate(s.machine, s.operating, method="adaptive").metrics
            for name in METRICS:
                assert float(batched[name][i]) == pytest.approx(float(ref[name]), rel=3e-5), (
                    rpm, row, name)


@pytest.mark.slow
def test_corners_of_the_default_box_match_the_adaptive_reference():
    """All 16 corners of speed 400–1200 r/min × warp 345–1035 N × stroke 80–140 mm × t 6–8 mm:
    each metric within 1e-4 relative of the adaptive solve (rtol 1e-8)."""
    lo, hi = (400 * RPM, 345.0, 0.080, 0.006), (1200 * RPM, 1035.0, 0.140, 0.008)
    rows = np.array([[hi[i] if b else lo[i] for i, b in enumerate(bits)]
                     for bits in itertools.product([0, 1], repeat=4)])
    batched = jax.jit(jax.vmap(lambda r: steady_state_metrics(setup_at(r))))(jnp.asarray(rows))
    assert bool(jnp.all(batched["ok"]))
    for i, row in enumerate(rows):
        s = setup_at(jnp.asarray(row))
        ref = simulate(s.machine, s.operating, method="adaptive").metrics
        for name in METRICS:
            assert float(batched[name][i]) == pytest.approx(float(ref[name]), rel=1e-4), (row,
                                                                                          name)


def test_batched_program_calls_lapack_one_matrix_at_a_time():
    """jaxlib splits a *batched* LAPACK call over the CPU's intra-op threads and blocks one of
    them until the pieces finish; two such calls side by side deadlock a 2-core CPU (seen: a
    chunk of 256 samples waiting for ever at 0 % CPU, native stacks in dgetrf and dtrsm both in
    ParallelBatchMap). The batch path builds each sample's model sequentially, so in the program
    vmapped over 256 samples (thickness varies, so the arm is rebuilt per sample) every LAPACK
    call has operands of one matrix: rank 2, no batch axis."""
    import re

    def one(row):
        return steady_state_metrics(setup_at(row), steps=8, max_passes=1)

    rows = jnp.tile(jnp.array([800 * RPM, 690.0, 0.14007, 0.006]), (256, 1))
    text = jax.jit(jax.vmap(one)).lower(rows).as_text()
    calls = re.findall(r"custom_call @(lapack_\w+)\(.*?\) .*?: \(([^)]*)\)", text)
    assert {name for name, _ in calls} >= {"lapack_dsyevd_ffi", "lapack_dgetrf_ffi"}
    for name, operands in calls:
        for shape in re.findall(r"tensor<([0-9x]+)xf64>", operands):
            assert shape.count("x") == 1, (name, shape)
