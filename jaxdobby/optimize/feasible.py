"""The feasible set of the normalised design variables: the box [0, 1]ⁿ, cut by at most one
linear inequality a·u ≤ b held exactly (the arm-mass budget: the mass is linear in the plate
thickness alone and in the depth control points alone).

*Projection.* The Euclidean projection of v onto X = {0 ≤ u ≤ 1, a·u ≤ b} is, by its KKT
conditions, u(μ) = clip(v − μa, 0, 1) with μ ≥ 0 the smallest value for which a·u(μ) ≤ b;
a·u(μ) is continuous and non-increasing in μ, so μ is found by bisection and then made exact on
the final set of free components (Held, Wolfe & Crowder 1974; Bertsekas, *Nonlinear
Programming*, 3rd ed., §2.3, on projection onto a box cut by one constraint).

*Stationarity.* u is a KKT point of min J over X iff there is μ ≥ 0 with μ(a·u − b) = 0 such that
each component of g + μa is zero where u is strictly inside its bounds, ≥ 0 at its lower and
≤ 0 at its upper bound. :meth:`FeasibleSet.reduced_gradient` estimates μ by least squares on the
free components (those not held at a bound) and returns g + μa with the held components zeroed:
zero exactly at a KKT point, and the quantity the optimiser steps along and reports.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np


def box_projected_gradient(u: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Gradient with the components that would leave the box [0, 1] zeroed."""
    out = np.array(g, dtype=float, copy=True)
    out[(u <= 0.0) & (out > 0.0)] = 0.0
    out[(u >= 1.0) & (out < 0.0)] = 0.0
    return out


class Reduced(NamedTuple):
    """The reduced gradient at a point (see :meth:`FeasibleSet.reduced_gradient`)."""

    gradient: np.ndarray  # g + μa, held components zeroed (zero at a KKT point)
    multiplier: float  # μ ≥ 0 of the linear constraint
    held: np.ndarray  # components held at a bound (bool)


@dataclasses.dataclass(frozen=True)
class FeasibleSet:
    """[0, 1]ⁿ ∩ {u : a·u ≤ b}; without ``a``, the box alone.

    Attributes:
        a: normal of the linear inequality, shape (n,), or None.
        b: its right-hand side.
    """

    a: np.ndarray | None = None
    b: float = 0.0

    def __post_init__(self):
        if self.a is not None:
            lightest = float(np.sum(np.minimum(self.a, 0.0)))
            if lightest > self.b:
                raise ValueError(f"the linear constraint a·u <= {self.b:g} cannot be met in the "
                                 f"box (its smallest value there is {lightest:g})")

    @property
    def has_halfspace(self) -> bool:
        return self.a is not None

    def slack(self, u: np.ndarray) -> float:
        """b − a·u (≥ 0 when the linear inequality holds; +inf without one)."""
        return np.inf if self.a is None else float(self.b - np.dot(self.a, u))

    def active(self, u: np.ndarray) -> bool:
        """Whether u lies on the linear constraint (to round-off)."""
        if self.a is None:
            return False
        return self.slack(u) <= 1e-12 * (abs(self.b) + float(np.sum(np.abs(self.a))))

    def project(self, v: np.ndarray) -> np.ndarray:
        """Euclidean projection of ``v`` onto the set."""
        x = np.clip(np.asarray(v, dtype=float), 0.0, 1.0)
        if self.a is None or np.dot(self.a, x) <= self.b:
            return x
        a, b = self.a, self.b
        at = lambda mu: np.clip(v - mu * a, 0.0, 1.0)
        lo, hi = 0.0, 1.0
        while np.dot(a, at(hi)) > b:
            lo, hi = hi, 2.0 * hi
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if np.dot(a, at(mid)) > b:
                lo = mid
            else:
                hi = mid
            if hi - lo <= 1e-16 * hi:
                break
        x = at(hi)
        # Exact μ on the free set of the bisection's answer (round-off on the constraint).
        free = (x > 0.0) & (x < 1.0) & (a != 0.0)
        if free.any():
            mu = (np.dot(a[free], v[free]) + np.dot(a[~free], x[~free]) - b) \
                / np.dot(a[free], a[free])
            exact = at(mu)
            same = np.array_equal((exact > 0.0) & (exact < 1.0) & (a != 0.0), free)
            if mu >= 0.0 and same and np.dot(a, exact) <= b + 1e-15 * (abs(b) + 1.0):
                x = exact
        return x

    def reduced_gradient(self, u: np.ndarray, g: np.ndarray) -> Reduced:
        """g + μa with the components held at a bound zeroed, μ, and the held components, at
        ``u`` (see the module docstring); μ = 0 unless ``u`` is on the linear constraint and the
        gradient presses on it.
        """
        g = np.asarray(g, dtype=float)
        if not self.active(u):
            held = ((u <= 0.0) & (g > 0.0)) | ((u >= 1.0) & (g < 0.0))
            return Reduced(box_projected_gradient(u, g), 0.0, held)
        a = self.a
        mu, held = 0.0, None
        for _ in range(u.shape[0] + 2):  # the held set settles in a few passes
            gm = g + mu * a
            new = ((u <= 0.0) & (gm > 0.0)) | ((u >= 1.0) & (gm < 0.0))
            if held is not None and np.array_equal(new, held):
                break
            held = new
            af = np.where(held, 0.0, a)
            norm2 = float(np.dot(af, af))
            mu = max(0.0, -float(np.dot(af, np.where(held, 0.0, g))) / norm2) if norm2 else 0.0
        r = g + mu * a
        r[held] = 0.0
        return Reduced(r, mu, held)

    def tangent(self, u: np.ndarray, d: np.ndarray, held: np.ndarray, pressed: bool) -> np.ndarray:
        """``d`` with the held components zeroed and, when the gradient presses on the linear
        constraint (``pressed``), its component along a removed: a step along the face."""
        d = np.where(held, 0.0, d)
        if pressed and self.a is not None:
            af = np.where(held, 0.0, self.a)
            norm2 = float(np.dot(af, af))
            if norm2:
                d = d - af * float(np.dot(af, d)) / norm2
        return d
