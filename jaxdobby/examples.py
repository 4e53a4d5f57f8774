"""Worked examples of the flexible-body layer, one per capability; each is also a test.

Run any of them after switching float64 on::

    import jax; jax.config.update("jax_enable_x64", True)
    from jaxdobby import examples
    ts, tip = examples.spin_up_beam(6.0)

* :func:`cantilever_tip_deflection` — statics of a straight beam (capability 1–2);
* :func:`curved_arm_modes` — modes of a curved arm pinned and spring-supported (capability 3);
* :func:`spin_up_beam` — Kane's equations in a floating frame with geometric stiffening: the
  Kane–Ryan–Banerjee spin-up beam (capability 4).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .beam import Beam
from .centreline import CentreLine
from .flexible_body import flexible_body
from .floating_frame import SpinUp
from .loads import point_load
from .modal import modal_basis
from .response import simulate_flexible_body
from .supports import Supports, static_deflection


def cantilever_tip_deflection(force=100.0, length=1.0, thickness=0.006, depth=0.04,
                              youngs_modulus=2.07e11, n_elements=10):
    """Tip deflection [m] of a straight steel cantilever under a transverse tip force [N].

    Equals F L³/(3 E I) exactly (nodally exact elements), I = t d³/12.
    """
    line = CentreLine.from_segments([("line", length)])
    beam = Beam.uniform_mesh(line, n_elements, thickness=thickness, depth=depth,
                             youngs_modulus=youngs_modulus, density=7800.0)
    u = static_deflection(beam, Supports(clamped=(0,)),
                          point_load(beam, length, force=(0.0, force)))
    return u[-2]


def curved_arm_modes(n_modes=4, spring_stiffness=1.38e8):
    """Natural frequencies [Hz] of a curved steel arm pinned at its pivot and held by a spring.

    The centre line is the dobby's bending arm (105 mm straight, a 400 mm-radius arc over
    13.75°, 25 mm straight), 6 mm × 40 mm section, pinned at s = 0 and held at s = 80 mm by an
    axial spring [N/m] along the body direction (0.6, 0.8).
    """
    arm = CentreLine.from_segments([("line", 0.105), ("arc", 0.4, -np.radians(13.75)),
                                    ("line", 0.025)])
    beam = Beam.uniform_mesh(arm, 12, thickness=0.006, depth=0.04, youngs_modulus=2.07e11,
                             density=7800.0)
    node = beam.nearest_node(0.08)
    supports = Supports(pinned=(0,), spring_nodes=(node,), spring_directions=[[0.6, 0.8]],
                        spring_stiffness=[spring_stiffness])
    return modal_basis(beam, supports, n_modes).frequencies_hz


def krb_beam(n_elements=10) -> Beam:
    """The Kane–Ryan–Banerjee (1987) beam: L = 10 m, E = 7e10 Pa, ρ = 3000 kg/m³,
    A = 4e-4 m², I = 2e-7 m⁴ (a rectangle with the same A and I), clamped at s = 0."""
    area, inertia = 4e-4, 2e-7
    depth = np.sqrt(12.0 * inertia / area)
    line = CentreLine.from_segments([("line", 10.0)])
    return Beam.uniform_mesh(line, n_elements, thickness=area / depth, depth=depth,
                             youngs_modulus=7e10, density=3000.0)


def spin_up_beam(omega, stiffening=True, *, duration=15.0, t_end=30.0, n_out=601, n_modes=4,
                 n_elements=10):
    """Tip deflection history of the Kane–Ryan–Banerjee spin-up beam.

    The hub angle follows θ(t) = (Ω/T)[t²/2 + (T/2π)²(cos(2πt/T) − 1)] for t < T, then
    Ω(t − T/2), with Ω = ``omega`` [rad/s] and T = ``duration`` [s]. With geometric stiffening
    the tip deflection stays bounded (one lagging excursion during spin-up, millimetre
    oscillation after); without it the model diverges once Ω exceeds the first bending frequency
    (3.80 rad/s), because centrifugal softening −Ω² then outweighs the elastic stiffness.

    Returns:
        ``(ts, tip)``: times [s] and the transverse tip deflection in the rotating frame [m].
    """
    beam = krb_beam(n_elements)
    body = flexible_body(beam, Supports(clamped=(0,)), n_modes, points=(10.0,))
    ts = jnp.linspace(0.0, t_end, n_out)
    out = simulate_flexible_body(body, SpinUp(omega, duration), ts,
                                 stiffening=1.0 if stiffening else 0.0, throw=False)
    return ts, out.point_displacements[:, 0, 1]
