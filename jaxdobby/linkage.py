"""Planar loop closures: circle–circle intersection and the four-bar output angle.

A planar four-bar (ground, input link, coupler, output link) closes where two circles meet: the
circle of the output link's end about its ground pivot and the circle of the coupler's length
about the input link's end. Both functions are pure, elementwise over leading batch axes
(points are arrays of shape ``(..., 2)``), jittable, vmappable and differentiable.

**Branch (assembly mode).** Two circles meet in two points, mirror images in the line through
the centres. ``branch = +1`` picks the point on the *left* of the directed line from
``centre_a`` to ``centre_b`` (counter-clockwise side: (b − a) × (p − a) > 0), ``branch = −1``
the point on its right. The branch is an ordinary (possibly traced) number, so it never forces a
retrace; a mechanism that does not pass through a singular (folded) position keeps its branch over
the whole cycle.

**Reachability.** The circles meet iff |r_a − r_b| ≤ d ≤ r_a + r_b (d the distance between the
centres). The intersection uses h = sqrt(r_a² − x²) for the half-chord; h² is clamped at 0
through a double-``where`` guard, so a just-reachable configuration (h = 0, tangent circles)
returns the tangent point with finite gradients (the true dh/dd is infinite there; the guard
returns 0 for it) instead of NaN. An *unreachable* configuration returns the same clamped point
— finite but wrong — so check it with :func:`circles_intersect` (or
:func:`intersection_margin` ≥ 0) wherever the input may leave the workspace.

Reference: the closed-form intersection is the standard one, e.g. Norton, *Design of Machinery*,
6th ed., 2020, §4.5 (four-bar position analysis by vector loops; here solved geometrically).
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

_TINY = 1e-300  # keeps sqrt's argument positive in the branch that is not taken


def _cross(u, v):
    """z component of the planar cross product u × v, over the last axis."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def intersection_margin(centre_a, radius_a, centre_b, radius_b, *, axis: int = -1) -> Array:
    """Squared half-chord h² [m²] of two circles; ≥ 0 iff they meet.

    With d = |b − a| and x = (d² + r_a² − r_b²)/(2d) the distance from a to the chord's foot,
    h² = r_a² − x² (Norton 2020, §4.5). Its sign is the reachability test; its size says how far
    from the tangent (dead-centre) configuration the loop is. ``axis``: the centres' coordinate
    axis, as :func:`circle_intersection`'s.
    """
    a, b = jnp.asarray(centre_a), jnp.asarray(centre_b)
    d = jnp.linalg.norm(b - a, axis=axis)
    x = (d**2 + radius_a**2 - radius_b**2) / (2.0 * d)
    return radius_a**2 - x**2


def circles_intersect(centre_a, radius_a, centre_b, radius_b, *, tol=1e-12) -> Array:
    """True where the circles meet, i.e. the loop can close: h² ≥ −tol [m²]."""
    return intersection_margin(centre_a, radius_a, centre_b, radius_b) >= -tol


def circle_intersection(centre_a, radius_a, centre_b, radius_b, branch, *, axis: int = -1
                        ) -> Array:
    """Intersection point [m] of circle (centre_a, radius_a) and circle (centre_b, radius_b).

    p = a + x·û + branch·h·n̂, with û = (b − a)/d, n̂ = û rotated +90°, x and h as in
    :func:`intersection_margin`.

    Args:
        centre_a, centre_b: centres [m], shape ``(..., 2)``.
        radius_a, radius_b: radii [m], broadcastable to ``(...)``.
        branch: +1 for the point left of the directed line a → b, −1 for the right one.
        axis: the centres' coordinate axis (the last by default; 0 for (2, lanes...) arrays
            with the batch's lanes last, as :mod:`jaxdobby.periodic.steady` runs a batch).

    Returns:
        The point, shape ``(..., 2)`` (its coordinates on ``axis``). For circles that do not
        meet, h is clamped to 0 (the point on the line of centres); test with
        :func:`circles_intersect`.
    """
    a, b = jnp.asarray(centre_a), jnp.asarray(centre_b)
    ab = b - a
    d = jnp.linalg.norm(ab, axis=axis)
    u = ab / jnp.expand_dims(d, axis)
    n = jnp.stack([-jnp.take(u, 1, axis=axis), jnp.take(u, 0, axis=axis)], axis=axis)
    x = (d**2 + radius_a**2 - radius_b**2) / (2.0 * d)
    h2 = radius_a**2 - x**2
    positive = h2 > _TINY
    h = jnp.where(positive, jnp.sqrt(jnp.where(positive, h2, 1.0)), 0.0)
    return a + jnp.expand_dims(x, axis) * u + jnp.expand_dims(branch * h, axis) * n


def rocker_angle(coupler_end, coupler_length, pivot, rocker_length, branch) -> Array:
    """Angle [rad] of a rocker (pivot, length) tied to a given point by a coupler.

    The rocker's end R lies on the circle (pivot, rocker_length) and on the circle
    (coupler_end, coupler_length); the returned angle is atan2 of R − pivot, in (−π, π].

    Args:
        coupler_end: the coupler's other end [m], shape ``(..., 2)`` (any point: a crank pin,
            or a point on a deformed link).
        coupler_length: [m].
        pivot: the rocker's ground pivot [m], shape ``(2,)`` or ``(..., 2)``.
        rocker_length: [m], distance pivot → rocker end.
        branch: ±1, side of the directed line pivot → coupler_end on which the rocker end lies.
    """
    end = circle_intersection(pivot, rocker_length, coupler_end, coupler_length, branch)
    rel = end - pivot
    return jnp.arctan2(rel[..., 1], rel[..., 0])


def four_bar_output_angle(
    input_angle,
    *,
    input_pivot,
    input_length,
    coupler_length,
    output_pivot,
    output_length,
    branch,
) -> Array:
    """Output-link angle [rad] of a planar four-bar from its input-link angle [rad].

    The input link's end is input_pivot + input_length·(cos, sin)(input_angle); the output angle
    is :func:`rocker_angle` of that point. Angles are inertial, from the +x axis.

    Args:
        input_angle: [rad], any shape ``(...)``.
        input_pivot, output_pivot: ground pivots [m], shape ``(2,)``.
        input_length, coupler_length, output_length: link lengths [m] (pivot to joint).
        branch: ±1, see :func:`rocker_angle`.
    """
    input_angle = jnp.asarray(input_angle, dtype=float)
    tip = jnp.asarray(input_pivot) + input_length * jnp.stack(
        [jnp.cos(input_angle), jnp.sin(input_angle)], axis=-1
    )
    return rocker_angle(tip, coupler_length, output_pivot, output_length, branch)


def four_bar_closes(
    input_angle, *, input_pivot, input_length, coupler_length, output_pivot, output_length
) -> Array:
    """True where the four-bar can be assembled at this input angle (:func:`circles_intersect`)."""
    input_angle = jnp.asarray(input_angle, dtype=float)
    tip = jnp.asarray(input_pivot) + input_length * jnp.stack(
        [jnp.cos(input_angle), jnp.sin(input_angle)], axis=-1
    )
    return circles_intersect(output_pivot, output_length, tip, coupler_length)
