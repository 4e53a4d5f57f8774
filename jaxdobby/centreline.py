"""Planar centre lines made of straight and circular-arc segments.

A beam's centre line is described in the beam's own *body frame* as a chain of segments, each
either straight or a circular arc with a signed turn angle (positive = counter-clockwise). The
chain starts at ``start`` [m] heading at ``start_angle`` [rad] from the body x axis. Points are
addressed by arc length s [m] from the start, so loads and attachments can sit anywhere on the
centre line, and every quantity is a smooth function of the segment lengths and turn angles
(an arc's radius can be a design variable).

Example::

    import jax; jax.config.update("jax_enable_x64", True)
    from jaxdobby.centreline import CentreLine
    arm = CentreLine.from_segments([("line", 0.105), ("arc", 0.400, -0.23998), ("line", 0.025)])
    arm.total_length          # 0.226 m
    arm.point(0.201)          # body-frame position [m] of the link-11 joint
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._arrays import as_float, is_traced


def _chord(sigma, kappa, heading):
    """Displacement along a segment of curvature ``kappa`` [1/m] over arc length ``sigma`` [m].

    Written with ``sinc`` so it is exact and differentiable for straight segments (kappa = 0):
    the chord of an arc has length 2 sin(kappa sigma/2)/kappa in the direction of the mean heading.
    """
    half = 0.5 * kappa * sigma
    length = sigma * jnp.sinc(half / jnp.pi)  # jnp.sinc(x) = sin(pi x)/(pi x)
    mid = heading + half
    return jnp.stack([length * jnp.cos(mid), length * jnp.sin(mid)], axis=-1)


class CentreLine(eqx.Module):
    """A chain of straight and circular-arc segments in the body frame.

    Attributes:
        lengths: arc length of each segment [m], shape (n_segments,).
        turns: signed turn angle of each segment [rad], shape (n_segments,); zero for a straight
            segment, positive counter-clockwise. The radius of an arc is ``lengths/|turns|``.
        start: body-frame position of the start of the chain [m], shape (2,).
        start_angle: heading of the chain at its start, from the body x axis [rad].
    """

    lengths: Array = eqx.field(converter=as_float)
    turns: Array = eqx.field(converter=as_float)
    start: Array = eqx.field(converter=as_float)
    start_angle: Array = eqx.field(converter=as_float)

    @classmethod
    def from_segments(
        cls,
        segments: Sequence[tuple],
        start=(0.0, 0.0),
        start_angle=0.0,
    ) -> "CentreLine":
        """Build a centre line from ``("line", length)`` and ``("arc", radius, turn)`` tuples.

        Lengths and radii in metres, turn angles in radians (signed, positive counter-clockwise).
        """
        # NumPy for concrete values (no small XLA programs at start-up), jnp for traced ones
        xp = jnp if is_traced(segments, start, start_angle) else np
        lengths, turns = [], []
        for seg in segments:
            kind = seg[0]
            if kind == "line":
                lengths.append(xp.asarray(seg[1], dtype=float))
                turns.append(xp.zeros((), dtype=float))
            elif kind == "arc":
                radius, turn = xp.asarray(seg[1], dtype=float), xp.asarray(seg[2], dtype=float)
                lengths.append(radius * xp.abs(turn))
                turns.append(turn)
            else:
                raise ValueError(f"unknown segment kind {kind!r}: use 'line' or 'arc'")
        return cls(lengths=xp.stack(lengths), turns=xp.stack(turns), start=start,
                   start_angle=start_angle)

    @property
    def total_length(self) -> Array:
        """Total arc length of the chain [m]."""
        return jnp.sum(self.lengths)

    @property
    def segment_starts(self) -> Array:
        """Arc length at the start of each segment [m], shape (n_segments,)."""
        return jnp.concatenate([jnp.zeros(1), jnp.cumsum(self.lengths)[:-1]])

    def _segment_frames(self):
        """Start point [m] and start heading [rad] of each segment."""
        curvatures = self.turns / self.lengths
        headings = self.start_angle + jnp.concatenate([jnp.zeros(1), jnp.cumsum(self.turns)[:-1]])
        steps = _chord(self.lengths, curvatures, headings)
        points = self.start + jnp.concatenate([jnp.zeros((1, 2)), jnp.cumsum(steps, axis=0)[:-1]])
        return points, headings, curvatures

    def _locate(self, s):
        """Segment index and local arc length for arc length(s) ``s`` [m] (clamped to the chain)."""
        s = jnp.asarray(s, dtype=float)
        edges = jnp.cumsum(self.lengths)[:-1]
        index = jnp.searchsorted(edges, s, side="right")
        return index, s - self.segment_starts[index]

    def point(self, s) -> Array:
        """Body-frame position [m] of the point at arc length ``s`` [m]; shape ``s.shape + (2,)``."""
        points, headings, curvatures = self._segment_frames()
        i, sigma = self._locate(s)
        return points[i] + _chord(sigma, curvatures[i], headings[i])

    def heading(self, s) -> Array:
        """Tangent angle [rad] of the centre line at arc length ``s`` [m], from the body x axis."""
        _, headings, curvatures = self._segment_frames()
        i, sigma = self._locate(s)
        return headings[i] + curvatures[i] * sigma
