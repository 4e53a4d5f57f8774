"""One design study end to end: build, optimise, verify, report.

:func:`run_study` takes a :class:`Study` (everything ``jaxdobby optimize`` was asked for, in SI),
runs the optimiser and returns a :class:`StudyResult`: the history rows, the result summary
(users' units), the optimised Setup and its TOML, and the time series for the figures.

*Model.* The optimiser's model is the one ``jaxdobby simulate`` runs: every design reduced on
its own first modes, whose derivative is taken as that of the subspace they span
(:func:`jaxdobby.modal.mode_subspace`; no 1/(λᵢ − λⱼ) between kept modes), so the optimum is a
KKT point of that model and ``jaxdobby simulate --config design.toml`` reproduces its numbers.
(A fixed Ritz basis, ``DesignSpace.create(..., basis=...)``, is a cheaper-to-reason-about
alternative, but it stiffens designs far from the one it came from: an arm 20 mm deep over most
of its length has its first coupled mode at 70 Hz on its own modes and at 176 Hz on the
default arm's, and an optimiser trusting it ends where the true deviation is much larger than
it believes.)

*Verification.* At the end the starting and optimised designs are re-evaluated on their own
modes (the reported numbers; with the default model, the optimiser's own values).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from ..config import RunOptions, to_toml
from ..parameters import Setup
from ..units import MM, RPM
from .design import (
    Constraints,
    DesignSpace,
    affine_rows,
    check_mass_budget,
    constraint_jacobian,
    properties,
)
from .loop import Record, Result, Settings, optimize
from .objective import Evaluator, Objective


@dataclasses.dataclass(frozen=True)
class Study:
    """A design study (SI inside; see ``jaxdobby optimize --help`` for each setting)."""

    space: DesignSpace
    objective: Objective
    limits: Constraints = dataclasses.field(default_factory=Constraints)
    settings: Settings = dataclasses.field(default_factory=Settings)
    gradient: str = "auto"
    steps: int | None = None
    starts: int = 1
    seed: int = 0


@dataclasses.dataclass
class StudyResult:
    history: list[dict]
    summary: dict
    setup: Setup
    design_toml: str
    profiles: dict
    deviations: dict
    result: Result


def run_study(study: Study, progress: Callable[[str], None] | None = None, *,
              programs=None) -> StudyResult:
    """Run ``study``; ``progress`` receives one line per iteration (and a few status lines).
    ``programs``: where the evaluator's programs
    (:class:`~jaxdobby.optimize.objective.Evaluator`) and the validity check's
    (:func:`design_warnings`) are stored."""
    say = progress or (lambda _: None)
    space = study.space
    check_mass_budget(space, study.limits)
    linear = affine_rows(space, study.limits)[:1]  # held exactly by projection
    t0 = time.perf_counter()
    say("preparing the steady-state programs (seconds where the package ships them compiled "
        "or this folder's cache has them traced; up to a minute on 2 cores where they "
        "compile)...")
    evaluator = Evaluator(space, study.objective, steps=study.steps, mode=study.gradient,
                          directory=programs)
    t_forward = time.perf_counter() - t0
    say(f"{space.size} design variable(s), {len(study.objective.speeds)} speed(s), "
        f"{evaluator.steps} collocation steps per cycle, {evaluator.mode}-mode gradients "
        "(the first one may compile: up to a minute)")
    rows: list[dict] = []

    def on_iteration(rec: Record):
        row = _row(space, study, rec, evaluator)
        rows.append(row)
        say(_progress_line(row, study, evaluator))

    constraint_fn = _constraint_fn(space, study.limits)
    u_start, scanned = np.asarray(space.initial), None
    if study.starts > 1:
        u_start, scanned = best_start(evaluator, constraint_fn, u_start, study.starts, linear,
                                      seed=study.seed)
        say(f"scanned {study.starts} starting designs in one batch: starting from J = "
            f"{scanned:.5f} (the given design: 1)")
    result = optimize(evaluator.value_and_grad, constraint_fn, u_start, study.settings,
                      callback=on_iteration, linear=linear)
    t_optimize = time.perf_counter() - t0 - t_forward
    say("verifying the start and the optimum on their own modes...")
    u_final = jnp.asarray(result.u)
    final_setup = space.setup(u_final)
    speeds_rpm = [w / RPM for w in study.objective.speeds]
    start_setup = space.setup(space.initial)
    start = _verified(evaluator, space.initial)
    final = _verified(evaluator, u_final)
    summary = _summary(study, evaluator, result, start, final, speeds_rpm,
                       seconds={"first_compile_and_solve": t_forward, "optimisation": t_optimize,
                                    "total": time.perf_counter() - t0})
    summary["starts"] = {"candidates": study.starts, "best_objective": scanned,
                         "start_design": _design(space, u_start)}
    say("checking the start and the optimum against the model's validity limits...")
    design_warnings(summary, start_setup, final_setup, study.objective.speeds, evaluator.steps,
                    directory=programs)
    setup_out = dataclasses.replace(
        final_setup, operating=dataclasses.replace(final_setup.operating,
                                                   speed=study.objective.speeds[0]))
    toml = (f"# jaxdobby optimize: optimised design; the objective's speeds were "
            f"{', '.join(f'{s:g}' for s in speeds_rpm)} r/min (run another with --speed)\n"
            + to_toml(setup_out, RunOptions(method="collocation", steps=evaluator.steps)))
    profiles = {"start": _profile(start_setup), "optimised": _profile(final_setup)}
    deviations = {f"{rpm:g} r/min": {
        f"start ({start['deviation_pp'][i] * 1e3:.3f} mm p-p)":
            (start["time"][i], start["deviation_series"][i]),
        f"optimised ({final['deviation_pp'][i] * 1e3:.3f} mm p-p)":
            (final["time"][i], final["deviation_series"][i])}
        for i, rpm in enumerate(speeds_rpm)}
    return StudyResult(history=rows, summary=summary, setup=final_setup, design_toml=toml,
                       profiles=profiles, deviations=deviations, result=result)


def design_warnings(summary: dict, start: Setup, final: Setup, speeds, steps: int, *,
                    directory=None) -> None:
    """Add the validity warnings of the starting and optimised designs to ``summary``: at every
    speed [rad/s], ``per_speed[i]["start"|"optimised"]["warnings"]`` as ``jaxdobby simulate``
    reports them for that design (:func:`jaxdobby.validity.setup_warnings`: the collocation
    solver with the study's ``steps``, the run ``design.toml`` describes), and
    ``summary["warnings"]``: the optimised design's, each message prefixed with its speed
    (code, message, value, limit, as simulate's)."""
    from ..validity import setup_warnings

    options = RunOptions(method="collocation", steps=steps)
    for w, entry in zip(speeds, summary["per_speed"]):
        for label, setup in (("start", start), ("optimised", final)):
            at = dataclasses.replace(setup, operating=dataclasses.replace(setup.operating,
                                                                          speed=w))
            entry[label]["warnings"] = setup_warnings(at, options, directory=directory)
    summary["warnings"] = [dict(w, message=f"at {e['speed_rpm']:g} r/min: {w['message']}")
                           for e in summary["per_speed"] for w in e["optimised"]["warnings"]]


def start_candidates(u0: np.ndarray, count: int, *, seed: int = 0) -> np.ndarray:
    """``count`` starting designs in [0, 1]ⁿ: the given one and, for one variable, a uniform
    grid of the rest over the range; for several, a scrambled Sobol sequence (scipy.stats.qmc)."""
    n = u0.shape[0]
    if n == 1:
        rest = np.linspace(0.0, 1.0, count - 1)[:, None]
    else:
        import warnings

        from scipy.stats import qmc

        with warnings.catch_warnings():  # a count that is not a power of two: fine for a scan
            warnings.simplefilter("ignore", UserWarning)
            rest = qmc.Sobol(d=n, scramble=True, seed=seed).random(count - 1)
    return np.concatenate([u0[None], rest])


def best_start(evaluator: Evaluator, constraint_fn, u0, count: int, linear=(), *,
               seed: int = 0) -> tuple[np.ndarray, float]:
    """The candidate (:func:`start_candidates`, projected onto the bounds and the linear mass
    budget) with the lowest J among those meeting the other constraints, found with one vmapped
    batch of solves; and its J. Local optimisers end in the basin they start in: on this
    bumpy objective (resonances of the frame-on-arm mode with the pick rate's harmonics) a
    coarse scan first picks the basin."""
    from .loop import feasible_set

    candidates = start_candidates(np.asarray(u0, dtype=float), count, seed=seed)
    feasible = feasible_set(constraint_fn, np.asarray(u0, dtype=float), list(linear))
    candidates = np.stack([feasible.project(c) for c in candidates])
    j = evaluator.values_many(candidates)
    others = [i for i in range(np.asarray(constraint_fn(u0)[0]).shape[0]) if i not in linear]
    ok = np.array([np.all(np.asarray(constraint_fn(c)[0])[others] <= 0.0) for c in candidates])
    ok[0] = True  # the given design is always a candidate
    j = np.where(ok & np.isfinite(j), j, np.inf)
    i = int(np.argmin(j))
    return candidates[i], float(j[i])


def _constraint_fn(space: DesignSpace, limits: Constraints):
    def fn(u):
        c, jac = constraint_jacobian(space, limits, jnp.asarray(u))
        return np.asarray(c), np.asarray(jac)

    return fn


def _verified(evaluator: Evaluator, u) -> dict:
    _, values = evaluator.value(u, basis="own")
    return values


def _design(space: DesignSpace, u) -> dict[str, float]:
    p = np.asarray(space.physical(jnp.asarray(u)))
    return {f"{label}_{unit.replace(' ', '_')}": float(v / scale)
            for label, (unit, scale), v in zip(space.labels(), space.units(), p)}


def _row(space: DesignSpace, study: Study, rec: Record, evaluator: Evaluator) -> dict:
    props = properties(space, jnp.asarray(rec.u))
    row = {"iteration": rec.iteration, "evaluations": rec.evaluations, "seconds": rec.seconds,
               "objective": rec.objective, "lagrangian": rec.lagrangian,
               "projected_gradient": rec.projected_gradient, "penalty": rec.penalty}
    row.update(_design(space, rec.u))
    row["arm_mass_kg"] = float(props["mass"])
    row["first_frequency_hz"] = float(props["frequency"])
    for name, c, lam in zip(study.limits.names, rec.constraints, rec.multipliers):
        row[f"c_{name}"] = float(c)
        row[f"multiplier_{name}"] = float(lam)
    for i, w in enumerate(study.objective.speeds):
        tag = f"{w / RPM:g}rpm"
        row[f"deviation_pp_mm_{tag}"] = float(rec.values["deviation_pp"][i]) * 1e3
        row[f"deviation_smooth_mm_{tag}"] = float(rec.values["deviation"][i]) * 1e3
        row[f"deviation_rms_mm_{tag}"] = float(rec.values["deviation_rms"][i]) * 1e3
        row[f"acceleration_pp_m_s2_{tag}"] = float(rec.values["acceleration_pp"][i])
        row[f"converged_{tag}"] = bool(rec.values["converged"][i] > 0.5)
    return row


def _progress_line(row: dict, study: Study, evaluator: Evaluator) -> str:
    speeds = "  ".join(f"{w / RPM:g}:{row[f'deviation_pp_mm_{w / RPM:g}rpm']:.3f}"
                       for w in study.objective.speeds)
    cons = "  ".join(f"c_{n}={row[f'c_{n}']:+.2e}" for n in study.limits.names)
    return (f"iter {row['iteration']:>3}/{study.settings.steps}  J={row['objective']:.5f}  "
            f"dev p-p [mm] {speeds}  mass={row['arm_mass_kg']:.4f} kg  "
            f"f1={row['first_frequency_hz']:.1f} Hz  {cons}  |pg|={row['projected_gradient']:.1e}"
            f"  evals={row['evaluations']}  {row['seconds']:.0f} s")


def _metrics(values: dict, i: int) -> dict[str, float]:
    return {"deviation_pp_mm": float(values["deviation_pp"][i]) * 1e3,
                "deviation_smooth_mm": float(values["deviation"][i]) * 1e3,
                "deviation_rms_mm": float(values["deviation_rms"][i]) * 1e3,
                "acceleration_pp_m_s2": float(values["acceleration_pp"][i]),
                "converged": bool(values["converged"][i] > 0.5)}


def _summary(study, evaluator, result: Result, start, final, speeds_rpm, seconds) -> dict:
    space = study.space
    per_speed = []
    for i, rpm in enumerate(speeds_rpm):
        s, f = _metrics(start, i), _metrics(final, i)
        per_speed.append({
            "speed_rpm": rpm, "start": s, "optimised": f,
            "improvement_percent": 100.0 * (1.0 - f["deviation_pp_mm"] / s["deviation_pp_mm"])})
    u0, u1 = space.initial, jnp.asarray(result.u)
    p0, p1 = (properties(space, u, own_modes=True) for u in (u0, u1))
    limits = study.limits
    return {
        "objective": {"metric": study.objective.metric, "aggregate": study.objective.aggregate,
                       "speeds_rpm": speeds_rpm,
                       "acceleration_weight": study.objective.acceleration_weight},
        "variables": space.labels(),
        "bounds": {label: [float(lo / scale), float(hi / scale)] for label, (_, scale), lo, hi in
                zip(space.labels(), space.units(), np.asarray(space.lower),
                    np.asarray(space.upper))},
        "constraints": {"mass_budget_kg": limits.mass_budget,
                         "frequency_floor_hz": limits.frequency_floor,
                         "stroke_mm": float(space.target_stroke) / MM},
        "optimizer": dataclasses.asdict(study.settings), "gradient_mode": evaluator.mode,
        "cycle_steps": evaluator.steps,
        "start": _state(space, u0, p0), "optimised": _state(space, u1, p1),
        "objective_start": float(result.history[0].objective),
        "objective_optimised": float(result.history[-1].objective),
        "per_speed": per_speed,
        "multipliers": {n: float(v) for n, v in zip(limits.names, result.multipliers)},
        "stress": {"start": stress_values(limits, result.history[0].constraints),
                   "optimised": stress_values(limits, result.history[-1].constraints)},
        "optimality": result.optimality, "converged": bool(result.converged),
        "iterations": len(result.history) - 1, "evaluations": result.history[-1].evaluations,
        "seconds": seconds,
        "note": ("'start'/'optimised' are the modal model of `jaxdobby simulate` (each design on "
                 "its own modes)"),
    }


def stress_values(limits: Constraints, constraints) -> dict[str, float]:
    """The stress constraints' smooth values from their rows c of :func:`constraints`
    (:mod:`jaxdobby.stress.design`): ``stress_max_smooth_mpa`` = (c + 1)·σ_limit and
    ``fatigue_safety_factor_smooth`` = n_min/(c + 1), the worst over the constraint's speeds
    (the surrogates bound the true peak from above and the true factor from below, by about
    1 %); empty without stress constraints."""
    c = dict(zip(limits.names, np.asarray(constraints, dtype=float)))
    out = {}
    if "stress" in c:
        out["stress_max_smooth_mpa"] = (c["stress"] + 1.0) * limits.stress_limit * 1e-6
    if "fatigue" in c:
        out["fatigue_safety_factor_smooth"] = limits.fatigue_floor / (c["fatigue"] + 1.0)
    return out


def _state(space, u, props) -> dict:
    return {"design": _design(space, u), "arm_mass_kg": float(props["mass"]),
                "first_frequency_hz": float(props["frequency"]),
                "stroke_mm": float(props["stroke"]) / MM}


def _profile(setup: Setup):
    arm = setup.machine.arm
    s = np.linspace(0.0, float(arm.total_length), 200)
    return s, np.interp(s, np.asarray(arm.depth_arc_lengths), np.asarray(arm.depth))


def speeds_from_rpm(values) -> tuple[float, ...]:
    """Speeds in r/min → rad/s (a tuple, for the static objective settings)."""
    return tuple(float(v) * math.pi / 30.0 for v in values)
