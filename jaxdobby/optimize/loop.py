"""The optimisation loop: box bounds by projection, constraints by an augmented Lagrangian.

For inequality constraints c(u) ≤ 0 the augmented Lagrangian of Powell–Hestenes–Rockafellar
(Nocedal & Wright, *Numerical Optimization*, 2nd ed., §17.4, eq. 17.65),

    L(u; λ, ρ) = J(u) + Σⱼ [max(0, λⱼ + ρ cⱼ(u))² − λⱼ²] / (2ρ),

is minimised over the box 0 ≤ u ≤ 1 for fixed multipliers λ by projected steps, and after every
``inner_steps`` iterations the multipliers are updated, λ ← max(0, λ + ρ c), and the penalty ρ
is raised ×10 if the worst violation did not fall to a quarter. L is continuously
differentiable, so the inner problem suits both optimisers:

* ``adam`` (optax): u ← P(u + Adam(∇L)), learning rate decaying along a cosine to 2 % of its
  start over the run (P the projection, clipping, onto the box);
* ``lbfgs`` (optax's ``scale_by_lbfgs`` for the direction): projected L-BFGS — the variables at
  a bound whose gradient points out of the box are held (their gradient and step zeroed), the
  L-BFGS direction of the others is followed along the projected path with Armijo
  backtracking (Bertsekas, *Nonlinear Programming*, §2.3 and Kelley, *Iterative Methods for
  Optimization*, §5.5); the memory is reset when the multipliers change.

The first-order optimality conditions are reported at the end: the projected gradient of the
Lagrangian J + λᵀc on the box (zero at a KKT point), the violation max(c, 0), and the
complementarity λᵀc.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np
import optax

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
    out = g.copy()
    out[(u <= 0.0) & (g > 0.0)] = 0.0
    out[(u >= 1.0) & (g < 0.0)] = 0.0
    return out


def _augmented(j, g_j, c, jac_c, lam, rho):
    shifted = np.maximum(0.0, lam + rho * c)
    value = j + float(np.sum(shifted**2 - lam**2)) / (2.0 * rho)
    grad = g_j + (jac_c.T @ shifted if c.size else 0.0)
    return value, grad


class _Problem:
    """Evaluations of J, c and L, counted."""

    def __init__(self, value_and_grad, constraints):
        self.value_and_grad, self.constraints, self.count = value_and_grad, constraints, 0

    def __call__(self, u, lam, rho):
        self.count += 1
        j, g_j, values = self.value_and_grad(u)
        c, jac_c = self.constraints(u)
        c, jac_c = np.asarray(c, dtype=float), np.asarray(jac_c, dtype=float)
        value, grad = _augmented(j, np.asarray(g_j, dtype=float), c, jac_c, lam, rho)
        return {"j": j, "g_j": np.asarray(g_j, dtype=float), "c": c, "jac_c": jac_c, "value": value,
                    "grad": grad, "values": values}


def optimize(value_and_grad: Callable, constraints: Callable, u0, settings: Settings,
             callback: Callable[[Record], None] | None = None) -> Result:
    """Minimise J over the box [0, 1]ⁿ subject to c(u) ≤ 0, from ``u0``.

    Args:
        value_and_grad: u ↦ (J, ∇J, values) (values: anything to keep in the history), e.g.
            :meth:`jaxdobby.optimize.objective.Evaluator.value_and_grad`.
        constraints: u ↦ (c, ∂c/∂u) with shapes (n_c,) and (n_c, n), e.g.
            :func:`jaxdobby.optimize.design.constraint_jacobian`.
        u0: starting point (projected onto the box).
        settings: the optimiser's settings.
        callback: called with every iteration's :class:`Record` (the command prints a line).
    """
    if settings.optimizer not in OPTIMIZERS:
        raise ValueError(f"optimizer must be one of {OPTIMIZERS}, got {settings.optimizer!r}")
    problem = _Problem(value_and_grad, constraints)
    u = np.clip(np.asarray(u0, dtype=float), 0.0, 1.0)
    n_c = np.asarray(constraints(u)[0]).shape[0]
    lam, rho = np.zeros(n_c), float(settings.penalty)
    start = time.perf_counter()
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

    def record(i):
        pg = projected_gradient(u, point["grad"])
        rec = Record(iteration=i, u=u.copy(), objective=point["j"], lagrangian=point["value"],
                     constraints=point["c"].copy(), multipliers=lam.copy(), penalty=rho,
                     projected_gradient=float(np.max(np.abs(pg), initial=0.0)),
                     values=point["values"], evaluations=problem.count,
                     seconds=time.perf_counter() - start)
        history.append(rec)
        if callback is not None:
            callback(rec)
        return rec

    record(0)
    for i in range(1, settings.steps + 1):
        if settings.optimizer == "adam":
            updates, state = transform.update(point["grad"], state, u)
            u = np.clip(u + np.asarray(updates), 0.0, 1.0)
            point = problem(u, lam, rho)
        else:
            u, point, state = _lbfgs_step(problem, transform, state, u, point, lam, rho)
        rec = record(i)
        violation = float(np.max(point["c"], initial=0.0))
        stationary = rec.projected_gradient < settings.tolerance
        if n_c == 0:
            if stationary:
                converged = True
                break
            continue
        if settings.optimizer == "adam":
            # Adam's steps do not shrink with the gradient, so its inner problems are never
            # solved exactly: the multipliers follow by damped ascent at every step instead
            # (a primal-dual iteration), the penalty fixed.
            lam = np.maximum(0.0, lam + rho * point["c"] / settings.inner_steps)
            value, grad = _augmented(point["j"], point["g_j"], point["c"], point["jac_c"],
                                     lam, rho)
            point = {**point, "value": value, "grad": grad}
            pg = float(np.max(np.abs(projected_gradient(u, grad)), initial=0.0))
            if pg < settings.tolerance and violation < settings.tolerance:
                converged = True
                break
            continue
        # Multiplier update: every inner_steps iterations, or early once the inner problem is
        # solved (a stationary point of L for these multipliers).
        if i % settings.inner_steps == 0 or stationary:
            new_lam = np.maximum(0.0, lam + rho * point["c"])
            settled = np.max(np.abs(new_lam - lam), initial=0.0) < settings.tolerance
            if stationary and violation < settings.tolerance and settled:
                converged = True
                break
            if violation > 0.25 * last_violation and violation > settings.tolerance:
                rho *= 10.0
            last_violation = violation
            lam = new_lam
            value, grad = _augmented(point["j"], point["g_j"], point["c"], point["jac_c"],
                                     lam, rho)
            point = {**point, "value": value, "grad": grad}
            state = transform.init(u)  # L changed: old curvature pairs would mislead
    return Result(u=u, history=history, multipliers=lam,
                  optimality=optimality(u, point, lam), converged=converged)


def _lbfgs_step(problem, transform, state, u, point, lam, rho, max_halvings: int = 8):
    """One projected L-BFGS step with Armijo backtracking along the projected path."""
    g = point["grad"]
    free = projected_gradient(u, g) != 0.0
    direction, new_state = transform.update(np.where(free, g, 0.0), state, u)
    d = -np.where(free, np.asarray(direction), 0.0)
    if not np.dot(d, g) < 0.0:  # not a descent direction: restart from steepest descent
        new_state = transform.init(u)
        d = -np.where(free, g, 0.0) / max(1.0, float(np.linalg.norm(g)))
    alpha = 1.0
    for _ in range(max_halvings + 1):
        trial = np.clip(u + alpha * d, 0.0, 1.0)
        new = problem(trial, lam, rho)
        if new["value"] <= point["value"] + 1e-4 * float(np.dot(g, trial - u)):
            return trial, new, new_state
        alpha *= 0.5
    return u, point, transform.init(u)  # no decrease found: stay, forget the curvature


def optimality(u: np.ndarray, point: dict, lam: np.ndarray) -> dict[str, float]:
    """First-order conditions at ``u``: projected gradient of J + λᵀc, violation, λᵀc."""
    c = point["c"]
    grad = point["g_j"] + (point["jac_c"].T @ lam if c.size else 0.0)
    pg = projected_gradient(u, grad)
    return {"projected_gradient": float(np.max(np.abs(pg), initial=0.0)),
                "objective_gradient": float(np.max(np.abs(point["g_j"]), initial=0.0)),
                "violation": float(np.max(c, initial=0.0)),
                "complementarity": float(abs(np.dot(lam, c))) if c.size else 0.0}
