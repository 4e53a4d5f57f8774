"""Every float parameter of the model by name, in the users' units, with its valid range.

One registry serves the configuration file, the command line, the sweeps, the Sobol studies and
the optimiser, so a parameter has one name, one unit and one range everywhere. Each entry knows
how to read and replace its value in a :class:`Setup` (machine + operating point) in SI; the
replacements are pure functions, usable under ``jax.jit``/``vmap``/``grad``.

Names are the users' words (``speed``, ``warp_force``, ``stroke``, ``thickness``); the TOML key
adds the unit (``speed_rpm``, ``warp_force_n``, ``stroke_mm``, ``thickness_mm``). ``stroke``
moves the link-11 joint in the slot by a root solve, so it is applied after every geometric
change (see :func:`apply`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from .machine import Machine, OperatingPoint
from .units import DEG, MM, RPM


class Setup(eqx.Module):
    """A machine at an operating point: what one simulation needs."""

    machine: Machine = eqx.field(default_factory=Machine.default)
    operating: OperatingPoint = eqx.field(default_factory=OperatingPoint)


@dataclasses.dataclass(frozen=True)
class Parameter:
    """A float parameter of the model.

    Attributes:
        name: the name on the command line and in problem files.
        section: the TOML table it belongs to.
        key: its key in that table (name + unit suffix).
        unit: the users' unit.
        scale: one users' unit in SI.
        limits: valid open interval (low, high) in users' units (``low_closed`` includes low).
        description: a few words, for help texts and errors.
        get: Setup → SI value.
        set: (Setup, SI value) → Setup.
        bounds: default Sobol bounds in users' units (None: not in a default study).
        low_closed: whether ``limits[0]`` itself is valid.
        high_closed: whether ``limits[1]`` itself is valid.
    """

    name: str
    section: str
    key: str
    unit: str
    scale: float
    limits: tuple[float, float]
    description: str
    get: Callable[[Setup], Array]
    set: Callable[[Setup, Array], Setup]
    bounds: tuple[float, float] | None = None
    low_closed: bool = False
    high_closed: bool = False

    def range_text(self) -> str:
        low, high = self.limits
        if math.isinf(low) and math.isinf(high):
            return "any finite number"
        lo = f"{'>=' if self.low_closed else '>'} {low:g}"
        return lo if math.isinf(high) else f"{lo} and {'<=' if self.high_closed else '<'} {high:g}"


def _operating(field):
    return (lambda s: getattr(s.operating, field),
            lambda s, v: eqx.tree_at(lambda x: getattr(x.operating, field), s, jnp.asarray(v, float)))


def _machine(field):
    return (lambda s: getattr(s.machine, field),
            lambda s, v: eqx.tree_at(lambda x: getattr(x.machine, field), s, jnp.asarray(v, float)))


def _arm(field):
    return (lambda s: getattr(s.machine.arm, field),
            lambda s, v: eqx.tree_at(lambda x: getattr(x.machine.arm, field), s,
                                     jnp.asarray(v, float)))


def _linkage(field, index=None):
    def get(s):
        value = getattr(s.machine.linkage, field)
        return value if index is None else value[index]

    def set_(s, v):
        v = jnp.asarray(v, float)
        if index is not None:
            v = getattr(s.machine.linkage, field).at[index].set(v)
        return eqx.tree_at(lambda x: getattr(x.machine.linkage, field), s, v)

    return get, set_


def _stroke():
    return (lambda s: s.machine.stroke(),
            lambda s, v: eqx.tree_at(lambda x: x.machine, s, s.machine.with_stroke(v)))


def _p(name, section, unit, scale, limits, description, accessors, key_unit=None, bounds=None,
       low_closed=False, high_closed=False):
    get, set_ = accessors
    suffix = key_unit if key_unit is not None else unit
    key = f"{name}_{suffix}" if suffix else name
    return Parameter(name, section, key, unit, scale, limits, description, get, set_, bounds,
                     low_closed, high_closed)


INF = math.inf
SPEED_RANGE = (100.0, 1800.0)
"""Supported loom speeds [r/min], both included: where the default collocation solver's steady
state converges for arm thicknesses 3–8 mm (README, Limits; ``pytest -m slow
tests/test_validity.py``). Below ~70 r/min its 432 steps per cycle each span more than a period
of the arm's first mode and the shooting stalls, while the answer there is quasi-static anyway
(the deviation at 100 r/min equals the 70 r/min one to three digits); at 2000 r/min a 3 mm arm
fails (NaN), at 2500 an 8 mm one — far beyond the small-deformation limits, which the default
arm leaves already near 1000 r/min (:mod:`jaxdobby.validity`)."""
PARAMETERS: dict[str, Parameter] = {p.name: p for p in [
    _p("speed", "operating", "r/min", RPM, SPEED_RANGE, "loom speed", _operating("speed"), "rpm",
       bounds=(400.0, 1200.0), low_closed=True, high_closed=True),
    _p("warp_force", "operating", "N", 1.0, (0, INF), "peak warp-yarn force on the heald frame",
       _operating("warp_force"), "n", bounds=(345.0, 1035.0), low_closed=True),
    _p("stroke", "stroke", "mm", MM, (0, INF), "heald-frame stroke (moves the link-11 joint)",
       _stroke(), bounds=(80.0, 140.0)),
    _p("link11_position", "stroke", "mm", MM, (0, INF),
       "arc length of the link-11 joint on the arm", _linkage("link11_arc_length")),
    _p("thickness", "arm", "mm", MM, (0, INF), "plate thickness of the bending arm",
       _arm("thickness"), bounds=(6.0, 8.0)),
    _p("depth", "arm", "mm", MM, (0, INF), "in-plane depth of the arm (one value or a list)",
       _arm("depth")),
    _p("depth_positions", "arm", "mm", MM, (0, INF), "arc lengths of the depth control points",
       _arm("depth_arc_lengths"), low_closed=True),
    _p("straight_length", "arm", "mm", MM, (0, INF), "straight part from the pivot to the arc",
       _arm("straight_length")),
    _p("arc_radius", "arm", "mm", MM, (0, INF), "radius of the arm's arc (the slot)",
       _arm("arc_radius")),
    _p("arc_angle", "arm", "deg", DEG, (0, 180), "angle the arc turns through",
       _arm("arc_angle")),
    _p("tip_length", "arm", "mm", MM, (0, INF), "straight tip beyond the arc", _arm("tip_length"),
       low_closed=True),
    _p("ring_joint_position", "arm", "mm", MM, (0, INF),
       "arc length of the ring-link joint on the arm", _arm("ring_joint_arc_length")),
    _p("youngs_modulus", "arm", "Pa", 1.0, (0, INF), "Young's modulus of the arm",
       _arm("youngs_modulus"), "pa"),
    _p("density", "arm", "kg/m3", 1.0, (0, INF), "density of the arm", _arm("density"),
       "kg_m3"),
    _p("ultimate_strength", "arm", "MPa", 1e6, (0, INF), "ultimate tensile strength of the arm",
       _arm("ultimate_strength"), "mpa"),
    _p("yield_strength", "arm", "MPa", 1e6, (0, INF), "yield strength of the arm",
       _arm("yield_strength"), "mpa"),
    _p("endurance_limit", "arm", "MPa", 1e6, (0, INF),
       "endurance limit of a polished specimen (before surface and size factors)",
       _arm("endurance_limit"), "mpa"),
    _p("surface_factor", "arm", "", 1.0, (0, INF), "Marin surface factor k_a of the endurance "
       "limit", _arm("surface_factor")),
    _p("size_factor", "arm", "", 1.0, (0, INF), "Marin size factor k_b of the endurance limit",
       _arm("size_factor")),
    _p("eccentricity", "linkage", "mm", MM, (0, INF), "eccentricity of the eccentric (crank)",
       _linkage("eccentricity")),
    _p("eccentric_axis_x", "linkage", "mm", MM, (-INF, INF), "eccentric axis A0, x",
       _linkage("eccentric_axis", 0)),
    _p("eccentric_axis_y", "linkage", "mm", MM, (-INF, INF), "eccentric axis A0, y",
       _linkage("eccentric_axis", 1)),
    _p("ring_link_length", "linkage", "mm", MM, (0, INF), "length L9 of the ring link",
       _linkage("ring_link_length")),
    _p("link11_length", "linkage", "mm", MM, (0, INF), "length L11 of link 11",
       _linkage("link11_length")),
    _p("blade_pivot_x", "linkage", "mm", MM, (-INF, INF), "big-blade pivot D0, x",
       _linkage("blade_pivot", 0)),
    _p("blade_pivot_y", "linkage", "mm", MM, (-INF, INF), "big-blade pivot D0, y",
       _linkage("blade_pivot", 1)),
    _p("blade_input_arm", "linkage", "mm", MM, (0, INF), "big blade's input arm",
       _linkage("blade_input_arm")),
    _p("blade_output_arm", "linkage", "mm", MM, (0, INF), "big blade's output arm",
       _linkage("blade_output_arm")),
    _p("tumbler_length", "linkage", "mm", MM, (0, INF), "tumbler link L13",
       _linkage("tumbler_length")),
    _p("frame_guide_x", "linkage", "mm", MM, (-INF, INF), "x of the heald frame's guide",
       _linkage("frame_guide_x")),
    _p("dwell", "linkage", "deg", DEG, (0, 360), "modulator dwell per pick (loom angle)",
       _linkage("dwell")),
    _p("heald_frame_mass", "downstream", "kg", 1.0, (0, INF), "mass moving with the heald frame",
       _machine("heald_frame_mass")),
    _p("blade_inertia", "downstream", "kg m2", 1.0, (0, INF), "big blade's moment of inertia",
       _machine("blade_inertia"), "kg_m2", low_closed=True),
    _p("ring_link_modulus", "downstream", "Pa", 1.0, (0, INF), "Young's modulus of the ring link",
       _machine("ring_link_modulus"), "pa"),
    _p("ring_link_area", "downstream", "mm2", MM**2, (0, INF), "cross-section of the ring link",
       _machine("ring_link_area")),
    _p("gravity", "downstream", "m/s2", 1.0, (0, INF), "gravitational acceleration",
       _machine("gravity"), "m_s2", low_closed=True),
    _p("damping_ratio", "model", "", 1.0, (0, 1), "modal damping ratio of the arm",
       _machine("damping_ratio"), low_closed=True),
]}
"""The registry, by name."""

APPLY_LAST = ("stroke",)
"""Parameters applied after all others (they depend on the geometry)."""


def apply(setup: Setup, values_si: Mapping[str, Array]) -> Setup:
    """Replace parameters (by name, SI values) in ``setup``; ``stroke`` goes last."""
    ordered = sorted(values_si, key=lambda n: n in APPLY_LAST)
    for name in ordered:
        setup = PARAMETERS[name].set(setup, values_si[name])
    return setup


def value(setup: Setup, name: str) -> Array:
    """SI value of a parameter in ``setup``."""
    return PARAMETERS[name].get(setup)
