"""Models a Sobol study can run, and the registries of their parameters.

A model plugs into the pipeline as a :class:`ModelSpec`: a registry of the parameters it lets a
study vary (names, users' units, default bounds) and a ``build(space)`` factory returning
``model(x) -> dict[str, Array]``, a pure JAX function of ONE sample row ``x`` (shape (D,),
float64, users' units, columns in ``space.names`` order) that returns scalar metrics. It may also
return an ``"ok"`` entry: a bool (True = success) or an integer code (0 = success, as diffrax's
``RESULTS``); a sample with ok False / a nonzero code, or any non-finite metric, is a *failed
sample*. The pipeline vmaps and jits ``model``; it must not raise at run time (solve with
``throw=False`` and return the status instead).

``ISHIGAMI`` is the test model (Ishigami & Homma 1990): f = sin x1 + a sin² x2 + b x3⁴ sin x1
with x_i uniform on [−π, π]; its Sobol indices are known in closed form (Sobol' & Levitan 1999).
The dobby's spec is :data:`jaxdobby.sensitivity.dobby.DOBBY`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import jax.numpy as jnp
from jax import Array

from .space import ParameterSpace, ParameterSpec

Model = Callable[[Array], dict[str, Array]]

VALIDITY_PREFIX = "validity."
"""Model outputs whose name starts with this are validity outputs, not metrics."""


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """A model as the Sobol pipeline sees it.

    Attributes:
        name: the model's name (recorded in the run's manifest; ``--model`` on the CLI).
        parameters: registry of the parameters a study may vary.
        default_names: the parameters of the default problem, in order.
        build: ``build(space) -> model``; ``model(x)`` maps one sample row (D,) [users' units]
            to a dict of scalar float64 metrics, plus an optional ``"ok"`` status.
        build_with_steps: for a model solved on a fixed number of time steps per cycle,
            ``build_with_steps(n)`` is its ``build`` with n steps (``jaxdobby sobol --steps``:
            accuracy traded for speed); None: the model has no such setting.
        default_steps: the steps per cycle of ``build`` (with ``build_with_steps``); with
            ``row_groups``, the most.
        row_groups: for a model whose ``build`` chooses each row's steps per cycle from the
            row (the dobby: from its speed), ``row_groups(space, samples)`` → the (M,) step
            counts of the rows (None: all alike), so that the pipeline gives every chunk rows
            of one count (:func:`jaxdobby.sensitivity.batch.evaluate`'s ``groups``).
    """

    name: str
    parameters: Mapping[str, ParameterSpec]
    default_names: tuple[str, ...]
    build: Callable[[ParameterSpace], Model]
    build_with_steps: Callable[[int], Callable[[ParameterSpace], Model]] | None = None
    default_steps: int | None = None
    row_groups: Callable[[ParameterSpace, object], object] | None = None

    def builder(self, steps: int | None = None) -> Callable[[ParameterSpace], Model]:
        """``build`` for ``steps`` time steps per cycle (None, or :attr:`default_steps` of a
        model without ``row_groups``: the default ``build`` itself); see :func:`check_steps`
        for the valid values."""
        steps = check_steps(self, steps)
        return self.build if steps is None else self.build_with_steps(steps)


MIN_STEPS, MAX_STEPS = 72, 4320
"""Valid steps per cycle of :meth:`ModelSpec.builder` (72: one per 5° of the cycle; 4320: ten
times the dobby's default: a chunk's rigid-motion tables and Newton matrices, kept for every
step of every row, grow with the steps)."""


def check_steps(model: ModelSpec, steps) -> int | None:
    """``steps`` checked for ``model`` (raise ``ValueError`` naming ``--steps`` and the valid
    range); None when it is None or the model's fixed default (the default build)."""
    if steps is None:
        return None
    if model.build_with_steps is None:
        raise ValueError(f"--steps: model {model.name!r} has no time steps to set")
    if isinstance(steps, bool) or not isinstance(steps, int) or not (
            MIN_STEPS <= steps <= MAX_STEPS):
        raise ValueError(f"--steps must be an integer {MIN_STEPS}…{MAX_STEPS} (collocation steps "
                         f"per cycle; default {model.default_steps}); got {steps!r}")
    return None if steps == model.default_steps and model.row_groups is None else steps


def ishigami(x: Array, a: float = 7.0, b: float = 0.1) -> Array:
    """The Ishigami function f = sin x1 + a sin² x2 + b x3⁴ sin x1 (dimensionless).

    Args:
        x: (x1, x2, x3), shape (3,) [rad].
        a, b: the function's constants (7 and 0.1 in the usual benchmark).
    """
    return jnp.sin(x[0]) + a * jnp.sin(x[1]) ** 2 + b * x[2] ** 4 * jnp.sin(x[0])


ISHIGAMI_PARAMETERS = {
    f"x{i}": ParameterSpec(f"x{i}", unit="rad", bounds=(-math.pi, math.pi), description=f"x{i}")
    for i in (1, 2, 3)
}
"""The Ishigami inputs x1, x2, x3, uniform on [−π, π] [rad]."""


def _build_ishigami(space: ParameterSpace) -> Model:
    # Parameters left out of the space are held at 0 [rad]; x[space.names.index(...)] picks
    # the varied ones, as a model with a default parameter set would.
    def model(x):
        full = jnp.stack([x[space.names.index(n)] if n in space.names else jnp.zeros((), x.dtype)
                          for n in ISHIGAMI_PARAMETERS])
        return {"y": ishigami(full)}

    return model


ISHIGAMI = ModelSpec("ishigami", ISHIGAMI_PARAMETERS, ("x1", "x2", "x3"), _build_ishigami)
"""Ishigami (a = 7, b = 0.1) as a Sobol model with one metric ``"y"``: the pipeline's test case."""
