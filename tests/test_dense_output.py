"""The collocation path's dense output (jaxdobby.batch.collocation.dense_weights, used by
simulate's default method) against closed-form integrals."""

import numpy as np
import pytest

from jaxdobby.batch import collocation as gl

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
