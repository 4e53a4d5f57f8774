"""One-at-a-time parameter studies, as in the source study (§4–§5 of the paper).

``run_sweep(setup, "speed", [400, 500, …])`` runs the steady state for each value of one
parameter, the others held at ``setup``. Two ways, the same equations:

* **one value after another through the command line's programs** (the default for collocation
  and up to :data:`LOOP_MAX` values, and for ``modes``): :func:`jaxdobby.simulate.stored_report`
  per value, the run and report programs ``jaxdobby simulate`` uses — compiled once per
  configuration and process (or loaded from the package's shipped executables, or traced once
  and kept in the command line's cache folder), then run again for each float value at
  ~0.1 s per run. With an empty cache, on 2 cores (2026-12-06): ``jaxdobby sweep speed`` on
  the default machine 2.8 s (15 s when it compiled a vmapped batch), ``jaxdobby sweep modes``
  52 s (86 s compiling ``simulate`` for each size); ``tests/test_sweep.py`` holds the two ways
  to each other. A sweep of sizes traces each size's programs while XLA compiles the previous
  ones in two background threads (:func:`jaxdobby.simulate.compile_reports`): ``jaxdobby sweep
  modes`` 45–46 s against 64–70 s one size after another (the two alternated, 2026-12-06
  evening, the same machine);
* **one vmapped batch** (``batched=True``, RK4 and adaptive runs, and more than
  :data:`LOOP_MAX` values): one compilation, one solve for all values, with the step count of
  the most demanding value.

``modes`` (the number of modes kept, a size) runs value by value either way: a program each.

Default studies (:data:`STUDIES`): modal truncation 1…8, speed 400…1200 r/min in steps of
100, peak warp force 690/1380/2760 N, stroke 140/115/80 mm, arm thickness 6/7/8 mm.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .config import RunOptions, check_value
from .errors import InputError
from .parameters import PARAMETERS, Setup, apply
from .simulate import (_simulate, cancel_compiles, compile_reports, resolve_method,
                       stored_report, summary)

LOOP_MAX = 32
"""Most values a collocation sweep runs one after another through the command line's programs
(see the module docstring); a longer sweep runs as one vmapped batch, whose compilation
(~15 s) then costs less than the runs (~0.1 s each)."""

STUDIES: dict[str, list[float]] = {
    "modes": [1, 2, 3, 4, 5, 6, 7, 8],
    "speed": [400.0, 500.0, 600.0, 700.0, 800.0, 900.0, 1000.0, 1100.0, 1200.0],
    "warp_force": [690.0, 1380.0, 2760.0],
    "stroke": [140.0, 115.0, 80.0],
    "thickness": [6.0, 7.0, 8.0],
}
"""The source study's one-at-a-time studies (users' units)."""

TABLE_COLUMNS = [
    ("deviation_min_mm", "dev. min [mm]", "{:+.3f}"),
    ("deviation_max_mm", "dev. max [mm]", "{:+.3f}"),
    ("deviation_pp_mm", "dev. p-p [mm]", "{:.3f}"),
    ("link_point_deviation_x_mm", "joint x p-p [mm]", "{:.3f}"),
    ("link_point_deviation_y_mm", "joint y p-p [mm]", "{:.3f}"),
    ("velocity_deviation_amp_m_s", "vel. dev. p-p [m/s]", "{:.3f}"),
    ("acceleration_amp_m_s2", "acc. p-p [m/s²]", "{:.0f}"),
    ("acceleration_rigid_amp_m_s2", "rigid acc. p-p [m/s²]", "{:.0f}"),
    ("stress_max_mpa", "arm stress max [MPa]", "{:.0f}"),
    ("fatigue_safety_factor", "fatigue factor", "{:.2f}"),
    ("converged", "converged", "{}"),
]


@dataclasses.dataclass
class SweepResult:
    """Rows (one summary per value) and the runs' time series, in the order of ``values``;
    ``steps``: the steps per cycle of a vmapped batch (the most demanding value's)."""

    parameter: str
    unit: str
    values: list[float]
    rows: list[dict]
    series: list
    steps: int | None = None


def _label(parameter: str) -> tuple[str, str]:
    if parameter == "modes":
        return "modes", ""
    return parameter, PARAMETERS[parameter].unit


def run_sweep(setup: Setup, parameter: str, values, *, method: str | None = None,
              batched: bool | None = None, directory=None) -> SweepResult:
    """Steady states of ``setup`` with ``parameter`` set to each of ``values`` (users' units);
    ``batched``, ``directory``: as :func:`prepare_sweep`'s."""
    return prepare_sweep(setup, parameter, values, method=method, batched=batched,
                         directory=directory)()


def prepare_sweep(setup: Setup, parameter: str, values, *, method: str | None = None,
                  batched: bool | None = None, directory=None):
    """Validate a sweep (raising :class:`InputError` for bad values) and return a function
    that runs it. Splitting the two lets the command line report bad input before it starts.

    Args:
        setup, parameter, values, method: the base machine, what is swept, its values in users'
            units, the integrator (None: :func:`jaxdobby.simulate.resolve_method`'s).
        batched: True: float values as one vmapped batch; False: one after another through
            the command line's programs (collocation only); None: the latter for collocation
            and up to :data:`LOOP_MAX` values (see the module docstring).
        directory: where the command line's traced programs are stored and looked for
            (:func:`jaxdobby.command_line.programs_dir`); None: the shipped ones only.
    """
    if parameter != "modes" and parameter not in PARAMETERS:
        raise InputError(f"unknown sweep parameter '{parameter}': use modes or one of "
                         f"{', '.join(PARAMETERS)}")
    values = list(values)
    if not values:
        raise InputError("the sweep needs at least one value")
    name, unit = _label(parameter)
    if parameter == "modes":
        runs = []
        for k in values:
            if isinstance(k, float) and k.is_integer():
                k = int(k)
            if not isinstance(k, int) or not 1 <= k <= 30:
                raise InputError(f"modes = {k!r} is outside the valid range (an integer 1…30)")
            runs.append(dataclasses.replace(setup, machine=setup.machine.replace(n_modes=k)))

        def run_modes():
            if batched is not True and all(
                    resolve_method(s.machine, s.operating, method)[0] == "collocation"
                    for s in runs):
                return _loop(runs, values, name, unit, method, directory)
            sims = [_simulate(s.machine, s.operating, None,
                              **_method_kw(*resolve_method(s.machine, s.operating, method)))
                    for s in runs]
            return SweepResult(name, unit, values, [summary(r) for r in sims],
                               [r.series for r in sims])

        return run_modes
    p = PARAMETERS[parameter]
    si = [check_value(p, v, f"{parameter}")[0] * p.scale for v in values]
    setups = []
    for v in si:
        try:
            setups.append(apply(setup, {parameter: v}))
        except ValueError as err:
            raise InputError(str(err)) from None
    # one static step count for the batch: the most demanding value's
    resolved = [resolve_method(s.machine, s.operating, method) for s in setups]
    kind = resolved[0][0]
    steps = None if kind == "adaptive" else max(n for _, n in resolved)
    if batched is False and kind != "collocation":
        raise InputError(f"a sweep runs one value after another only with collocation; "
                         f"got method {kind!r}")
    if not batched and kind == "collocation" and (batched is False or len(si) <= LOOP_MAX):
        return lambda: dataclasses.replace(
            _loop(setups, values, name, unit, method, directory), steps=steps)

    def one(value):
        s = apply(setup, {parameter: value})
        return _simulate(s.machine, s.operating, None, **_method_kw(kind, steps))

    def run_batch():
        batch = eqx.filter_jit(jax.vmap(one))(jnp.asarray(si))
        runs = [jax.tree.map(lambda a, i=i: a[i], batch) for i in range(len(values))]
        return SweepResult(name, unit, values, [summary(r) for r in runs],
                           [r.series for r in runs], steps)

    return run_batch


def _loop(setups, values, name, unit, method, directory) -> SweepResult:
    """The sweep one value after another through :func:`jaxdobby.simulate.stored_report` (the
    command line's programs, compiled once per configuration and process)."""
    rows, series = [], []
    # a sweep of sizes: XLA compiles one size's programs while the next is traced
    started = compile_reports(setups, RunOptions(method=method), directory=directory)
    try:
        for s in setups:
            row, cycle, _ = stored_report(s, RunOptions(method=method), directory=directory)
            rows.append(row)
            series.append(cycle)
    except BaseException:  # an interrupt: the sizes not yet compiling are not compiled
        cancel_compiles(started)
        raise
    return SweepResult(name, unit, list(values), rows, series)


def _method_kw(method: str, steps: int | None) -> dict:
    return {"method": method, "steps": steps, "n_out": 3001, "rtol": 1e-8, "atol": 1e-12,
            "tolerance": 1e-6, "forward_mode": False}


def markdown_table(result: SweepResult) -> str:
    """The sweep as a markdown table."""
    head = f"{result.parameter} [{result.unit}]" if result.unit else result.parameter
    cols = [head] + [label for _, label, _ in TABLE_COLUMNS]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for v, row in zip(result.values, result.rows):
        cells = [f"{v:g}"] + [fmt.format(row[key]) for key, _, fmt in TABLE_COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def csv_table(result: SweepResult) -> str:
    """The sweep as CSV (one row per value, the summary's scalar keys as columns)."""
    keys = [k for k, v in result.rows[0].items() if not isinstance(v, list)]
    head = f"{result.parameter}_{result.unit.replace('/', '_')}" if result.unit else result.parameter
    lines = [",".join([head] + keys)]
    for v, row in zip(result.values, result.rows):
        lines.append(",".join([f"{v:g}"] + [str(row[k]) for k in keys]))
    return "\n".join(lines) + "\n"


def trend_figure(result: SweepResult):
    """Deviation range and acceleration amplitude against the swept value."""
    from .plots import plt

    x = np.asarray(result.values, dtype=float)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
    a1.plot(x, [r["deviation_max_mm"] for r in result.rows], "o-", label="max")
    a1.plot(x, [r["deviation_min_mm"] for r in result.rows], "s-", label="min")
    a1.plot(x, [r["deviation_pp_mm"] for r in result.rows], "^-", label="peak to peak")
    a1.set_ylabel("heald-frame displacement deviation [mm]")
    a1.legend()
    a2.plot(x, [r["acceleration_amp_m_s2"] for r in result.rows], "o-", label="flexible")
    a2.plot(x, [r["acceleration_rigid_amp_m_s2"] for r in result.rows], "s--", label="rigid")
    a2.set_ylabel("heald-frame acceleration, peak to peak [m/s²]")
    a2.legend()
    for a in (a1, a2):
        a.set_xlabel(f"{result.parameter} [{result.unit}]" if result.unit else result.parameter)
        a.grid(alpha=0.3)
    return fig
