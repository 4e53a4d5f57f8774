"""Loop-closure primitives (jaxdobby.linkage) against hand-solved configurations."""

import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxdobby.linkage import (
    circle_intersection,
    circles_intersect,
    four_bar_closes,
    four_bar_output_angle,
    intersection_margin,
)


def test_circle_intersection_branches_3_4_5():
    # Circles of radius 5 about (0, 0) and (6, 0) meet at (3, ±4) (a 3-4-5 triangle).
    # +1 is the point left of the directed line a → b (here +x), i.e. (3, +4). Round-off only.
    a, b = jnp.array([0.0, 0.0]), jnp.array([6.0, 0.0])
    np.testing.assert_allclose(circle_intersection(a, 5.0, b, 5.0, 1), [3.0, 4.0], atol=1e-14)
    np.testing.assert_allclose(circle_intersection(a, 5.0, b, 5.0, -1), [3.0, -4.0], atol=1e-14)
    # Swapping the centres reverses the line's direction, hence the side.
    np.testing.assert_allclose(circle_intersection(b, 5.0, a, 5.0, 1), [3.0, -4.0], atol=1e-14)
    # The branch may be traced: one compiled function serves both assembly modes.
    f = jax.jit(circle_intersection)
    np.testing.assert_allclose(f(a, 5.0, b, 5.0, jnp.asarray(-1.0)), [3.0, -4.0], atol=1e-14)
    assert float(intersection_margin(a, 5.0, b, 5.0)) == 16.0  # h² = 4²


def test_batched_points_rotate_the_hand_solution():
    # The same triangle rotated by angles θ: the intersection rotates with it (elementwise API).
    theta = jnp.linspace(-3.0, 3.0, 13)
    u = jnp.stack([jnp.cos(theta), jnp.sin(theta)], axis=-1)
    n = jnp.stack([-jnp.sin(theta), jnp.cos(theta)], axis=-1)
    p = circle_intersection(jnp.zeros(2), 5.0, 6.0 * u, 5.0, 1)
    np.testing.assert_allclose(p, 3.0 * u + 4.0 * n, atol=1e-13)


def test_just_reachable_configuration_has_finite_gradients():
    # Tangent circles (radius 1 at the origin, radius 2 at (3, 0)) touch at (1, 0): h = 0.
    # The guard must give that point and finite (not NaN) derivatives.
    def px(bx):
        return circle_intersection(jnp.zeros(2), 1.0, jnp.array([bx, 0.0]), 2.0, 1)[0]

    assert float(px(3.0)) == 1.0
    grads = jax.jacobian(
        lambda b: circle_intersection(jnp.zeros(2), 1.0, b, 2.0, 1)
    )(jnp.array([3.0, 0.0]))
    assert bool(jnp.all(jnp.isfinite(grads)))
    # x = (d² + r_a² − r_b²)/(2d) → dx/dd = (1 + (r_b² − r_a²)/d²)/2 = (1 + 3/9)/2 = 2/3; the
    # foot of the chord is smooth at tangency, only dh/dd (infinite) is cut to 0 by the guard.
    assert math.isclose(float(jax.grad(px)(3.0)), 2.0 / 3.0, rel_tol=1e-14)

def test_unreachable_configurations_are_detected():
    a = jnp.zeros(2)
    # d = 4 > r_a + r_b = 3 (too far), d = 0.5 < |r_a − r_b| = 1 (one inside the other), and
    # the touching and crossing cases.
    centres = jnp.array([[4.0, 0.0], [0.5, 0.0], [3.0, 0.0], [2.0, 0.0]])
    np.testing.assert_array_equal(
        circles_intersect(a, 1.0, centres, 2.0), [False, False, True, True]
    )


def test_four_bar_parallelogram_copies_the_input_angle():
    # Parallelogram four-bar: ground 1 m, cranks 0.5 m, coupler 1 m. In the open (parallel)
    # assembly the output link stays parallel to the input one: output angle = input angle.
    # The output end R = tip + (1, 0) lies right of the line pivot → tip, so branch −1.
    phi = jnp.linspace(0.2, math.pi - 0.2, 25)
    kwargs = dict(
        input_pivot=jnp.array([0.0, 0.0]),
        input_length=0.5,
        coupler_length=1.0,
        output_pivot=jnp.array([1.0, 0.0]),
        output_length=0.5,
    )
    np.testing.assert_allclose(four_bar_output_angle(phi, branch=-1, **kwargs), phi, atol=1e-13)
    assert bool(jnp.all(four_bar_closes(phi, **kwargs)))
    # Too short a coupler cannot span the 1 m ground when the cranks point apart.
    assert not bool(four_bar_closes(math.pi, **{**kwargs, "coupler_length": 0.3}))
