"""Heald-frame stroke as a function of the link-11 joint's place on the arm, and its inverse.

The frame dwells at both extremes of its motion (the dwells sit on the crank-rocker's dead
centres, :mod:`jaxdobby.rigid_motion`), and y_H increases monotonically with the arm angle over
the swing, so the stroke — max − min of y_H over a cycle — is

    H(s) = y_H(θ_folded, s) − y_H(θ_extended, s),

θ the dead-centre arm angles (:func:`jaxdobby.kinematics.dead_centres`), s the arc length of the
link-11 joint on the arm's centre line. H is a smooth, increasing function of s.

**Reachable range.** The joint is clamped in the stroke-adjustment slot: the arm's circular arc,
from ``slot_start`` (0.105 m, arc start) to ``slot_end`` (≈ 0.201 m, arc end) for the default
machine — 77.26 … 140.07 mm of stroke. The straight tip beyond the arc would close the chain up to
s = 0.226 m (156 mm) but is not part of the slot: only on the arc, whose centre of curvature is
the blade pin at mid-shed, does the shed-crossing level stay put when the stroke is changed
(DESIGN.md §6), so the solver is limited to the slot. :func:`stroke_range` reports it.

**Inverse.** :func:`arc_length_for_stroke` solves H(s) = H* by Newton's method inside
``jax.lax.custom_root``, so its derivatives (with respect to H* and to every linkage field) come
from the implicit-function theorem, ds/dp = −(∂H/∂s)⁻¹ ∂H/∂p, not from unrolling the iterations.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .kinematics import (
    DobbyLinkage,
    dead_centres,
    heald_frame_height_from_arm,
    with_link11_arc_length,
)
from .units import m_to_mm

_NEWTON_STEPS = 8  # H(s) is nearly linear; from the secant guess 4 steps reach 1e-15 m
_RANGE_TOL = 1e-9  # [m] slack on the range check, far below any stroke setting's precision


@eqx.filter_jit
def stroke(linkage: DobbyLinkage, s=None) -> Array:
    """Heald-frame stroke H [m] with the link-11 joint at arc length ``s`` [m] (any shape).

    Default ``s``: ``linkage.link11_arc_length``. Jitted (inlined when called under ``jit``), as
    it is often called eagerly, e.g. by the range check.
    """
    _, (theta_bottom, theta_top) = dead_centres(linkage)
    return heald_frame_height_from_arm(linkage, theta_top, s) - heald_frame_height_from_arm(
        linkage, theta_bottom, s
    )


@eqx.filter_jit
def stroke_range(linkage: DobbyLinkage) -> tuple[Array, Array]:
    """Smallest and largest stroke [m] the slot allows (H at the slot's two ends)."""
    at_start, at_end = stroke(linkage, linkage.slot_start), stroke(linkage, linkage.slot_end)
    return jnp.minimum(at_start, at_end), jnp.maximum(at_start, at_end)


def _concrete(x):
    """``x`` as a numpy array, or None while it is being traced (jit, vmap, grad)."""
    try:
        return np.asarray(x)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return None


def _check_reachable(linkage: DobbyLinkage, target: Array) -> None:
    """Raise ``ValueError`` naming the range in mm if a concrete target stroke is unreachable."""
    lo, hi = stroke_range(linkage)
    values = [_concrete(x) for x in (target, lo, hi, linkage.slot_start, linkage.slot_end)]
    if any(v is None for v in values):
        return  # traced: checked at run time by eqx.error_if in arc_length_for_stroke
    target, lo, hi, s_lo, s_hi = values
    bad = ~((target >= lo - _RANGE_TOL) & (target <= hi + _RANGE_TOL))
    if np.any(bad):
        worst = np.atleast_1d(target)[np.atleast_1d(bad)][0]
        raise ValueError(
            f"stroke {m_to_mm(worst):.2f} mm is outside the reachable range "
            f"{m_to_mm(lo):.2f} … {m_to_mm(hi):.2f} mm (link-11 joint in the slot at arc length "
            f"{m_to_mm(s_lo):.1f} … {m_to_mm(s_hi):.1f} mm)"
        )


def arc_length_for_stroke(linkage: DobbyLinkage, target_stroke, *, check: bool = True) -> Array:
    """Arc length s [m] of the link-11 joint that gives the heald-frame stroke ``target_stroke``.

    ``target_stroke`` [m], elementwise (any shape). Newton iterations in ``lax.fori_loop`` from the
    secant guess between the slot ends; derivatives by the implicit-function theorem
    (``jax.lax.custom_root``). Compiled once per shape (also when called eagerly).

    Raises:
        ValueError: for a concrete target outside :func:`stroke_range` (the message gives the
            range in mm). Under ``jit``/``vmap`` with traced values the same check runs through
            ``eqx.error_if`` and fails at run time. ``check=False`` leaves both checks out (the
            caller clips or flags unreachable targets itself): ``eqx.error_if`` is a host
            callback, and host callbacks inside a program sharded over several CPU devices
            can stall it.
    """
    target = jnp.asarray(target_stroke, dtype=float)
    if not check:
        return _solve(linkage, target, False)
    _check_reachable(linkage, target)
    return _solve(linkage, target, True)


@eqx.filter_jit
def _solve(linkage: DobbyLinkage, target: Array, check: bool) -> Array:
    """Newton on H(s) = target inside ``custom_root``; flags unreachable targets at run time."""
    s_lo, s_hi = linkage.slot_start, linkage.slot_end
    h_at_lo, h_at_hi = stroke(linkage, s_lo), stroke(linkage, s_hi)
    guess = s_lo + (s_hi - s_lo) * (target - h_at_lo) / (h_at_hi - h_at_lo)  # secant

    def residual(s):
        return stroke(linkage, s) - target

    def newton(f, s0):
        def step(_, s):
            value, slope = jax.jvp(f, (s,), (jnp.ones_like(s),))
            return jnp.clip(s - value / slope, s_lo, s_hi)

        return jax.lax.fori_loop(0, _NEWTON_STEPS, step, s0)

    def tangent_solve(g, y):
        return y / g(jnp.ones_like(y))  # g is diagonal: the residual is elementwise in s

    s = jax.lax.custom_root(residual, guess, newton, tangent_solve)
    if not check:
        return s
    h_lo, h_hi = jnp.minimum(h_at_lo, h_at_hi), jnp.maximum(h_at_lo, h_at_hi)
    unreachable = (target < h_lo - _RANGE_TOL) | (target > h_hi + _RANGE_TOL)
    return eqx.error_if(
        s, unreachable, "target stroke outside the reachable range: see stroke_range(linkage)"
    )


def with_stroke(linkage: DobbyLinkage, target_stroke) -> DobbyLinkage:
    """A copy of ``linkage`` with the link-11 joint moved to give ``target_stroke`` [m]."""
    return with_link11_arc_length(linkage, arc_length_for_stroke(linkage, target_stroke))
