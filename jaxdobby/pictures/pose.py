"""Where every joint of the lifting mechanism is at one instant: the geometry the pictures draw.

A :class:`Pose` holds the inertial positions [m] (x horizontal, y up, origin at the arm pivot
B0) of the joints of the chain of :mod:`jaxdobby.kinematics` — eccentric axis A0 and pin Q
(eccentric 8), ring-link joint J on the arm (ring link 9 = Q–J), the bending arm 10's centre line,
the link-11 joint P, the big blade 12's pivot D0, input pin C (link 11 = P–C) and output joint E,
and the heald frame 16's suspension point H on its guide (tumbler 13 = E–H).

:func:`rigid_pose` closes the loops of the rigid mechanism for an eccentric angle with the
package's own closures (:func:`~jaxdobby.kinematics.arm_angle_from_crank`,
:func:`~jaxdobby.kinematics.blade_angle`,
:func:`~jaxdobby.kinematics.heald_frame_height_from_blade`).
:func:`flexible_pose` adds the arm's elastic deformation u(s) = N(s) Φ q in the arm's frame —
Φ the model's mode shapes (:func:`jaxdobby.dobby.arm_modes`), q the modal coordinates of a run
(``Simulation.series.modal``) — optionally magnified, and drives the downstream chain with the
deformed link-11 joint, exactly as the coupled model does (:func:`jaxdobby.dobby.joint_position`).

All functions broadcast over leading axes (many frames at once) and return numpy arrays.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..arm import arm_beam
from ..dobby import LINK, DobbyModel, arm_modes
from ..kinematics import (
    DobbyLinkage,
    rotate,
    arm_angle_from_crank,
    blade_angle,
    dead_centres,
    heald_frame_height_from_blade,
)
from ..machine import Machine
from ..modulator import crank_angle as modulator_crank_angle

SAMPLES_PER_ELEMENT = 8
"""Points drawn per finite element along the arm's centre line."""


class Pose(NamedTuple):
    """Inertial joint positions [m], each shape ``(..., 2)`` (``arm``: ``(..., n, 2)``)."""

    eccentric_axis: np.ndarray  # A0
    eccentric_pin: np.ndarray  # Q
    pivot: np.ndarray  # B0
    ring_joint: np.ndarray  # J
    arm: np.ndarray  # centre line of the arm 10, from the pivot to the tip
    link11_joint: np.ndarray  # P
    blade_pin: np.ndarray  # C
    blade_pivot: np.ndarray  # D0
    tumbler_joint: np.ndarray  # E
    heald_frame: np.ndarray  # H = (x_g, y_H)

    def at(self, i) -> "Pose":
        """The pose of instant ``i`` of a pose over many instants (index of the leading axis)."""
        return Pose(*(np.asarray(v)[i] for v in self))


class ArmSampling(NamedTuple):
    """The arm's centre line sampled for drawing.

    Attributes:
        arc_lengths: s of the samples [m], (n,).
        element: finite element each segment between samples i and i+1 belongs to, (n − 1,).
        body: undeformed body-frame positions [m], (n, 2).
        modal_rows: body-frame displacement per unit modal coordinate, N(s)Φ [m], (n, 2, k).
        ring_rows, link_rows: the same at the ring-link and link-11 joints, (2, k).
        node_arc_lengths: s of the FE nodes [m], (n_nodes,).
    """

    arc_lengths: np.ndarray
    element: np.ndarray
    body: np.ndarray
    modal_rows: np.ndarray
    ring_rows: np.ndarray
    link_rows: np.ndarray
    node_arc_lengths: np.ndarray


def crank_angle_at(machine: Machine, loom_angle, plan=None) -> np.ndarray:
    """Eccentric angle φ [rad] at loom (main-shaft) angle ψ [rad] from the middle of the bottom
    dwell (the modulator's φ(t) with t = ψ/speed, as :func:`jaxdobby.dobby.crank_angle`; one
    heald-frame cycle is ψ = 0…4π, the frame at the top at ψ = 2π). With a lift ``plan``
    (P,) of 0/1 (DESIGN.md §7): ψ = 0 is the middle of the last pick's dwell and the repeat
    is ψ = 0…2πP."""
    plan = None if plan is None else jnp.asarray(plan, dtype=float)
    return np.asarray(_crank_angles(machine.chain, jnp.asarray(loom_angle, dtype=float), plan))


@eqx.filter_jit
def _crank_angles(chain: DobbyLinkage, loom_angle, plan):
    (crank_start, _), _ = dead_centres(chain)
    return modulator_crank_angle(loom_angle, 1.0, dwell=chain.dwell, start_angle=crank_start,
                                 law=chain.motion_law, plan=plan)


def _downstream(chain: DobbyLinkage, joint):
    """Blade pin C, tumbler joint E and heald-frame point H [m] for link-11 joint P [m]."""
    beta = blade_angle(chain, joint)
    gamma = beta + chain.blade_output_offset
    unit = lambda a: jnp.stack([jnp.cos(a), jnp.sin(a)], axis=-1)  # noqa: E731
    c = chain.blade_pivot + chain.blade_input_arm * unit(beta)
    e = chain.blade_pivot + chain.blade_output_arm * unit(gamma)
    y_h = heald_frame_height_from_blade(chain, beta)
    h = jnp.stack([jnp.broadcast_to(chain.frame_guide_x, y_h.shape), y_h], axis=-1)
    return c, e, h


def _pose_arrays(chain: DobbyLinkage, crank, theta, arm_body, ring_body, link_body):
    """(Q, J, arm, P, C, E, H) from the eccentric angle, the arm angle and the (possibly
    deformed) arm in its frame (traced: inside the compiled pose programs below)."""
    q = chain.eccentric_axis + chain.eccentricity * jnp.stack([jnp.cos(crank), jnp.sin(crank)],
                                                              axis=-1)
    arm = rotate(theta[..., None], arm_body)
    ring = rotate(theta, ring_body)
    link = rotate(theta, link_body)
    c, e, h = _downstream(chain, link)
    return q, ring, arm, link, c, e, h


def _as_pose(chain: DobbyLinkage, arrays) -> Pose:
    """The :class:`Pose` (numpy) of :func:`_pose_arrays`' output, fixed joints broadcast."""
    q, ring, arm, link, c, e, h = (np.asarray(a) for a in arrays)
    fixed = lambda p: np.broadcast_to(np.asarray(p), q.shape)  # noqa: E731
    return Pose(fixed(chain.eccentric_axis), q, fixed(np.zeros(2)), ring, arm, link, c,
                fixed(chain.blade_pivot), e, h)


def arm_sampling(machine: Machine, model: DobbyModel | None = None) -> ArmSampling:
    """Sample the arm's centre line and its modal displacement rows (Φ of ``arm_modes``).

    With ``model``, each mode's sign is matched to the model's own basis (its rows at the
    link-11 joint, ``model.body.points``), so q of a run of that model deforms the arm the way
    the model did; a mismatch beyond round-off raises ``ValueError``.
    """
    s, body, modal_rows, special, nodes = (np.asarray(a) for a in _sampling_arrays(machine))
    element = np.repeat(np.arange(nodes.size - 1), SAMPLES_PER_ELEMENT)
    if model is not None:
        own = np.asarray(model.body.points[LINK])
        sign = np.where(np.sum(own * special[1], axis=0) < 0.0, -1.0, 1.0)
        if not np.allclose(special[1] * sign, own, rtol=1e-6, atol=1e-9 * np.abs(own).max()):
            raise ValueError("the model's basis is not the arm's own modes (a fixed basis?): "
                             "cannot draw its deformation")
        special, modal_rows = special * sign, modal_rows * sign
    return ArmSampling(arc_lengths=s, element=element, body=body, modal_rows=modal_rows,
                       ring_rows=special[0], link_rows=special[1], node_arc_lengths=nodes)


@eqx.filter_jit
def _sampling_arrays(machine: Machine):
    """(s, body points, N(s)Φ, N Φ at the ring-link and link-11 joints, node s) of
    :func:`arm_sampling`: one compiled program rather than hundreds of small operations."""
    beam = arm_beam(machine.arm)
    nodes = machine.arm.node_arc_lengths()
    step = (nodes[1:] - nodes[:-1]) / SAMPLES_PER_ELEMENT  # np.linspace(a, b, K, endpoint=False)
    s = nodes[:-1, None] + step[:, None] * jnp.arange(SAMPLES_PER_ELEMENT)
    s = jnp.concatenate([s.reshape(-1), nodes[-1:]])
    shapes = arm_modes(machine).shapes
    rows_of = jax.vmap(beam.point_rows)
    special = rows_of(jnp.stack([machine.arm.ring_joint_arc_length,
                                 machine.link11_arc_length])) @ shapes
    return s, machine.chain.arm.point(s), rows_of(s) @ shapes, special, nodes


def rigid_pose(machine: Machine, crank, sampling: ArmSampling) -> Pose:
    """The rigid mechanism at eccentric angle(s) φ [rad] (any shape)."""
    chain = machine.chain
    return _as_pose(chain, _rigid_pose(chain, jnp.asarray(crank, dtype=float),
                                       jnp.asarray(sampling.body)))


@eqx.filter_jit
def _rigid_pose(chain: DobbyLinkage, crank, body):
    theta = arm_angle_from_crank(chain, crank)
    return _pose_arrays(chain, crank, theta, body, chain.arm.point(chain.ring_joint_arc_length),
                        chain.arm.point(chain.link11_arc_length))


def flexible_pose(machine: Machine, crank, sampling: ArmSampling, q,
                  magnification: float = 1.0) -> Pose:
    """The mechanism with the arm deformed by modal coordinates q (..., k), magnified.

    The arm, the ring-link joint and the link-11 joint move by ``magnification``·N(s)Φq in the
    arm's frame; the blade, tumbler and heald frame follow the moved link-11 joint through the
    loop closures (at magnification 1, the coupled model's flexible heald-frame height).
    """
    chain = machine.chain
    rows = (jnp.asarray(a) for a in (sampling.body, sampling.modal_rows, sampling.ring_rows,
                                       sampling.link_rows))
    q = jnp.asarray(np.asarray(q, dtype=float) * magnification)
    return _as_pose(chain, _flexible_pose(chain, jnp.asarray(crank, dtype=float), *rows, q))


@eqx.filter_jit
def _flexible_pose(chain: DobbyLinkage, crank, body, modal_rows, ring_rows, link_rows, q):
    theta = arm_angle_from_crank(chain, crank)
    arm = body + jnp.einsum("nik,...k->...ni", modal_rows, q)
    ring = chain.arm.point(chain.ring_joint_arc_length) + q @ ring_rows.T
    link = chain.arm.point(chain.link11_arc_length) + q @ link_rows.T
    return _pose_arrays(chain, crank, theta, arm, ring, link)
