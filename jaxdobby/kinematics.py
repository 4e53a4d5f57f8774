"""Rigid kinematics of the dobby's lifting chain: crank-rocker, bending arm, double-rocker, frame.

The chain (DESIGN.md §1, §2 item 3, §6), planar, x horizontal, y up, origin at the arm pivot B0:

1. the eccentric (crank, link 8) turns about A0; its pin Q = A0 + e(cos φ, sin φ);
2. the ring link 9 (length L9) ties Q to the arm joint J = A(θ)·r_J on the bending arm 10, which
   turns about B0; θ is the inertial angle of the arm's body x axis (its first straight segment);
3. link 11 (length L11) ties the link-11 joint P = A(θ)·p(s) — p(s) the arm's centre line at arc
   length s — to the big blade's input-arm pin C, on a circle of radius r_in about D0;
   the blade angle β is the inertial angle of D0 → C (π/2 at mid-shed);
4. the blade's output arm (length r_out, at β − π/2) ends at E; the tumbler 13 (length L13)
   hangs from E to the heald frame, guided on the vertical x = x_g:
   y_H = E_y − sqrt(L13² − (x_g − E_x)²).

A(θ) is the 2-D rotation by θ. The functions here are position-level: they take the crank
angle, the arm angle, or — for the flexible model — any inertial position P of the link-11
joint. Motion in time (the modulator, θ(t), y_H(t) and their rates by forward-mode autodiff) is
in :mod:`jaxdobby.rigid_motion`; the stroke and its inverse in :mod:`jaxdobby.stroke`.

Conventions: branches (assembly modes, see :mod:`jaxdobby.linkage`): the arm joint J lies right
of the directed line B0 → Q (``ring_branch = −1``), the blade pin C right of D0 → P
(``blade_branch = −1``). The crank-rocker's *extended* dead centre (|J − A0| = L9 + e) gives the
smallest arm angle (81.74°) and the heald frame's **bottom**; the folded one (L9 − e) the largest
(125.79°) and the top. Increasing θ lifts the frame. The rigid motion puts t = 0 in the middle of
the bottom dwell.

Example (rigid heald-frame motion at 800 r/min)::

    import jax, jax.numpy as jnp
    jax.config.update("jax_enable_x64", True)
    from jaxdobby.kinematics import DobbyLinkage
    from jaxdobby.modulator import cycle_period
    from jaxdobby.rigid_motion import arm_motion, heald_frame_motion
    from jaxdobby.units import rpm_to_rad_s

    linkage = DobbyLinkage.default()
    speed = jnp.asarray(rpm_to_rad_s(800.0))             # loom main shaft [rad/s]
    t = jnp.linspace(0.0, cycle_period(speed), 4001)      # one heald-frame cycle, 0.15 s
    y, v, a = heald_frame_motion(linkage, t, speed)       # [m], [m/s], [m/s²]
    y.max() - y.min()          # 0.14007 m stroke (bottom at t = 0, top at t = T/2)
    jnp.abs(v).max()           # 7.33 m/s
    jnp.abs(a).max()           # 645 m/s²
    theta, omega, alpha = arm_motion(linkage, t, speed)
    jnp.abs(omega).max()       # 38.94 rad/s
    jnp.abs(alpha).max()       # 3340 rad/s²
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._arrays import as_float
from ._x64 import require_x64
from .centreline import CentreLine
from .linkage import circle_intersection, circles_intersect, rocker_angle
from .motion_laws import DEFAULT_MOTION_LAW, motion_law
from .units import DEG, MM

_ORIGIN = np.zeros(2)  # the arm pivot B0 (numpy: importing must not start a JAX backend)


def rotate(angle, vector):
    """A(angle)·vector: planar rotation, counter-clockwise positive.

    ``angle`` has shape ``(...)``, ``vector`` ``(..., 2)``; they broadcast over the leading axes.
    """
    c, s = jnp.cos(angle), jnp.sin(angle)
    x, y = vector[..., 0], vector[..., 1]
    return jnp.stack([c * x - s * y, s * x + c * y], axis=-1)


class DobbyLinkage(eqx.Module):
    """Geometry of the lifting chain and its modulator (DESIGN.md §6), SI units.

    Attributes:
        arm: centre line of the bending arm 10 in its body frame (origin at the pivot B0, first
            segment along +x) [m].
        eccentric_axis: A0, the eccentric's axis of rotation [m], shape (2,).
        eccentricity: e, crank radius of the eccentric 8 [m].
        ring_link_length: L9 [m].
        ring_joint_arc_length: arc length of the ring-link joint on the arm's centre line [m].
        link11_arc_length: arc length s of the link-11 joint on the arm (the stroke setting) [m].
        link11_length: L11 [m].
        blade_pivot: D0, the big blade's pivot [m], shape (2,).
        blade_input_arm: r_in, D0 to the link-11 pin C [m].
        blade_output_arm: r_out, D0 to the tumbler joint E [m].
        blade_output_offset: angle of the output arm minus that of the input arm [rad].
        tumbler_length: L13 [m].
        frame_guide_x: x of the heald frame's vertical guide [m].
        slot_start, slot_end: arc lengths bounding the stroke-adjustment slot [m].
        dwell: modulator dwell per pick, in loom (main-shaft) angle [rad].
        motion_law: name of the modulator's index law (see :mod:`jaxdobby.motion_laws`).
        ring_branch, blade_branch: assembly modes ±1 (see module docstring).
    """

    arm: CentreLine
    eccentric_axis: Array = eqx.field(converter=as_float)
    eccentricity: Array = eqx.field(converter=as_float)
    ring_link_length: Array = eqx.field(converter=as_float)
    ring_joint_arc_length: Array = eqx.field(converter=as_float)
    link11_arc_length: Array = eqx.field(converter=as_float)
    link11_length: Array = eqx.field(converter=as_float)
    blade_pivot: Array = eqx.field(converter=as_float)
    blade_input_arm: Array = eqx.field(converter=as_float)
    blade_output_arm: Array = eqx.field(converter=as_float)
    blade_output_offset: Array = eqx.field(converter=as_float)
    tumbler_length: Array = eqx.field(converter=as_float)
    frame_guide_x: Array = eqx.field(converter=as_float)
    slot_start: Array = eqx.field(converter=as_float)
    slot_end: Array = eqx.field(converter=as_float)
    dwell: Array = eqx.field(converter=as_float)
    motion_law: str = eqx.field(static=True, default=DEFAULT_MOTION_LAW)
    ring_branch: int = eqx.field(static=True, default=-1)
    blade_branch: int = eqx.field(static=True, default=-1)

    def __check_init__(self):
        motion_law(self.motion_law)  # raises ValueError naming the valid laws

    @classmethod
    def default(cls, **overrides) -> "DobbyLinkage":
        """The default machine of DESIGN.md §6 (fixed numbers, mm and degrees converted to SI).

        Keyword ``overrides`` replace fields by name (SI values), e.g. ``dwell=deg_to_rad(80)``.
        """
        require_x64()
        arc_turn = 13.75 * DEG
        arc_start = 105.0 * MM
        arc_end = arc_start + 400.0 * MM * arc_turn  # ≈ 0.201 m
        fields = dict(
            arm=CentreLine.from_segments(
                [("line", arc_start), ("arc", 400.0 * MM, -arc_turn), ("line", 25.0 * MM)]
            ),
            eccentric_axis=np.array([-192.5, 29.3]) * MM,
            eccentricity=30.0 * MM,
            ring_link_length=180.0 * MM,
            ring_joint_arc_length=80.0 * MM,
            link11_arc_length=arc_end,
            link11_length=400.0 * MM,
            blade_pivot=np.array([363.6, 37.1]) * MM,
            blade_input_arm=160.0 * MM,
            blade_output_arm=152.0 * MM,
            blade_output_offset=-0.5 * math.pi,
            tumbler_length=500.0 * MM,
            frame_guide_x=515.6 * MM,
            slot_start=arc_start,
            slot_end=arc_end,
            dwell=100.0 * DEG,
        )
        fields.update(overrides)
        return cls(**fields)

    def replace(self, **changes) -> "DobbyLinkage":
        """A copy with some fields changed, e.g. ``linkage.replace(eccentricity=0.031)``.

        Goes through the field converters, so plain Python floats become float64 arrays and a
        jitted function sees the same types (no retrace). Prefer it to ``eqx.tree_at`` with
        Python numbers, which would bypass the converters.
        """
        return dataclasses.replace(self, **changes)


def with_link11_arc_length(linkage: DobbyLinkage, s) -> DobbyLinkage:
    """A copy of ``linkage`` with the link-11 joint at arc length ``s`` [m]."""
    return linkage.replace(link11_arc_length=s)


# --- crank-rocker 8-9-10 --------------------------------------------------------------------


def _ring_joint_body(linkage: DobbyLinkage) -> Array:
    """Body-frame position r_J of the ring-link joint on the arm [m]."""
    return linkage.arm.point(linkage.ring_joint_arc_length)


def _eccentric_pin(linkage: DobbyLinkage, crank_angle) -> Array:
    """Q = A0 + e(cos φ, sin φ) [m], shape ``φ.shape + (2,)``."""
    phi = jnp.asarray(crank_angle, dtype=float)
    return linkage.eccentric_axis + linkage.eccentricity * jnp.stack(
        [jnp.cos(phi), jnp.sin(phi)], axis=-1
    )


def arm_angle_from_crank(linkage: DobbyLinkage, crank_angle) -> Array:
    """Arm angle θ [rad] for eccentric angle φ [rad]: the crank-rocker 8-9-10 loop closure.

    θ = angle(J) − angle(r_J), J the meeting point of the circles (B0, |r_J|) and (Q, L9).
    """
    r_j = _ring_joint_body(linkage)
    q = _eccentric_pin(linkage, crank_angle)
    joint_angle = rocker_angle(
        q, linkage.ring_link_length, _ORIGIN, jnp.linalg.norm(r_j), linkage.ring_branch
    )
    return joint_angle - jnp.arctan2(r_j[1], r_j[0])


def ring_link_direction_from_crank(linkage: DobbyLinkage, crank_angle) -> Array:
    """Unit vector (inertial) along the ring link from the eccentric pin Q to the arm joint J.

    Shape ``φ.shape + (2,)``; the axial force of the ring link acts on the arm along it.
    """
    q = _eccentric_pin(linkage, crank_angle)
    j = circle_intersection(
        _ORIGIN,
        jnp.linalg.norm(_ring_joint_body(linkage)),
        q,
        linkage.ring_link_length,
        linkage.ring_branch,
    )
    d = j - q
    return d / jnp.linalg.norm(d, axis=-1, keepdims=True)


def dead_centres(linkage: DobbyLinkage) -> tuple[tuple[Array, Array], tuple[Array, Array]]:
    """Crank and arm angles [rad] at the crank-rocker's two dead centres.

    At a dead centre crank and ring link are collinear, so |J − A0| = L9 + e (extended) or
    L9 − e (folded) and θ is extreme (Norton 2020, §4.12, toggle positions). J is the meeting
    point of the circles (B0, |r_J|) and (A0, L9 ± e) — on the same side of B0 → A0 as of
    B0 → Q, since Q lies on the line A0J.

    Returns:
        ``((phi_extended, phi_folded), (theta_extended, theta_folded))``. For the default machine
        φ_folded − φ_extended = 179.989° (centric to 0.011°) and θ = 81.74° / 125.79°.
    """
    r_j = _ring_joint_body(linkage)
    radius = jnp.linalg.norm(r_j)
    offset = jnp.arctan2(r_j[1], r_j[0])
    a0, e, l9 = linkage.eccentric_axis, linkage.eccentricity, linkage.ring_link_length
    j_ext = circle_intersection(_ORIGIN, radius, a0, l9 + e, linkage.ring_branch)
    j_fold = circle_intersection(_ORIGIN, radius, a0, l9 - e, linkage.ring_branch)
    phi_ext = jnp.arctan2(j_ext[1] - a0[1], j_ext[0] - a0[0])
    phi_fold = jnp.arctan2(a0[1] - j_fold[1], a0[0] - j_fold[0])
    phi_fold = phi_ext + jnp.mod(phi_fold - phi_ext, 2.0 * math.pi)  # the next one, CCW
    theta_ext = jnp.arctan2(j_ext[1], j_ext[0]) - offset
    theta_fold = jnp.arctan2(j_fold[1], j_fold[0]) - offset
    return (phi_ext, phi_fold), (theta_ext, theta_fold)


# --- arm 10 → double-rocker 10-11-12 → tumbler 13 → heald frame 16 -----------------------------


def link11_joint_body(linkage: DobbyLinkage, s=None) -> Array:
    """Body-frame position p(s) [m] of the link-11 joint (default s: ``link11_arc_length``)."""
    return linkage.arm.point(linkage.link11_arc_length if s is None else s)


def link11_joint_position(linkage: DobbyLinkage, arm_angle, s=None) -> Array:
    """Inertial position P = A(θ)·p(s) [m] of the link-11 joint on the rigid arm.

    Shape ``broadcast(θ.shape, s.shape) + (2,)``.
    """
    theta = jnp.asarray(arm_angle, dtype=float)
    p = link11_joint_body(linkage, s)
    return rotate(theta, p)


def blade_angle(linkage: DobbyLinkage, joint_position) -> Array:
    """Big-blade angle β [rad] (inertial angle of D0 → C) for link-11 joint position P [m].

    P is any inertial point (rigid or deformed arm), shape ``(..., 2)``; the double-rocker loop
    closes where the circles (D0, r_in) and (P, L11) meet. β = π/2 at mid-shed (input arm up).
    """
    return rocker_angle(
        jnp.asarray(joint_position, dtype=float),
        linkage.link11_length,
        linkage.blade_pivot,
        linkage.blade_input_arm,
        linkage.blade_branch,
    )


def blade_reachable(linkage: DobbyLinkage, joint_position) -> Array:
    """True where link 11 can reach the blade pin from P [m], ``(..., 2)`` (the loop closes).

    Where it is False, :func:`blade_angle` returns the clamped (tangent) configuration — finite
    but not a solution — so check this when P comes from a large deformation.
    """
    return circles_intersect(
        linkage.blade_pivot,
        linkage.blade_input_arm,
        jnp.asarray(joint_position, dtype=float),
        linkage.link11_length,
    )


def heald_frame_height_from_blade(linkage: DobbyLinkage, blade_angle) -> Array:
    """Heald-frame height y_H [m] (positive up, from B0's level) for blade angle β [rad].

    E = D0 + r_out(cos, sin)(β + offset); y_H = E_y − sqrt(L13² − (x_g − E_x)²).
    """
    gamma = jnp.asarray(blade_angle, dtype=float) + linkage.blade_output_offset
    ex = linkage.blade_pivot[0] + linkage.blade_output_arm * jnp.cos(gamma)
    ey = linkage.blade_pivot[1] + linkage.blade_output_arm * jnp.sin(gamma)
    return ey - jnp.sqrt(linkage.tumbler_length**2 - (linkage.frame_guide_x - ex) ** 2)


def heald_frame_height(linkage: DobbyLinkage, joint_position) -> Array:
    """Heald-frame height y_H [m] for an inertial link-11 joint position P [m], ``(..., 2)``.

    This is the downstream chain G(P) of the rigid–flexible coupling (DESIGN.md §2 item 5): feed
    it the deformed position of the joint.
    """
    return heald_frame_height_from_blade(linkage, blade_angle(linkage, joint_position))


def heald_frame_height_from_arm(linkage: DobbyLinkage, arm_angle, s=None) -> Array:
    """Heald-frame height y_H [m] for the rigid arm at angle θ [rad], joint at arc length s [m]."""
    return heald_frame_height(linkage, link11_joint_position(linkage, arm_angle, s))
