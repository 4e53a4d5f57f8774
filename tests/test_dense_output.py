"""The collocation path's dense output (jaxdobby.periodic.collocation.dense_weights, used by
simulate's default method) against closed-form integrals."""

import numpy as np
import pytest

from jaxdobby.periodic import collocation as gl

THETA = np.linspace(0.0, 1.0, 9)


@pytest.mark.parametrize("m", [0, 1, 2])
def test_velocity_weights_integrate_quadratics_exactly(m):
    # v(θ) − v_n = h Σ W1ᵢ(θ) f(cᵢ) for q̈ = f(t) = (t/h)^m: the quadratic interpolant of f at
    # three nodes is f itself, so v is exact: ∫₀^θ s^m ds = θ^(m+1)/(m+1). Round-off: 1e-15.
    w1, _ = gl.dense_weights(THETA)
    np.testing.assert_allclose(w1 @ gl.NODES**m, THETA ** (m + 1) / (m + 1), atol=1e-15)


@pytest.mark.parametrize("m", [0, 1])
def test_position_weights_integrate_lines_exactly(m):
    # q(θ) − q_n − θh v_n = h² Σ W2ₖ(θ) f(cₖ): q̇ of the collocation polynomial interpolates
    # the stage velocities (exact for f of degree ≤ 1, where v is quadratic), so
    # ∫₀^θ (θ − s) s^m ds = θ^(m+2)/((m+1)(m+2)).
    _, w2 = gl.dense_weights(THETA)
    np.testing.assert_allclose(w2 @ gl.NODES**m, THETA ** (m + 2) / ((m + 1) * (m + 2)),
                               atol=1e-15)


def test_dense_weights_at_the_nodes_and_the_step_end_are_the_methods():
    # At θ = cⱼ the stage formulas (rows of a and a²); at θ = 1 the update (b and bᵀa).
    w1, w2 = gl.dense_weights(np.r_[gl.NODES, 1.0])
    np.testing.assert_allclose(w1[:3], gl.MATRIX, atol=1e-15)
    np.testing.assert_allclose(w2[:3], gl.MATRIX2, atol=1e-15)
    np.testing.assert_allclose(w1[3], gl.WEIGHTS, atol=1e-15)
    np.testing.assert_allclose(w2[3], gl.WEIGHTS2, atol=1e-15)


def test_collocation_outputs_equal_the_autodiff_kinematics():
    """The collocation path reports its time series from the chain in closed form
    (jaxdobby.periodic.dense.outputs_at); jaxdobby.outputs computes the same quantities from the
    autodiff kinematics of jaxdobby.dobby (loop closures differentiated by jax.jvp, q̈ from
    equations_at). Two independent implementations of the same definitions at the same states
    (q, q̇) of the default run: equal to round-off, 1e-9 of each series' amplitude (closed-form
    derivatives against nested forward-mode ones; measured ≤ 3e-11). The same for the arm's
    motion the stress correction reads (Simulation.arm_motion: the tables' frame, ring direction
    and rigid link-11 force, q̈ of the closed-form equations) against
    jaxdobby.outputs.arm_motion (rigid_state and equations_at; measured ≤ 1e-12)."""
    import jax

    from jaxdobby import simulate
    from jaxdobby.dobby import rigid_state
    from jaxdobby.outputs import arm_motion, flexible_outputs, rigid_outputs

    run = simulate()
    model, series = run.model, run.series

    @jax.jit
    def reference(ts, q, qd):
        rigid = jax.vmap(lambda t: rigid_state(model, t))(ts)
        out = jax.vmap(lambda r, a, b: flexible_outputs(model, r, a, b))(rigid, q, qd)
        return dict(out, **rigid_outputs(model, ts))

    want = reference(series.t, series.modal, series.modal_rate)
    for key, value in want.items():
        got, ref = np.asarray(getattr(series, key)), np.asarray(value)
        scale = np.max(np.abs(ref))
        assert np.max(np.abs(got - ref)) <= 1e-9 * scale, key
    want = jax.jit(arm_motion)(model, series)
    for key in want.__dataclass_fields__:
        got, ref = np.asarray(getattr(run.arm_motion, key)), np.asarray(getattr(want, key))
        assert np.max(np.abs(got - ref)) <= 1e-9 * np.max(np.abs(ref)), key
