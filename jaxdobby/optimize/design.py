"""Design variables of the bending arm, their bounds, and the constraints of a design study.

A :class:`DesignSpace` maps a vector u ∈ [0, 1]ⁿ of *normalised* design variables to a
:class:`~jaxdobby.parameters.Setup` (a pure, differentiable function): each variable is
p = lower + u·(upper − lower) in SI, so bounds are kept exactly by projecting u onto the box
(clipping) and every variable has the same scale for the optimiser.

Variables (``--vars``; defaults of the bounds in :data:`DEFAULT_BOUNDS`, users' units):

* ``thickness`` — plate thickness t [mm]. Its upper bound is also the constraint t ≤ pitch −
  clearance (the pitch between neighbouring arms on the dobby's shaft): a bound on one variable
  is kept exactly by the projection, so it needs no penalty.
* ``depth`` — in-plane depth d [mm] at the control points ``depth_positions`` [mm] (linear in
  between, constant beyond): one variable per control point (shape optimisation).
* ``arc_radius`` — radius of the arm's arc [mm], its *length* held at the design's (the arc
  angle follows), so the arm's length and the slot's length do not change.
* ``heald_frame_mass`` [kg], ``blade_inertia`` [kg·m²] — the heald-frame side.

Constraints, as functions c(u) ≤ 0 normalised to be O(1) (see :func:`constraints`): the arm's
mass ≤ a budget, c = m/m_max − 1; the first coupled natural frequency ≥ a floor,
c = 1 − f₁/f_min. The stroke is held fixed: when the arc changes, the link-11 joint is moved in
the slot by a differentiable root solve (:meth:`~jaxdobby.machine.Machine.with_stroke`), so the
equality never needs a multiplier.

Example::

    space = DesignSpace.create(Setup(), ["thickness", "depth"], depth_positions_mm=[0, 80, 226])
    setup = space.setup(space.initial)        # the starting design as a Setup
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..arm import ArmDesign
from ..dobby import build_model
from ..errors import InputError
from ..outputs import coupled_frequencies
from ..parameters import Setup
from ..units import MM

VARIABLES: dict[str, tuple[str, float, str]] = {
    "thickness": ("mm", MM, "plate thickness of the arm"),
    "depth": ("mm", MM, "in-plane depth of the arm at a control point"),
    "arc_radius": ("mm", MM, "radius of the arm's arc (arc length kept)"),
    "heald_frame_mass": ("kg", 1.0, "mass moving with the heald frame"),
    "blade_inertia": ("kg m2", 1.0, "big blade's moment of inertia"),
}
"""name → (users' unit, one unit in SI, description)."""

DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {
    "thickness": (4.0, 8.0),
    "depth": (20.0, 80.0),
    "arc_radius": (250.0, 1000.0),
    "heald_frame_mass": (8.0, 18.0),
    "blade_inertia": (0.01, 0.04),
}
"""Default bounds [users' units]. Thickness: 12 mm heald-frame pitch minus 4 mm clearance for
washers and the neighbouring arm's bushes = 8 mm, the largest value the source study ran (an
assumption; set ``pitch_mm``/``clearance_mm``). Depth: 20 mm keeps material round the pins;
80 mm is twice the default. Heald frame 8–18 kg: DESIGN.md §6."""

def default_depth_positions(arm: ArmDesign) -> np.ndarray:
    """Depth control points [m of arc length]: pivot, ring-link joint, middle of the slot, end
    of the slot (the link-11 joint at the longest stroke), tip — 0, 80, 153, 201, 226 mm on
    the default arm."""
    return np.array([0.0, float(arm.ring_joint_arc_length),
                     0.5 * float(arm.arc_start + arm.arc_end), float(arm.arc_end),
                     float(arm.total_length)])

PITCH_MM, CLEARANCE_MM = 12.0, 4.0
"""Pitch between neighbouring arms (the heald-frame pitch of a rotary dobby) and the clearance
the arm must leave [mm]: t ≤ pitch − clearance (assumptions; no source gives them)."""


@dataclasses.dataclass(frozen=True)
class Constraints:
    """Limits of a design study (None: not imposed). SI units.

    Attributes:
        mass_budget: largest arm mass [kg].
        frequency_floor: smallest first coupled natural frequency [Hz].
        stress_limit: largest peak stress in the arm over the cycle [Pa] (smooth surrogate).
        fatigue_floor: smallest Goodman fatigue safety factor of the arm [-] (surrogate).
        speeds: loom speeds at which the stress constraints hold, the worst counts [rad/s].
    """

    mass_budget: float | None = None
    frequency_floor: float | None = None
    stress_limit: float | None = None
    fatigue_floor: float | None = None
    speeds: tuple[float, ...] = (800.0 * math.pi / 30.0,)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n, v in (("mass", self.mass_budget),
                                    ("frequency", self.frequency_floor),
                                    ("stress", self.stress_limit),
                                    ("fatigue", self.fatigue_floor)) if v is not None)


class DesignSpace(eqx.Module):
    """Normalised design variables u ∈ [0, 1]ⁿ ↔ a Setup (see the module docstring).

    Attributes:
        base: the design the variables modify (its other parameters stay as they are).
        variables: variable names, in order (static); ``depth`` covers ``n_depth`` entries.
        lower, upper: bounds of each entry [SI], shape (n,).
        initial: the base design's u, shape (n,) (clipped into the box).
        basis: the arm's reduction: ``"own"`` (default) — every design on its own first modes,
            differentiated as a subspace (:func:`jaxdobby.modal.mode_subspace`), the model
            ``jaxdobby simulate`` runs — or a fixed basis (n_dofs, n_modes) held constant (a
            Ritz reduction, e.g. ``arm_modes(base.machine).shapes``).
        target_stroke: rigid stroke kept when the arc changes [m].
        arc_length: arc length of the arm's arc, kept when its radius changes [m].
    """

    base: Setup
    variables: tuple[str, ...] = eqx.field(static=True)
    lower: Array
    upper: Array
    initial: Array
    basis: Array | str
    target_stroke: Array
    arc_length: Array

    @classmethod
    def create(cls, base: Setup, variables: Sequence[str],
               bounds: Mapping[str, tuple[float, float]] | None = None,
               depth_positions_mm: Sequence[float] | None = None,
               pitch_mm: float = PITCH_MM, clearance_mm: float = CLEARANCE_MM,
               basis: Array | str = "own") -> DesignSpace:
        """A design space around ``base`` (concrete values; raises InputError on bad input).

        Args:
            base: the starting design.
            variables: names from :data:`VARIABLES`, each at most once.
            bounds: (lower, upper) per name in users' units (default :data:`DEFAULT_BOUNDS`;
                the thickness's upper bound is capped at pitch − clearance).
            depth_positions_mm: arc lengths of the depth control points (default: those of
                ``base`` if it has several, else :func:`default_depth_positions`); the base
                depth profile is interpolated onto them.
            pitch_mm, clearance_mm: t ≤ pitch − clearance.
            basis: the arm's reduction (see the class attributes).
        """
        variables = tuple(variables)
        if not variables:
            raise InputError("--vars must name at least one of " + ", ".join(VARIABLES))
        for v in variables:
            if v not in VARIABLES:
                raise InputError(f"--vars: unknown design variable '{v}': valid are "
                                 + ", ".join(VARIABLES))
        if len(set(variables)) != len(variables):
            raise InputError("--vars names a design variable twice")
        if not pitch_mm > clearance_mm >= 0.0:
            raise InputError(f"pitch_mm = {pitch_mm:g} and clearance_mm = {clearance_mm:g}: "
                             "need pitch > clearance >= 0 [mm]")
        bounds = {**DEFAULT_BOUNDS, **(bounds or {})}
        arm = base.machine.arm
        if "depth" in variables or depth_positions_mm is not None:
            arm = _with_depth_positions(arm, depth_positions_mm)
            base = eqx.tree_at(lambda s: s.machine.arm, base, arm)
        lower, upper = [], []
        for v in variables:
            lo, hi = (float(b) for b in bounds[v])
            if v == "thickness":
                hi = min(hi, pitch_mm - clearance_mm)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo < hi):
                raise InputError(f"bounds of {v} = [{lo:g}, {hi:g}] {VARIABLES[v][0]}: need "
                                 f"0 < lower < upper" + (f" <= pitch - clearance = "
                                 f"{pitch_mm - clearance_mm:g} mm" if v == "thickness" else ""))
            n = arm.depth.shape[0] if v == "depth" else 1
            scale = VARIABLES[v][1]
            lower += [lo * scale] * n
            upper += [hi * scale] * n
        lower, upper = jnp.asarray(lower), jnp.asarray(upper)
        space = cls(base=base, variables=variables, lower=lower, upper=upper,
                    initial=jnp.zeros_like(lower), basis=basis,
                    target_stroke=base.machine.stroke(),
                    arc_length=arm.arc_radius * arm.arc_angle)
        if "arc_radius" in variables:
            _check_stroke_reachable(space)
        values = space.values(base)
        u0 = (values - lower) / (upper - lower)
        return dataclasses.replace(space, initial=jnp.clip(u0, 0.0, 1.0))

    # -- mapping ------------------------------------------------------------------------------
    @property
    def size(self) -> int:
        return self.lower.shape[0]

    def labels(self) -> list[str]:
        """One label per entry, e.g. ``thickness``, ``depth@80mm``."""
        out = []
        for v in self.variables:
            if v == "depth":
                out += [f"depth@{float(s) / MM:.0f}mm"
                        for s in self.base.machine.arm.depth_arc_lengths]
            else:
                out.append(v)
        return out

    def units(self) -> list[tuple[str, float]]:
        """(users' unit, one unit in SI) of each entry."""
        return [VARIABLES[name.split("@")[0]][:2] for name in self.labels()]

    def physical(self, u: Array) -> Array:
        """SI values of the variables, p = lower + u·(upper − lower)."""
        return self.lower + u * (self.upper - self.lower)

    def values(self, setup: Setup) -> Array:
        """SI values of the variables in ``setup`` (the inverse of :meth:`setup`)."""
        m = setup.machine
        get = {"thickness": lambda: m.arm.thickness[None], "depth": lambda: m.arm.depth,
               "arc_radius": lambda: m.arm.arc_radius[None],
               "heald_frame_mass": lambda: m.heald_frame_mass[None],
               "blade_inertia": lambda: m.blade_inertia[None]}
        return jnp.concatenate([get[v]() for v in self.variables])

    def setup(self, u: Array) -> Setup:
        """The Setup of normalised variables ``u`` (differentiable; stroke kept if the arc moves)."""
        p = self.physical(u)
        setup, i = self.base, 0
        for v in self.variables:
            n = self.base.machine.arm.depth.shape[0] if v == "depth" else 1
            value = p[i:i + n] if v == "depth" else p[i]
            i += n
            if v == "arc_radius":
                arm = dataclasses.replace(setup.machine.arm, arc_radius=value,
                                          arc_angle=self.arc_length / value)
                setup = eqx.tree_at(lambda s: s.machine.arm, setup, arm)
            elif v in ("thickness", "depth"):
                setup = eqx.tree_at(lambda s, v=v: getattr(s.machine.arm, v), setup, value)
            else:
                setup = eqx.tree_at(lambda s, v=v: getattr(s.machine, v), setup, value)
        if "arc_radius" in self.variables:
            setup = eqx.tree_at(lambda s: s.machine, setup,
                                setup.machine.with_stroke(self.target_stroke))
        return setup

    def project(self, u: Array) -> Array:
        """Projection onto the box [0, 1]ⁿ."""
        return jnp.clip(u, 0.0, 1.0)


def _check_stroke_reachable(space: DesignSpace) -> None:
    """The kept stroke must be reachable in the slot at both bounds of the arc radius."""
    from ..stroke import stroke_range

    i = space.labels().index("arc_radius")
    target = float(space.target_stroke)
    for radius in (float(space.lower[i]), float(space.upper[i])):
        arm = dataclasses.replace(space.base.machine.arm, arc_radius=radius,
                                  arc_angle=space.arc_length / radius)
        lo, hi = (float(x) for x in stroke_range(space.base.machine.replace(arm=arm).chain))
        if not lo - 1e-9 <= target <= hi + 1e-9:
            raise InputError(
                f"stroke {target / MM:.2f} mm cannot be kept with arc radius {radius / MM:g} mm "
                f"(reachable {lo / MM:.2f} … {hi / MM:.2f} mm): narrow the arc_radius bounds or "
                "give a smaller --stroke")


def _with_depth_positions(arm: ArmDesign, positions_mm) -> ArmDesign:
    """``arm`` with its depth profile interpolated onto control points (mm, increasing)."""
    if positions_mm is None:
        if arm.depth.shape[0] > 1:
            return arm
        positions_mm = default_depth_positions(arm) / MM
    s = np.asarray(positions_mm, dtype=float)
    total = float(arm.total_length) / MM
    if s.ndim != 1 or s.size < 1 or not np.all(np.isfinite(s)):
        raise InputError("depth_positions_mm must be a list of numbers [mm]")
    if np.any(np.diff(s) <= 0) or s[0] < 0 or s[-1] > total + 1e-9:
        raise InputError(f"depth_positions_mm = {s.tolist()} must increase strictly within the "
                         f"arm, 0 … {total:g} mm")
    depth = jnp.interp(jnp.asarray(s * MM), arm.depth_arc_lengths, arm.depth)
    return dataclasses.replace(arm, depth=depth, depth_arc_lengths=s * MM)


# -- constraints -------------------------------------------------------------------------------
def arm_mass(setup: Setup) -> Array:
    """Mass of the bending arm [kg]."""
    return setup.machine.arm.mass()


def first_frequency(setup: Setup, basis: Array | str | None = None) -> Array:
    """First coupled natural frequency of the mechanism at mid-stroke [Hz] (speed-free).

    Eigenvalues only (``eigvalsh``): their derivatives have no 1/(λᵢ − λⱼ) terms.
    """
    model = build_model(setup.machine, setup.operating, basis)
    return coupled_frequencies(model)[0]


def constraints(space: DesignSpace, limits: Constraints, u: Array) -> Array:
    """Normalised constraint values c(u), feasible when ≤ 0, in the order of ``limits.names``."""
    setup = space.setup(u)
    out = []
    if limits.mass_budget is not None:
        out.append(arm_mass(setup) / limits.mass_budget - 1.0)
    if limits.frequency_floor is not None:
        out.append(1.0 - first_frequency(setup, space.basis) / limits.frequency_floor)
    if limits.stress_limit is not None or limits.fatigue_floor is not None:
        from ..stress.design import stress_constraints

        out += stress_constraints(setup, space.basis, limits.speeds, limits.stress_limit,
                                  limits.fatigue_floor)
    return jnp.stack(out) if out else jnp.zeros(0)


def constraint_jacobian(space: DesignSpace, limits: Constraints, u: Array):
    """c(u) and its Jacobian (n_c, n) by forward mode (cheap without the stress rows; those
    integrate one steady cycle per speed, :mod:`jaxdobby.stress.design`)."""
    return _constraint_values_and_jacobian(space, limits, u)


@eqx.filter_jit
def _constraint_values_and_jacobian(space, limits, u):
    fn = lambda x: constraints(space, limits, x)
    return fn(u), jax.jacfwd(fn)(u)


def affine_rows(space: DesignSpace, limits: Constraints) -> tuple[int, ...]:
    """Rows of :func:`constraints` that are affine in u over the whole box (to round-off).

    The arm mass is ρ·t·∫d ds: linear in the thickness alone and in the depth control points
    alone (piecewise-linear depth, integrated exactly), bilinear when both vary, and the first
    frequency is never linear. Checked numerically rather than by name: the Jacobian at the
    corners u = 0, u = 1 and two inner points must agree, and c(1) − c(0) = J·1.
    """
    # all strongly typed float64 (jnp.full of a Python float alone is weakly typed, a second
    # compilation of the same program)
    points = [jnp.zeros(space.size), jnp.ones(space.size), jnp.full(space.size, 0.3, dtype=float),
              jnp.linspace(0.9, 0.1, space.size)]
    values = [constraint_jacobian(space, limits, u) for u in points]
    c = np.stack([np.asarray(v[0]) for v in values])
    jac = np.stack([np.asarray(v[1]) for v in values])
    rows = []
    for k in range(c.shape[1]):
        scale = float(np.max(np.abs(jac[:, k]))) + 1e-300
        same = np.all(np.abs(jac[:, k] - jac[0, k]) <= 1e-10 * scale)
        secant = abs(c[1, k] - c[0, k] - float(np.sum(jac[0, k]))) <= 1e-10 * scale * space.size
        if same and secant:
            rows.append(k)
    return tuple(rows)


def check_mass_budget(space: DesignSpace, limits: Constraints) -> None:
    """The budget must admit the lightest arm in the bounds (every variable at its lower bound:
    the mass grows with thickness and depth, and the others do not change it)."""
    if limits.mass_budget is None:
        return
    lightest = float(arm_mass(space.setup(jnp.zeros(space.size))))
    if lightest > limits.mass_budget:
        raise InputError(f"mass budget = {limits.mass_budget:g} kg is below the lightest arm "
                         f"within the bounds ({lightest:.4f} kg): raise the budget or lower the "
                         "thickness/depth bounds")


@eqx.filter_jit
def properties(space: DesignSpace, u: Array, own_modes: bool = False) -> dict[str, Array]:
    """Arm mass [kg], first coupled frequency [Hz] and rigid stroke [m] of the design ``u``
    (frequency on the space's basis, or with ``own_modes`` on the design's own modes)."""
    setup = space.setup(u)
    basis = "own" if own_modes else space.basis
    return {"mass": arm_mass(setup), "frequency": first_frequency(setup, basis),
                "stroke": setup.machine.stroke()}
