"""The optimisation loop: bounds and a linear constraint by projection, other constraints by an
augmented Lagrangian.

The bounds 0 ≤ u ≤ 1 and at most one affine constraint (the arm-mass budget; see
:mod:`jaxdobby.optimize.feasible`) are held exactly: every iterate is projected onto their
intersection, and at a KKT point the reduced gradient is zero with the constraint's multiplier
μ ≥ 0 read off the free components. The other constraints (the first coupled frequency, which
is not linear in the design) go into the augmented Lagrangian below.

For inequality constraints c(u) ≤ 0 the augmented Lagrangian of Powell–Hestenes–Rockafellar
(Nocedal & Wright, *Numerical Optimization*, 2nd ed., §17.4, eq. 17.65),

    L(u; λ, ρ) = J(u) + Σⱼ [max(0, λⱼ + ρ cⱼ(u))² − λⱼ²] / (2ρ),

is minimised over that feasible set for fixed multipliers λ by projected steps, and after every
``inner_steps`` iterations the multipliers are updated, λ ← max(0, λ + ρ c), and the penalty ρ
is raised ×10 if the worst violation did not fall to a quarter. L is continuously
differentiable, so the inner problem suits both optimisers:

* ``adam`` (optax): u ← P(u + Adam(r)), r the reduced gradient of L, learning rate decaying along a cosine to 2 % of its
  start over the run (P the projection onto the feasible set);
* ``lbfgs`` (optax's ``scale_by_lbfgs`` for the direction): projected L-BFGS — the variables at
  a bound whose reduced gradient points out of the box are held (their step zeroed), on the
  linear constraint's face the direction is kept in the face, and the step follows the
  projected path with Armijo backtracking (Bertsekas, *Nonlinear Programming*, §2.3 and
  Kelley, *Iterative Methods for Optimization*, §5.5); the memory is reset when the
  multipliers change.

The first-order optimality conditions are reported at the end: the reduced gradient of the
Lagrangian J + λᵀc (zero at a KKT point), the violation max(c, 0), and the complementarity λᵀc.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

import numpy as np

from .feasible import FeasibleSet, box_projected_gradient

OPTIMIZERS = ("adam", "lbfgs")


@dataclasses.dataclass(frozen=True)
class Settings:
    """Settings of the optimiser.

    Attributes:
        optimizer: ``adam`` or ``lbfgs``.
        steps: iterations (each one gradient evaluation; a backtracking L-BFGS step may take a
            few more).
        learning_rate: Adam's initial step in normalised variables (1 = the whole box).
        inner_steps: iterations between multiplier updates.
        penalty: initial ρ of the augmented Lagrangian (constraints are O(1)-normalised).
        tolerance: stop when the projected gradient of L (∞-norm) and the violation are below it
            (and, with constraints, the multipliers have settled).
    """

    optimizer: str = "lbfgs"
    steps: int = 20
    learning_rate: float = 0.05
    inner_steps: int = 5
    penalty: float = 10.0
    tolerance: float = 1e-4


@dataclasses.dataclass
class Record:
    """One iteration of the history (normalised variables u; SI metrics per speed)."""

    iteration: int
    u: np.ndarray
    objective: float
    lagrangian: float
    constraints: np.ndarray
    multipliers: np.ndarray
    penalty: float
    projected_gradient: float
    values: dict[str, np.ndarray]
    evaluations: int
    seconds: float


@dataclasses.dataclass
class Result:
    """The optimised design and how it got there."""

    u: np.ndarray
    history: list[Record]
    multipliers: np.ndarray
    optimality: dict[str, float]
    converged: bool


def projected_gradient(u: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Gradient with the components that would leave the box [0, 1] zeroed."""
    return box_projected_gradient(u, g)


def _augmented(j, g_j, c, jac_c, lam, rho):
    shifted = np.maximum(0.0, lam + rho * c)
    value = j + float(np.sum(shifted**2 - lam**2)) / (2.0 * rho)
    grad = g_j + (jac_c.T @ shifted if c.size else 0.0)
    return value, grad


class _Problem:
    """Evaluations of J, c and L (L over the rows not held by projection), counted."""

    def __init__(self, value_and_grad, constraints, nonlinear: np.ndarray):
        self.value_and_grad, self.constraints, self.count = value_and_grad, constraints, 0
        self.nonlinear = nonlinear

    def __call__(self, u, lam, rho):
        self.count += 1
        j, g_j, values = self.value_and_grad(u)
        c, jac_c = self.constraints(u)
        c, jac_c = np.asarray(c, dtype=float), np.asarray(jac_c, dtype=float)
        g_j = np.asarray(g_j, dtype=float)
        value, grad = _augmented(j, g_j, c[self.nonlinear], jac_c[self.nonlinear], lam, rho)
        return {"j": j, "g_j": g_j, "c": c, "jac_c": jac_c, "value": value, "grad": grad,
                "values": values}

    def relagrange(self, point, lam, rho):
        """``point`` with L and its gradient recomputed for new multipliers."""
        nl = self.nonlinear
        value, grad = _augmented(point["j"], point["g_j"], point["c"][nl], point["jac_c"][nl],
                                 lam, rho)
        return {**point, "value": value, "grad": grad}


def feasible_set(constraints: Callable, u: np.ndarray, linear: Sequence[int]) -> FeasibleSet:
    """The box cut by the affine constraint row ``linear`` (at most one) of ``constraints``:
    c(u) = c(u₀) + ∂c/∂u (u − u₀) ≤ 0, i.e. a·u ≤ b with a = ∂c/∂u, b = a·u₀ − c(u₀)."""
    if len(linear) == 0:
        return FeasibleSet()
    if len(linear) > 1:
        raise ValueError("at most one constraint can be held by projection (linear=...)")
    c, jac = (np.asarray(x, dtype=float) for x in constraints(u))
    a = jac[linear[0]]
    return FeasibleSet(a=a, b=float(np.dot(a, u) - c[linear[0]]))


def optimize(value_and_grad: Callable, constraints: Callable, u0, settings: Settings,
             callback: Callable[[Record], None] | None = None,
             linear: Sequence[int] = ()) -> Result:
    """Minimise J over the box [0, 1]ⁿ subject to c(u) ≤ 0, from ``u0``.

    Args:
        value_and_grad: u ↦ (J, ∇J, values) (values: anything to keep in the history), e.g.
            :meth:`jaxdobby.optimize.objective.Evaluator.value_and_grad`.
        constraints: u ↦ (c, ∂c/∂u) with shapes (n_c,) and (n_c, n), e.g.
            :func:`jaxdobby.optimize.design.constraint_jacobian`.
        u0: starting point (projected onto the feasible set of the box and the linear row).
        settings: the optimiser's settings.
        callback: called with every iteration's :class:`Record` (the command prints a line).
        linear: index of a row of c that is affine in u (at most one; e.g. the mass budget,
            see :func:`jaxdobby.optimize.design.affine_rows`): it is held exactly by projection
            (every iterate satisfies it) instead of by the augmented Lagrangian.
    """
    if settings.optimizer not in OPTIMIZERS:
        raise ValueError(f"optimizer must be one of {OPTIMIZERS}, got {settings.optimizer!r}")
    u = np.clip(np.asarray(u0, dtype=float), 0.0, 1.0)
    n_c = np.asarray(constraints(u)[0]).shape[0]
    nonlinear = np.ones(n_c, dtype=bool)
    nonlinear[list(linear)] = False
    feasible = feasible_set(constraints, u, list(linear))
    u = feasible.project(u)
    problem = _Problem(value_and_grad, constraints, nonlinear)
    n_nl = int(nonlinear.sum())
    lam, rho = np.zeros(n_nl), float(settings.penalty)
    start = time.perf_counter()
    import optax  # here, not at the top: every jaxdobby command imports this package (~0.1 s)

    if settings.optimizer == "adam":
        schedule = optax.cosine_decay_schedule(settings.learning_rate, max(settings.steps, 1),
                                               alpha=0.02)
        transform = optax.adam(schedule)
    else:
        transform = optax.scale_by_lbfgs()
    state = transform.init(u)
    point = problem(u, lam, rho)
    history: list[Record] = []
    last_violation = np.inf
    converged = False

    def multipliers(reduced):
        out = np.zeros(n_c)
        out[nonlinear] = lam
        out[~nonlinear] = reduced.multiplier
        return out

    def record(i):
        reduced = feasible.reduced_gradient(u, point["grad"])
        rec = Record(iteration=i, u=u.copy(), objective=point["j"], lagrangian=point["value"],
                     constraints=point["c"].copy(), multipliers=multipliers(reduced),
                     penalty=rho,
                     projected_gradient=float(np.max(np.abs(reduced.gradient), initial=0.0)),
                     values=point["values"], evaluations=problem.count,
                     seconds=time.perf_counter() - start)
        history.append(rec)
        if callback is not None:
            callback(rec)
        return rec

    first = record(0)
    if n_nl == 0 and first.projected_gradient < settings.tolerance:
        return Result(u=u, history=history, multipliers=first.multipliers,
                      optimality=optimality(u, point, lam, feasible, nonlinear), converged=True)
    for i in range(1, settings.steps + 1):
        if settings.optimizer == "adam":
            # Adam scales each component on its own, so a step along the full gradient would
            # mostly point off the face of an active constraint and be projected away: it
            # follows the reduced gradient (the part that can move) instead.
            reduced = feasible.reduced_gradient(u, point["grad"])
            updates, state = transform.update(reduced.gradient, state, u)
            u = feasible.project(u + np.asarray(updates))
            point = problem(u, lam, rho)
        else:
            u, point, state = _lbfgs_step(problem, feasible, transform, state, u, point, lam,
                                          rho)
        rec = record(i)
        violation = float(np.max(point["c"][nonlinear], initial=0.0))
        stationary = rec.projected_gradient < settings.tolerance
        if n_nl == 0:
            if stationary:
                converged = True
                break
            continue
        if settings.optimizer == "adam":
            # Adam's steps do not shrink with the gradient, so its inner problems are never
            # solved exactly: the multipliers follow by damped ascent at every step instead
            # (a primal-dual iteration), the penalty fixed.
            lam = np.maximum(0.0, lam + rho * point["c"][nonlinear] / settings.inner_steps)
            point = problem.relagrange(point, lam, rho)
            reduced = feasible.reduced_gradient(u, point["grad"])
            pg = float(np.max(np.abs(reduced.gradient), initial=0.0))
            if pg < settings.tolerance and violation < settings.tolerance:
                converged = True
                break
            continue
        # Multiplier update: every inner_steps iterations, or early once the inner problem is
        # solved (a stationary point of L for these multipliers).
        if i % settings.inner_steps == 0 or stationary:
            new_lam = np.maximum(0.0, lam + rho * point["c"][nonlinear])
            settled = np.max(np.abs(new_lam - lam), initial=0.0) < settings.tolerance
            if stationary and violation < settings.tolerance and settled:
                converged = True
                break
            if violation > 0.25 * last_violation and violation > settings.tolerance:
                rho *= 10.0
            last_violation = violation
            lam = new_lam
            point = problem.relagrange(point, lam, rho)
            state = transform.init(u)  # L changed: old curvature pairs would mislead
    return Result(u=u, history=history, multipliers=history[-1].multipliers,
                  optimality=optimality(u, point, lam, feasible, nonlinear), converged=converged)


def _lbfgs_step(problem, feasible, transform, state, u, point, lam, rho, max_halvings: int = 8):
    """One projected L-BFGS step with Armijo backtracking along the projected path.

    The components held at a bound keep being pushed outwards by their gradient (so that the
    projection keeps them there); the free ones follow the L-BFGS direction, taken along the
    linear constraint's face when the gradient presses on it. If no decrease is found along
    that path, the projected-gradient path P(u − αg) is searched instead, which gives a
    decrease for small enough α wherever u is not stationary (Bertsekas, *Nonlinear
    Programming*, Prop. 2.3.3).
    """
    g = point["grad"]
    reduced = feasible.reduced_gradient(u, g)
    pressed = reduced.multiplier > 0.0
    direction, new_state = transform.update(np.where(reduced.held, 0.0, g), state, u)
    d = feasible.tangent(u, -np.asarray(direction), reduced.held, pressed)
    if not np.dot(d, g) < 0.0:  # not a descent direction: restart from the reduced gradient
        new_state = transform.init(u)
        r = reduced.gradient
        d = -r / max(1.0, float(np.linalg.norm(r)))
    d = np.where(reduced.held, -g, d)
    found = _armijo(problem, feasible, u, point, d, lam, rho, 1.0, max_halvings)
    if found is not None:
        return found[0], found[1], new_state
    scale = 1.0 / max(1.0, float(np.max(np.abs(g))))
    found = _armijo(problem, feasible, u, point, -g, lam, rho, scale, 30)
    if found is not None:
        return found[0], found[1], transform.init(found[0])
    return u, point, transform.init(u)  # no decrease found: stay, forget the curvature


def _armijo(problem, feasible, u, point, d, lam, rho, alpha, halvings):
    """The first α = alpha·2⁻ᵏ (k ≤ halvings) with sufficient decrease along P(u + αd)."""
    g = point["grad"]
    for _ in range(halvings + 1):
        trial = feasible.project(u + alpha * d)
        if np.array_equal(trial, u):
            return None
        new = problem(trial, lam, rho)
        if new["value"] <= point["value"] + 1e-4 * float(np.dot(g, trial - u)):
            return trial, new
        alpha *= 0.5
    return None


def optimality(u: np.ndarray, point: dict, lam: np.ndarray,
               feasible: FeasibleSet | None = None,
               nonlinear: np.ndarray | None = None) -> dict[str, float]:
    """First-order conditions at ``u``: the reduced gradient of J + λᵀc (zero at a KKT point),
    the violation max(c, 0) and |λᵀc|, with λ the augmented Lagrangian's multipliers for the
    rows in ``nonlinear`` and the projection's μ for the linear row."""
    feasible = feasible or FeasibleSet()
    c, jac = point["c"], point["jac_c"]
    nonlinear = np.ones(c.shape[0], dtype=bool) if nonlinear is None else nonlinear
    grad = point["g_j"] + (jac[nonlinear].T @ lam if lam.size else 0.0)
    reduced = feasible.reduced_gradient(u, grad)
    full = np.zeros(c.shape[0])
    full[nonlinear] = lam
    full[~nonlinear] = reduced.multiplier
    return {"projected_gradient": float(np.max(np.abs(reduced.gradient), initial=0.0)),
            "objective_gradient": float(np.max(np.abs(point["g_j"]), initial=0.0)),
            "violation": float(np.max(c, initial=0.0)),
            "complementarity": float(abs(np.dot(full, c))) if c.size else 0.0}
