"""The downstream chain of :mod:`jaxdobby.dobby` in closed form, without trigonometric functions.

:func:`jaxdobby.dobby.chain_kinematics` differentiates the closure c = C(P) = (β, y_H) by
forward-mode autodiff through ``atan2``, ``sin`` and ``cos``; on a CPU those dominate the cost of
the coupled equations. Here the same quantities come from the geometry of the two loops directly
(circle intersection and square roots only), for one instant:

* **Blade.** r = pin − D0 (|r| = r_in) and ℓ = pin − P (|ℓ| = L11), with the pin from
  :func:`jaxdobby.linkage.circle_intersection` (the same branch). Differentiating |ℓ|² = L11²
  with ṙ = β̇ S r gives

      β̇ = ℓ·Ṗ / (ℓ·S r),   β̈ = (ℓ·P̈ + β̇² ℓ·r − |ℓ̇|²) / (ℓ·S r),   ℓ̇ = β̇ S r − Ṗ,

  so ∇_P β = ℓ / (ℓ·S r) (the partial velocity of β with respect to P).
* **Tumbler and frame.** The tumbler joint is E = D0 + (r_out/r_in) R(offset) r, which turns with
  the blade (dE/dβ = S e, d²E/dβ² = −e, e = E − D0), and y_H = E_y − √(L13² − d²),
  d = x_g − E_x, so y' = dy_H/dβ = d e_y/s + e_x and y'' = L13² e_y²/s³ + d e_x/s − e_y with
  s = √(L13² − d²).

With D = diag(J_b, m_H), the chain's kinetic energy is ½ μ β̇², μ = J_b + m_H y'², and Kane's
terms of :func:`jaxdobby.dobby.equations_at` become rank one: with g = Φ_Pᵀ Aᵀ ∇_P β (so
β̇ = g·q̇ + rigid part) and β̈ = g·q̈ + h_β,

    mass  += μ g gᵀ,     force += g φ,     φ = y' Q_y − μ h_β − m_H y' y'' β̇²,

Q_y = −m_H g_0 + F_warp(y_H) (identical to G_qᵀ D G_q and G_qᵀ(Q − D h) there, since
G_q = [gᵀ; y' gᵀ] and h = (h_β, y' h_β + y'' β̇²)). At q = 0 the force of link 11 on the arm by
rigid inverse dynamics is ∇_P β φ (:func:`jaxdobby.dobby.rigid_state`). The tests compare
everything with :func:`jaxdobby.dobby.chain_kinematics` and :func:`~jaxdobby.dobby.rigid_state`.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from ..dobby import LINK, DobbyModel
from ..linkage import circle_intersection, intersection_margin


class Downstream(eqx.Module):
    """What the chain needs of one model (SI units; shapes () unless said).

    Attributes:
        rows: Φ_P, body-frame displacement of the link-11 joint per modal coordinate, (2, k).
        joint: p, body-frame position of the link-11 joint on the undeformed arm [m], (2,).
        blade_pivot: D0 [m], (2,). input_arm: r_in [m]. link_length: L11 [m].
        output: (r_out/r_in)·(cos, sin) of the output-arm offset [-], (2,).
        tumbler: L13 [m]. guide_x: x_g [m].
        frame_mass: m_H [kg]. blade_inertia: J_b [kg·m²]. gravity: g_0 [m/s²].
        warp_peak: F_w [N]. mid_level: y_H at mid-stroke [m]. half_stroke: H/2 [m].
        branch: assembly mode of the double-rocker (±1, static). warp_law: static.
    """

    rows: Array
    joint: Array
    blade_pivot: Array
    input_arm: Array
    link_length: Array
    output: Array
    tumbler: Array
    guide_x: Array
    frame_mass: Array
    blade_inertia: Array
    gravity: Array
    warp_peak: Array
    mid_level: Array
    half_stroke: Array
    branch: int = eqx.field(static=True)
    warp_law: str = eqx.field(static=True)


def downstream(model: DobbyModel) -> Downstream:
    """The chain's constants for ``model`` (see :class:`Downstream`)."""
    ch, m = model.chain, model.machine
    ratio = ch.blade_output_arm / ch.blade_input_arm
    return Downstream(
        rows=model.body.points[LINK], joint=model.link_joint, blade_pivot=ch.blade_pivot,
        input_arm=ch.blade_input_arm, link_length=ch.link11_length,
        output=ratio * jnp.stack([jnp.cos(ch.blade_output_offset), jnp.sin(ch.blade_output_offset)]),
        tumbler=ch.tumbler_length, guide_x=ch.frame_guide_x, frame_mass=m.heald_frame_mass,
        blade_inertia=m.blade_inertia, gravity=m.gravity, warp_peak=model.operating.warp_force,
        mid_level=model.mid_level, half_stroke=0.5 * model.stroke, branch=ch.blade_branch,
        warp_law=m.warp_law)


class Frame(NamedTuple):
    """The arm frame at one instant: cos θ, sin θ [-], ω [rad/s], α [rad/s²], and the phase
    τ = t/T [-] of the cycle (for the ``opposing`` warp law)."""

    cos: Array
    sin: Array
    omega: Array
    alpha: Array
    phase: Array


class ChainTerms(NamedTuple):
    """The chain at one instant (see the module docstring).

    Attributes:
        g: partial velocity of β with respect to q̇, (k,) [rad/unit of q].
        phi: generalised chain force on β without the q̈ term [N·m].
        mu: inertia on β, J_b + m_H y'² [kg·m²].
        h_beta: β̈ − g·q̈ [rad/s²].
        beta_rate: β̇ [rad/s].
        slope, curvature: y' [m/rad] and y'' [m/rad²].
        height: y_H [m].
        grad_body: ∇_P β in the arm's body frame [rad/m], (2,).
    """

    g: Array
    phi: Array
    mu: Array
    h_beta: Array
    beta_rate: Array
    slope: Array
    curvature: Array
    height: Array
    grad_body: Array


def warp_force(ds: Downstream, height, phase) -> Array:
    """Warp-yarn force on the heald frame [N, up], as :func:`jaxdobby.dobby.warp_force`."""
    offset = (height - ds.mid_level) / ds.half_stroke
    if ds.warp_law == "restoring":
        return -ds.warp_peak * offset
    return -ds.warp_peak * jnp.abs(offset) * jnp.where(phase < 0.5, 1.0, -1.0)


def chain_terms(ds: Downstream, frame: Frame, u: Array, u_rate: Array) -> ChainTerms:
    """The chain driven by the deformed arm, for elastic joint displacement u = Φ_P q and its
    rate u̇ = Φ_P q̇ (body frame [m], [m/s], each (2,)). Every array may carry trailing lane
    axes (a batch with its lanes last): vector components are indexed on the first axis."""
    c, s, om, al = frame.cos, frame.sin, frame.omega, frame.alpha
    r0, r1 = ds.joint[0] + u[0], ds.joint[1] + u[1]
    ud0, ud1 = u_rate[0], u_rate[1]
    rot = lambda x, y: (c * x - s * y, s * x + c * y)  # noqa: E731  (A(θ)·(x, y))
    p = jnp.stack(rot(r0, r1))
    pd0, pd1 = rot(-om * r1 + ud0, om * r0 + ud1)
    pdd0, pdd1 = rot(-2.0 * om * ud1 - al * r1 - om**2 * r0, 2.0 * om * ud0 + al * r0 - om**2 * r1)
    d0 = ds.blade_pivot
    pin = circle_intersection(d0, ds.input_arm, p, ds.link_length, ds.branch, axis=0)
    b0, b1 = pin[0] - d0[0], pin[1] - d0[1]  # r
    l0, l1 = pin[0] - p[0], pin[1] - p[1]  # ℓ
    den = l1 * b0 - l0 * b1  # ℓ·S r
    beta_rate = (l0 * pd0 + l1 * pd1) / den
    ld0, ld1 = -beta_rate * b1 - pd0, beta_rate * b0 - pd1
    h_beta = (l0 * pdd0 + l1 * pdd1 + beta_rate**2 * (l0 * b0 + l1 * b1) - ld0**2 - ld1**2) / den
    grad_body = jnp.stack([c * l0 + s * l1, -s * l0 + c * l1]) / den
    # Φ_Pᵀ ∇_P β, unrolled (no batched dot under vmap; see jaxdobby.periodic.collocation.matmul)
    g = ds.rows[0] * grad_body[0] + ds.rows[1] * grad_body[1]
    co, so = ds.output[0], ds.output[1]
    e0, e1 = co * b0 - so * b1, so * b0 + co * b1
    dx = ds.guide_x - (d0[0] + e0)
    root = jnp.sqrt(ds.tumbler**2 - dx**2)
    height = d0[1] + e1 - root
    slope = dx * e1 / root + e0
    curvature = ds.tumbler**2 * e1**2 / root**3 + dx * e0 / root - e1
    mu = ds.blade_inertia + ds.frame_mass * slope**2
    force = -ds.frame_mass * ds.gravity + warp_force(ds, height, frame.phase)
    phi = slope * force - mu * h_beta - ds.frame_mass * slope * curvature * beta_rate**2
    return ChainTerms(g=g, phi=phi, mu=mu, h_beta=h_beta, beta_rate=beta_rate, slope=slope,
                      curvature=curvature, height=height, grad_body=grad_body)


def chain_reachable(ds: Downstream, frame: Frame, u: Array) -> Array:
    """True where both loops of the chain close for the deformed joint (else the terms above are
    those of the clamped, tangent configuration: finite but not a solution)."""
    c, s = frame.cos, frame.sin
    r0, r1 = ds.joint[0] + u[0], ds.joint[1] + u[1]
    p = jnp.stack([c * r0 - s * r1, s * r0 + c * r1])
    pin = circle_intersection(ds.blade_pivot, ds.input_arm, p, ds.link_length, ds.branch,
                              axis=0)
    b0, b1 = pin[0] - ds.blade_pivot[0], pin[1] - ds.blade_pivot[1]
    dx = ds.guide_x - (ds.blade_pivot[0] + ds.output[0] * b0 - ds.output[1] * b1)
    blade = intersection_margin(ds.blade_pivot, ds.input_arm, p, ds.link_length, axis=0) > 0.0
    return blade & (ds.tumbler**2 - dx**2 > 0.0)
