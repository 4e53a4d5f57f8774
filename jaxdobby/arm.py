"""The bending arm (part 10) of the rotary dobby as a curved beam.

:class:`ArmDesign` holds the arm's design in SI: its centre line (a straight length from the
pivot, a circular arc — the stroke-adjustment slot — and a short straight tip), its plate
thickness t (out of plane; the design variable the source study varies, 6–8 mm) and in-plane
depth d(s) (uniform 40 mm by default, or piecewise linear between control points for shape
optimisation), and its material (steel: E = 2.07e11 Pa, ρ = 7800 kg/m³, as in the source study).

The mesh follows the source study: 11 nodes, 10 elements, numbered from the pivot — nodes 1–3
on the first straight part, node 4 at the ring-link joint, node 5 at the arc start, nodes 6–10
along the arc with node 10 at its end (the link-11 joint at the longest stroke), node 11 at the
tip. (Python indices are one less: the ring-link joint is node index 3.) A finer mesh
(``n_elements``, static) keeps the key points — ring-link joint, arc start, arc end — as nodes
and splits the four stretches between them (3 : 1 : 5 : 1 elements in the study) in the same
proportion: 20 elements = 6, 2, 10, 2; 40 = 12, 4, 20, 4 (other counts by largest remainder,
at least one element each). The link-11 joint is the arc-end node at the default stroke; at
other strokes it lies inside an arc element and its loads and motion are interpolated there.

In the mechanism the arm is pinned at its pivot (the body-frame origin) and held at the
ring-link joint by the ring link 9, an axial spring of stiffness E·A₉/L₉ along the link.

Example::

    from jaxdobby.arm import ArmDesign, arm_beam
    beam = arm_beam(ArmDesign())     # the default arm: Beam with 11 nodes
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._arrays import as_float, as_float_1d
from .beam import Beam
from .centreline import CentreLine
from .supports import Supports

RING_JOINT_NODE = 3
"""Python index of the ring-link joint node on the study's 10-element mesh (node 4)."""

STUDY_SPLIT = (3, 1, 5, 1)
"""Elements of the study's mesh on pivot → ring joint → arc start → arc end → tip."""


def mesh_split(n_elements: int) -> tuple[int, int, int, int]:
    """Elements on each of the four stretches for an ``n_elements`` mesh (≥ 4), in the study's
    3 : 1 : 5 : 1 proportion (largest remainder, at least one each)."""
    if n_elements < 4:
        raise ValueError(f"n_elements = {n_elements} is outside the valid range (an integer >= 4)")
    share = np.array(STUDY_SPLIT, dtype=float) * n_elements / sum(STUDY_SPLIT)
    counts = np.maximum(np.floor(share).astype(int), 1)
    while counts.sum() < n_elements:
        counts[np.argmax(share - counts)] += 1
    while counts.sum() > n_elements:
        counts[np.argmax(np.where(counts > 1, counts - share, -np.inf))] -= 1
    return tuple(int(c) for c in counts)


class ArmDesign(eqx.Module):
    """Design of the bending arm (defaults: DESIGN.md §6).

    Attributes:
        thickness: plate thickness t, out of the plane of motion [m].
        depth: in-plane depth d at the control points [m], shape (n_ctrl,).
        depth_arc_lengths: arc lengths of the depth control points [m], shape (n_ctrl,);
            d is linear in between and constant beyond the first and last.
        straight_length: length of the straight part from the pivot to the arc [m].
        arc_radius: radius of the arc (the stroke-adjustment slot) [m].
        arc_angle: angle the arc turns through, clockwise towards link 11 [rad] (> 0).
        tip_length: straight tip beyond the arc [m].
        ring_joint_arc_length: arc length of the ring-link joint from the pivot [m].
        youngs_modulus: E [Pa]. density: ρ [kg/m³].
        ultimate_strength, yield_strength: σ_u and σ_y of the material [Pa] (42CrMo4 +QT,
            16–40 mm: 1000 and 750 MPa, EN 10083-3 Table 5).
        endurance_limit: σ_e′ of a polished rotating-beam specimen [Pa] (0.5·σ_u, Shigley
            eq. 6-8); surface_factor, size_factor: Marin factors k_a, k_b [-] (default 1);
            the fatigue check uses k_a·k_b·σ_e′ (:mod:`jaxdobby.stress.fatigue`).
        n_elements: elements of the mesh (static, ≥ 4; 10 in the source study's mesh).
    """

    thickness: Array = eqx.field(converter=as_float, default=0.006)
    depth: Array = eqx.field(converter=as_float_1d, default=0.040)
    depth_arc_lengths: Array = eqx.field(converter=as_float_1d, default=0.0)
    straight_length: Array = eqx.field(converter=as_float, default=0.105)
    arc_radius: Array = eqx.field(converter=as_float, default=0.400)
    arc_angle: Array = eqx.field(converter=as_float, default=float(np.radians(13.75)))
    tip_length: Array = eqx.field(converter=as_float, default=0.025)
    ring_joint_arc_length: Array = eqx.field(converter=as_float, default=0.080)
    youngs_modulus: Array = eqx.field(converter=as_float, default=2.07e11)
    density: Array = eqx.field(converter=as_float, default=7800.0)
    ultimate_strength: Array = eqx.field(converter=as_float, default=1.0e9)
    yield_strength: Array = eqx.field(converter=as_float, default=7.5e8)
    endurance_limit: Array = eqx.field(converter=as_float, default=5.0e8)
    surface_factor: Array = eqx.field(converter=as_float, default=1.0)
    size_factor: Array = eqx.field(converter=as_float, default=1.0)
    n_elements: int = eqx.field(static=True, default=10)

    @property
    def centreline(self) -> CentreLine:
        """Centre line in the arm's body frame: pivot at the origin, first part along +x."""
        return CentreLine.from_segments([
            ("line", self.straight_length),
            ("arc", self.arc_radius, -self.arc_angle),
            ("line", self.tip_length),
        ])

    @property
    def arc_start(self) -> Array:
        """Arc length of the start of the slot [m]."""
        return self.straight_length

    @property
    def arc_end(self) -> Array:
        """Arc length of the end of the slot (node 10, the longest stroke) [m]."""
        return self.straight_length + self.arc_radius * self.arc_angle

    @property
    def total_length(self) -> Array:
        """Arc length of the whole arm [m]."""
        return self.arc_end + self.tip_length

    @property
    def ring_joint_node(self) -> int:
        """Index of the ring-link joint node (static)."""
        return mesh_split(self.n_elements)[0]

    def node_arc_lengths(self) -> Array:
        """Arc lengths of the ``n_elements + 1`` mesh nodes [m] (see the module docstring)."""
        r = self.ring_joint_arc_length
        if self.n_elements == sum(STUDY_SPLIT):  # the study's mesh, as it always was computed
            arc = self.arc_start + (self.arc_end - self.arc_start) * jnp.arange(1, 6) / 5
            return jnp.concatenate([jnp.stack([0.0 * r, r / 3.0, 2.0 * r / 3.0, r,
                                               self.arc_start]), arc, self.total_length[None]])
        keys = [0.0 * r, r, self.arc_start, self.arc_end, self.total_length]
        parts = [keys[0][None]]
        for i, n in enumerate(mesh_split(self.n_elements)):  # key points exact, not interpolated
            parts += [keys[i] + (keys[i + 1] - keys[i]) * jnp.arange(1, n) / n, keys[i + 1][None]]
        return jnp.concatenate(parts)

    def mass(self) -> Array:
        """Mass of the arm [kg] (centre-line length × t × d, the section integrated exactly
        for piecewise-linear depth by the mesh's mid-point rule)."""
        beam = arm_beam(self)
        length, _, _ = beam.element_geometry()
        area, _ = beam.element_sections()
        return self.density * jnp.sum(area * length)


def arm_beam(design: ArmDesign) -> Beam:
    """The arm as a :class:`~jaxdobby.beam.Beam` on its mesh (the study's 11 nodes by default)."""
    return Beam(design.centreline, design.node_arc_lengths(), thickness=design.thickness,
                depth=design.depth, depth_arc_lengths=design.depth_arc_lengths,
                youngs_modulus=design.youngs_modulus, density=design.density)


def arm_supports(ring_direction, ring_stiffness, ring_node: int = RING_JOINT_NODE) -> Supports:
    """Pin at the pivot and the ring link as an axial spring at the ring-link joint.

    Args:
        ring_direction: body-frame direction of the ring link (any length) [-], shape (2,).
        ring_stiffness: axial stiffness of the ring link E·A₉/L₉ [N/m].
        ring_node: index of the ring-joint node (static; ``ArmDesign.ring_joint_node``).
    """
    return Supports(pinned=(0,), spring_nodes=(ring_node,),
                    spring_directions=jnp.reshape(ring_direction, (1, 2)),
                    spring_stiffness=jnp.reshape(ring_stiffness, (1,)))
