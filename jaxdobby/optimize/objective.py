"""The objective of a design study: steady-state metrics over a batch of speeds, and its gradient.

For normalised design variables u (:class:`~jaxdobby.optimize.design.DesignSpace`) the
mechanism's periodic steady state is solved at every speed of the study as one ``vmap``-ed batch
(the collocation path of :func:`jaxdobby.simulate.simulate`, 432 steps per cycle whatever the
speed; the arm reduced on its own modes, differentiated as the subspace they span, or on a
fixed basis: :class:`~jaxdobby.optimize.design.DesignSpace`), and reduced to

    J(u) = A_s [ m_s(u) / m_s⁰ + w · a_s(u) / a_s⁰ ]

with m the chosen metric's smooth surrogate (``deviation``: log-sum-exp peak-to-peak of the
heald-frame displacement deviation; ``deviation_rms``; ``acceleration``: smooth peak-to-peak of
the flexible heald-frame acceleration), a the acceleration surrogate weighted by w (optional),
the superscript 0 the values of the starting design (so J = 1 there, whatever the units), and
A_s the aggregate over speeds: ``mean``, or ``worst`` as a log-sum-exp soft maximum (sharpness
:data:`WORST_SHARPNESS`, within log(n_speeds)/β above the true maximum). Reports give the true
peak-to-peak values.

Gradients are exact derivatives of J through the reduction, the kinematics, the collocation
steps and the periodic state (implicit-function theorem at the shooting root). ``forward`` mode
(``jax.jacfwd``) carries one tangent per variable through every step; ``reverse`` mode
(``jax.value_and_grad``) replays the steps backwards once whatever the number of variables, and
stores the step residuals (a few hundred floats per step: megabytes). Both need the monodromy
matrix at the periodic state for the implicit-function derivative (2k tangents through one
cycle), and forward mode carries its tangents through the model's assembly and every
collocation step as well. Reverse mode pulls the steady cycle and its periodic state back in
one pullback of the recorded pass (``reverse_only`` of
:func:`jaxdobby.periodic.dense.steady_cycle`). Measured on the default machine at 800 r/min
(2 CPU cores, ``benchmarks/results/gradient_cost.json``, 2026-12-03): one forward solve
0.032 s; for 7 and 8 variables forward mode 7.3 solves, reverse mode 3.1 and 3.2 (5.0 and
5.1 with ``jax.lax.custom_root``'s derivative).
Reverse mode is the cheaper for any number of variables, so ``auto`` picks it
(:data:`FORWARD_MAX_VARIABLES` = 0).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.scipy.special import logsumexp

from ..periodic import DEFAULT_STEPS
from ..programs import ONE_SHOT, call_program, stored_call
from ..metrics import rms, smooth_peak_to_peak
from ..simulate import _simulate
from .design import DesignSpace

OBJECTIVES = ("deviation", "deviation_rms", "acceleration")
AGGREGATES = ("worst", "mean")
GRADIENT_MODES = ("auto", "forward", "reverse")
FORWARD_MAX_VARIABLES = 0
WORST_SHARPNESS = 50.0
"""β of the soft maximum over speeds, on values normalised to ~1."""
SHARPNESS = 50.0
"""β of the within-cycle log-sum-exp peak-to-peak (on the RMS-normalised signal): the
surrogate lies a few per cent below the true peak-to-peak (measured 3 % on the default
machine; β = 20 of :mod:`jaxdobby.metrics` gives 10 %), close enough that its minimiser is the
true metric's while it stays smooth."""


@dataclasses.dataclass(frozen=True)
class Objective:
    """What to minimise (static settings).

    Attributes:
        metric: one of :data:`OBJECTIVES`.
        speeds: loom speeds [rad/s] (one or more).
        aggregate: ``worst`` or ``mean`` over the speeds.
        acceleration_weight: w of the added acceleration surrogate (0: none).
    """

    metric: str = "deviation"
    speeds: tuple[float, ...] = (800.0 * math.pi / 30.0,)
    aggregate: str = "worst"
    acceleration_weight: float = 0.0


def cycle_values(space: DesignSpace, u: Array, speed, steps: int, reverse_only: bool = False
                 ) -> dict[str, Array]:
    """Steady-state metrics of the design ``u`` at one speed [rad/s] (SI; differentiable; in
    reverse mode only, by the cheaper derivative of the steady cycle, with ``reverse_only``:
    :func:`jaxdobby.periodic.dense.steady_cycle`).

    Keys: the surrogates ``deviation``, ``deviation_rms``, ``acceleration``; the true
    ``deviation_pp``, ``acceleration_pp``; ``converged`` (1.0 or 0.0); and the cycle's
    ``time`` and ``deviation_series`` (for figures).
    """
    setup = space.setup(u)
    operating = dataclasses.replace(setup.operating, speed=speed)
    run = _simulate(setup.machine, operating, space.basis, method="collocation", steps=steps,
                    n_out=0, rtol=0.0, atol=0.0, tolerance=1e-9, forward_mode=False,
                    reverse_only=reverse_only)
    s = run.series
    dev, acc = s.deviation, s.acceleration_flexible
    return {"deviation": smooth_peak_to_peak(dev, SHARPNESS), "deviation_rms": rms(dev[:-1]),
            "acceleration": smooth_peak_to_peak(acc, SHARPNESS),
            "deviation_pp": run.metrics["deviation_pp"],
            "acceleration_pp": run.metrics["acceleration_amp"],
            "converged": run.converged.astype(float), "time": s.t, "deviation_series": dev}


def batch_values(space: DesignSpace, u: Array, speeds: Array, steps: int,
                 reverse_only: bool = False) -> dict[str, Array]:
    """:func:`cycle_values` at every speed, as one vmapped batch (leading axis = speeds)."""
    return jax.vmap(lambda w: cycle_values(space, u, w, steps, reverse_only))(speeds)


def combine(objective: Objective, values: dict[str, Array], reference: dict[str, Array]) -> Array:
    """J from the per-speed values and the starting design's (see the module docstring)."""
    per_speed = values[objective.metric] / reference[objective.metric]
    if objective.acceleration_weight:
        per_speed = per_speed + objective.acceleration_weight * (
            values["acceleration"] / reference["acceleration"])
    if objective.aggregate == "mean" or per_speed.shape[0] == 1:
        return jnp.mean(per_speed)
    return logsumexp(WORST_SHARPNESS * per_speed) / WORST_SHARPNESS


def gradient_mode(mode: str, n_variables: int) -> str:
    """``forward`` or ``reverse`` for ``auto`` by the number of variables."""
    if mode not in GRADIENT_MODES:
        raise ValueError(f"gradient mode must be one of {GRADIENT_MODES}, got {mode!r}")
    if mode == "auto":
        return "forward" if n_variables <= FORWARD_MAX_VARIABLES else "reverse"
    return mode


def _values(space, u, speeds, steps):
    return batch_values(space, u, speeds, steps)


def _values_many(space, us, speeds, steps):
    return jax.vmap(lambda u: batch_values(space, u, speeds, steps))(us)


def _objective(space, u, speeds, steps, objective, reference, reverse_only=False):
    values = batch_values(space, u, speeds, steps, reverse_only)
    return combine(objective, values, reference), values


def _reverse(space, u, speeds, steps, objective, reference):
    return jax.value_and_grad(_objective, argnums=1, has_aux=True)(
        space, u, speeds, steps, objective, reference, True)


def _forward(space, u, speeds, steps, objective, reference):
    def fn(x):
        j, values = _objective(space, x, speeds, steps, objective, reference)
        return j, (j, values)

    grad, (j, values) = jax.jacfwd(fn, has_aux=True)(u)
    return (j, values), grad


PROGRAMS = {"values": (_values, ONE_SHOT), "values-many": (_values_many, ONE_SHOT),
            "reverse": (_reverse, None), "forward": (_forward, None)}
"""The evaluator's programs (:func:`jaxdobby.programs.stored_call`, names prefixed
``optimize-``) and their XLA options: the values, run a few times per study, at LLVM's
optimisation level 0 (:data:`jaxdobby.programs.ONE_SHOT`: quicker to compile); the gradients,
run at every iteration, fully optimised."""


class Evaluator:
    """J(u), its gradient and the per-speed values of a study.

    Each of its programs (:data:`PROGRAMS`) is a stored program
    (:func:`jaxdobby.programs.stored_call`), keyed on the static settings (variables, number
    of speeds, steps, objective, mode) and the shapes: traced once and kept in ``directory``
    (a later process reads it instead of tracing), compiled once per process (the package
    ships the default study's compiled, :mod:`jaxdobby.programs`), and shared by evaluators of
    the same kind.

    Args:
        space: the design space.
        objective: the objective settings.
        steps: collocation steps per cycle (default 432,
            :data:`jaxdobby.periodic.DEFAULT_STEPS`).
        mode: gradient mode (``auto``, ``forward``, ``reverse``).
        directory: where the programs are stored (the command line's programs folder); None:
            only the shipped ones are read.
        ship: where to write the compiled executables (``python -m jaxdobby.programs``).
    """

    def __init__(self, space: DesignSpace, objective: Objective, steps: int | None = None,
                 mode: str = "auto", *, directory=None, ship=None):
        if objective.metric not in OBJECTIVES:
            raise ValueError(f"objective must be one of {OBJECTIVES}, got {objective.metric!r}")
        if objective.aggregate not in AGGREGATES:
            raise ValueError(f"aggregate must be one of {AGGREGATES}")
        self.space, self.objective = space, objective
        self.speeds = jnp.asarray(objective.speeds, dtype=float)
        self.steps = DEFAULT_STEPS if steps is None else int(steps)
        self.mode = gradient_mode(mode, space.size)
        self.directory, self.ship = directory, ship
        # The programs take the objective as a static argument (part of their key); the speeds
        # travel as the array above, so a study at another speed reuses the compilation.
        self._static = dataclasses.replace(objective, speeds=())
        start = self._run("values", space.initial)
        self.reference = {k: start[k] for k in ("deviation", "deviation_rms", "acceleration")}

    def _arguments(self, name: str, u, space: DesignSpace | None = None) -> tuple:
        """The arguments of program ``name`` (:data:`PROGRAMS`) at ``u``."""
        args = (self.space if space is None else space, jnp.asarray(u), self.speeds, self.steps)
        return args + ((self._static, self.reference) if name in GRADIENT_MODES else ())

    def _run(self, name: str, u, space: DesignSpace | None = None):
        fn, options = PROGRAMS[name]
        return stored_call(f"optimize-{name}", fn, self._arguments(name, u, space),
                           directory=self.directory, compiler_options=options, ship=self.ship)

    def programs(self, starts: int = 1) -> list[tuple]:
        """(exported program, argument specs, XLA options, file name) of every program a
        study from ``starts`` starting designs runs (the values, the scan of the starts if
        more than one, the gradient), without compiling them: what the shipped programs' and
        executables' keys are made of (:func:`jaxdobby.programs.together_keys`)."""
        names = ["values"] + (["values-many"] if starts > 1 else []) + [self.mode]
        out = []
        scan = jnp.zeros((starts, self.space.size))
        for name in names:
            u = scan if name == "values-many" else self.space.initial
            fn, options = PROGRAMS[name]
            exported, specs, file = call_program(f"optimize-{name}", fn,
                                                 self._arguments(name, u),
                                                 directory=self.directory)
            out.append((exported, specs, options, file))
        return out

    def value(self, u: Array, basis: Array | str | None = None
              ) -> tuple[float, dict[str, np.ndarray]]:
        """J(u) and the per-speed values (no gradient), optionally on another reduction basis:
        an array, or ``"own"`` (the design's own modes: the modal model that
        ``jaxdobby simulate`` runs, up to round-off)."""
        space = self.space if basis is None else dataclasses.replace(self.space, basis=basis)
        values = self._run("values", u, space)
        j = combine(self.objective, values, self.reference)
        return float(j), {k: np.asarray(v) for k, v in values.items()}

    def values_many(self, us: Array) -> np.ndarray:
        """J at every row of ``us`` (m, n), as one vmapped batch of m × speeds solves."""
        values = self._run("values-many", us)
        return np.asarray(jax.vmap(lambda v: combine(self.objective, v, self.reference))(values))

    def value_and_grad(self, u: Array) -> tuple[float, np.ndarray, dict[str, np.ndarray]]:
        """J(u), ∇J(u) (shape (n,)) and the per-speed values."""
        (j, values), grad = self._run(self.mode, u)
        return float(j), np.asarray(grad), {k: np.asarray(v) for k, v in values.items()}
