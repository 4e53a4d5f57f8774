"""The rotary dobby's lifting mechanism as one parameter set, and its default (DESIGN.md §6).

:class:`Machine` gathers everything that defines the mechanism — the bending arm
(:class:`~jaxdobby.arm.ArmDesign`), the linkage geometry and modulator
(:class:`~jaxdobby.kinematics.DobbyLinkage`), the downstream inertia, the ring link's stiffness,
the warp-force law, damping and the number of modes — and :class:`OperatingPoint` the loom's
speed and the peak warp force. Both are ``equinox`` modules of float64 arrays: vmappable,
differentiable, and never recompiled for new values. Sizes and choices (modes, coupling, warp
law) are static fields.

Default machine (DESIGN.md §6; each number's reason is documented there and in the README):

=====================  ===============================================================
heald frame            12 kg (frame, healds, links 14 and small blades lumped), guided
                       vertically; gravity 9.81 m/s²
big blade              J = 0.02 kg·m² about its pivot (centre of mass on the pivot)
ring link 9            steel 20 mm × 6 mm over L9 = 180 mm: k₉ = E·A/L ≈ 1.38e8 N/m
warp force             peak 690 N at the stroke's extremes, zero at mid-stroke
damping                2 % in every mode; 4 modes kept
=====================  ===============================================================

Example::

    from jaxdobby.machine import Machine, OperatingPoint
    machine = Machine.default()
    machine.stroke()                                   # 0.14007 m
    machine = machine.with_stroke(0.115)               # move the link-11 joint in the slot
    op = OperatingPoint.from_users_units(speed_rpm=800.0, warp_force_n=690.0)
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from ._arrays import as_float
from .arm import ArmDesign
from .kinematics import DobbyLinkage
from .stroke import arc_length_for_stroke, stroke
from .units import rpm_to_rad_s

WARP_LAWS = ("restoring", "opposing")
"""Warp-force laws: ``restoring`` (default) pulls the frame back towards mid-stroke from both
sides, F = −F_w·(y − y_mid)/(H/2); ``opposing`` (the source study's reading) has the same
magnitude but always opposes the current pick's lift direction."""

COUPLINGS = ("two-way", "one-way")
"""``two-way``: the downstream chain moves with the deformed arm and its inertia enters the arm's
equations through the partial velocities (DESIGN.md §2 item 5). ``one-way``: the source study's
variant, link-11 force from rigid inverse dynamics applied at the joint."""


class Machine(eqx.Module):
    """The mechanism's parameters (SI). See the module docstring for the defaults.

    Attributes:
        arm: the bending arm; its centre line, ring-joint position and slot also define the
            linkage's arm geometry (the ``linkage`` fields of the same meaning are overridden).
        linkage: linkage geometry, stroke setting (``link11_arc_length``) and modulator.
        heald_frame_mass: mass moving with the heald frame [kg].
        blade_inertia: big blade's moment of inertia about its pivot [kg·m²].
        ring_link_modulus: Young's modulus of the ring link 9 [Pa].
        ring_link_area: cross-section of the ring link 9 [m²].
        gravity: gravitational acceleration, acting along −y [m/s²].
        damping_ratio: modal damping ratio ζ [-].
        n_modes: elastic modes of the arm kept (static, 1 … 30).
        coupling: ``"two-way"`` or ``"one-way"`` (static).
        warp_law: ``"restoring"`` or ``"opposing"`` (static).
    """

    arm: ArmDesign = eqx.field(default_factory=ArmDesign)
    linkage: DobbyLinkage = eqx.field(default_factory=DobbyLinkage.default)
    heald_frame_mass: Array = eqx.field(converter=as_float, default=12.0)
    blade_inertia: Array = eqx.field(converter=as_float, default=0.02)
    ring_link_modulus: Array = eqx.field(converter=as_float, default=2.07e11)
    ring_link_area: Array = eqx.field(converter=as_float, default=20e-3 * 6e-3)
    gravity: Array = eqx.field(converter=as_float, default=9.81)
    damping_ratio: Array = eqx.field(converter=as_float, default=0.02)
    n_modes: int = eqx.field(static=True, default=4)
    coupling: str = eqx.field(static=True, default="two-way")
    warp_law: str = eqx.field(static=True, default="restoring")

    def __check_init__(self):
        if self.coupling not in COUPLINGS:
            raise ValueError(f"coupling must be one of {COUPLINGS}, got {self.coupling!r}")
        if self.warp_law not in WARP_LAWS:
            raise ValueError(f"warp_law must be one of {WARP_LAWS}, got {self.warp_law!r}")

    @classmethod
    def default(cls, **changes) -> "Machine":
        """The default machine of DESIGN.md §6, with optional fields replaced (SI)."""
        return cls(**changes)

    def replace(self, **changes) -> "Machine":
        """A copy with some fields changed (through the converters)."""
        return dataclasses.replace(self, **changes)

    @property
    def chain(self) -> DobbyLinkage:
        """The linkage with the arm's geometry (centre line, ring joint, slot) taken from ``arm``."""
        return self.linkage.replace(
            arm=self.arm.centreline,
            ring_joint_arc_length=self.arm.ring_joint_arc_length,
            slot_start=self.arm.arc_start,
            slot_end=self.arm.arc_end,
        )

    @property
    def ring_link_stiffness(self) -> Array:
        """Axial stiffness of the ring link k₉ = E·A/L₉ [N/m]."""
        return self.ring_link_modulus * self.ring_link_area / self.linkage.ring_link_length

    @property
    def link11_arc_length(self) -> Array:
        """Arc length of the link-11 joint on the arm (the stroke setting) [m]."""
        return self.linkage.link11_arc_length

    def stroke(self) -> Array:
        """Heald-frame stroke of the rigid mechanism [m]."""
        return stroke(self.chain)

    def with_link11_arc_length(self, s) -> "Machine":
        """A copy with the link-11 joint at arc length ``s`` [m]."""
        return self.replace(linkage=self.linkage.replace(link11_arc_length=s))

    def with_stroke(self, target_stroke) -> "Machine":
        """A copy with the link-11 joint moved so the rigid stroke is ``target_stroke`` [m].

        A differentiable root solve (:func:`jaxdobby.stroke.arc_length_for_stroke`); a stroke
        the slot cannot give raises ``ValueError`` naming the reachable range.
        """
        return self.with_link11_arc_length(arc_length_for_stroke(self.chain, target_stroke))


class OperatingPoint(eqx.Module):
    """Where the loom runs.

    Attributes:
        speed: loom (main-shaft) speed [rad/s]; one pick per turn, one heald-frame cycle per
            two picks.
        warp_force: peak warp-yarn force on the heald frame, reached at the extremes [N].
    """

    speed: Array = eqx.field(converter=as_float, default=float(rpm_to_rad_s(800.0)))
    warp_force: Array = eqx.field(converter=as_float, default=690.0)

    @classmethod
    def from_users_units(cls, speed_rpm=800.0, warp_force_n=690.0) -> "OperatingPoint":
        """From r/min and N."""
        return cls(speed=rpm_to_rad_s(jnp.asarray(speed_rpm, dtype=float)),
                   warp_force=warp_force_n)
