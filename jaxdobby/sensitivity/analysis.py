"""Sobol indices with confidence intervals, per metric, through SALib.

For each metric, ``SALib.analyze.sobol.analyze`` estimates the first-order indices S1
(Saltelli et al. 2010), total indices ST (Jansen's estimator, idem) and, with second order, the
pair indices S2 (Saltelli 2002), each with a bootstrap confidence half-width (``*_conf``) at
``conf_level``. Failed samples are handled first by the policy in ``failures.py``: SALib never
sees a NaN.

A metric that is constant over the design (variance 0, e.g. a quantity the varied parameters do
not touch) has no variance to apportion; SALib would return NaN (it divides by the standard
deviation). Its indices are reported as 0 ± 0 with a note saying why.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from collections.abc import Mapping

import numpy as np

from .failures import FailureReport, apply_policy
from .models import VALIDITY_PREFIX
from .space import ParameterSpace


@dataclasses.dataclass(frozen=True)
class MetricIndices:
    """Sobol indices of one metric (dimensionless fractions of its variance).

    Attributes:
        S1, S1_conf: first-order indices and confidence half-widths, shape (D,).
        ST, ST_conf: total indices and confidence half-widths, shape (D,).
        S2, S2_conf: pair indices and half-widths, shape (D, D), set for j < k only (NaN on and
            below the diagonal, as SALib returns them); None without second order.
        note: why the indices are what they are, where that needs saying (constant metric).
    """

    S1: np.ndarray
    S1_conf: np.ndarray
    ST: np.ndarray
    ST_conf: np.ndarray
    S2: np.ndarray | None = None
    S2_conf: np.ndarray | None = None
    note: str | None = None

    def pairs(self) -> list[tuple[int, int]]:
        """The (j, k), j < k, of the S2 entries (empty without second order)."""
        if self.S2 is None:
            return []
        d = len(self.S1)
        return [(j, k) for j in range(d) for k in range(j + 1, d)]


@dataclasses.dataclass(frozen=True)
class SobolResult:
    """Sobol indices of every metric of a study.

    Attributes:
        space: the parameter space.
        metrics: indices per metric name.
        failures: the failed samples and how the indices were affected.
        second_order, conf_level, num_resamples, seed: the analysis settings.
        run: free-form facts about the run (samples, chunk size, devices, …) for the JSON.
        warnings: per-sample validity warnings, ``{code: {"count", "samples", "limit"}}``
            (:func:`jaxdobby.sensitivity.validity.sample_warnings`; samples are design row indices).
    """

    space: ParameterSpace
    metrics: dict[str, MetricIndices]
    failures: FailureReport
    second_order: bool
    conf_level: float
    num_resamples: int
    seed: int | None
    run: Mapping = dataclasses.field(default_factory=dict)
    warnings: Mapping = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready form: indices keyed by parameter name, S2 as a list of pairs."""
        names = self.space.names
        metrics = {}
        for m, ix in self.metrics.items():
            entry = {key: dict(zip(names, map(float, getattr(ix, key))))
                     for key in ("S1", "S1_conf", "ST", "ST_conf")}
            if ix.S2 is not None:
                entry["S2"] = [{"parameters": [names[j], names[k]], "S2": float(ix.S2[j, k]),
                                "S2_conf": float(ix.S2_conf[j, k])} for j, k in ix.pairs()]
            if ix.note:
                entry["note"] = ix.note
            metrics[m] = entry
        return {"problem": self.space.to_dict(),
                "analysis": {"n": self.failures.n, "n_used": self.failures.n_used,
                             "second_order": self.second_order, "conf_level": self.conf_level,
                             "num_resamples": self.num_resamples, "seed": self.seed},
                "run": dict(self.run), "failures": self.failures.to_dict(),
                "warnings": dict(self.warnings), "metrics": metrics}

    def to_json(self) -> str:
        """The indices as indented JSON (see :meth:`to_dict`)."""
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)

    def to_csv(self) -> str:
        """Tidy CSV: metric, index (S1/ST/S2), parameter, other_parameter (S2), value, conf."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["metric", "index", "parameter", "other_parameter", "value", "conf"])
        names = self.space.names
        for m, ix in self.metrics.items():
            for key in ("S1", "ST"):
                for name, v, c in zip(names, getattr(ix, key), getattr(ix, key + "_conf")):
                    w.writerow([m, key, name, "", repr(float(v)), repr(float(c))])
            for j, k in ix.pairs():
                w.writerow([m, "S2", names[j], names[k], repr(float(ix.S2[j, k])),
                            repr(float(ix.S2_conf[j, k]))])
        return buf.getvalue()

    def table(self) -> str:
        """A readable text table of the indices, one block per metric."""
        names, units = self.space.names, self.space.units
        w = max(len("parameter"), *(len(n) for n in names))
        u = max(len("unit"), *(len(x) for x in units))
        lines = [f"Sobol indices ({self.conf_level:.0%} intervals); {self.failures.summary}"]
        rows = self.failures.n * self.space.rows_per_base_sample(self.second_order)
        for code, entry in self.warnings.items():  # (not `w`: the column width above)
            shown = (", ".join(map(str, entry["samples"][:8]))
                     + (" …" if entry["count"] > 8 else ""))
            kept = "" if code in ("not_converged", "workspace") else ", still in the indices"
            lines.append(f"warning [{code}]: {entry['count']} of {rows} samples (rows {shown}; "
                         f"all in indices.json){kept}")
        for m, ix in self.metrics.items():
            lines += ["", m + (f"  ({ix.note})" if ix.note else ""),
                      f"  {'parameter':<{w}}  {'unit':<{u}}  {'S1':>17}  {'ST':>17}"]
            for i, (name, unit) in enumerate(zip(names, units)):
                lines.append(f"  {name:<{w}}  {unit:<{u}}  {ix.S1[i]:8.4f} ± {ix.S1_conf[i]:6.4f}"
                             f"  {ix.ST[i]:8.4f} ± {ix.ST_conf[i]:6.4f}")
            if ix.S2 is not None:
                lines.append(f"  {'pair':<{w + u + 2}}  {'S2':>17}")
            for j, k in ix.pairs():
                pair = f"{names[j]} × {names[k]}"
                lines.append(f"  {pair:<{w + u + 2}}  {ix.S2[j, k]:8.4f} ± "
                             f"{ix.S2_conf[j, k]:6.4f}")
        return "\n".join(lines)


def check_settings(*, num_resamples: int, conf_level: float) -> None:
    """Raise ``ValueError`` unless num_resamples ≥ 2 and 0 < conf_level < 1."""
    if not 0 < conf_level < 1:
        raise ValueError(f"conf_level must be in (0, 1); got {conf_level}")
    if num_resamples < 2:
        raise ValueError(f"num_resamples must be >= 2; got {num_resamples}")


def analyze(space: ParameterSpace, outputs: Mapping[str, np.ndarray], *, n: int,
            second_order: bool, on_failure: str = "raise", num_resamples: int = 100,
            conf_level: float = 0.95, seed: int | None = None,
            run: Mapping | None = None) -> SobolResult:
    """Sobol indices of every metric in ``outputs``.

    Args:
        space: the parameter space the design was drawn from.
        outputs: per-row outputs (M,) of the whole design, M = n · rows per base sample, in
            SALib's row order; ``"ok"`` is a status and ``validity.*`` are validity outputs
            (:data:`~jaxdobby.sensitivity.models.VALIDITY_PREFIX`), not metrics.
        n: base samples N of the design.
        second_order: whether the design holds the second-order blocks (and S2 is wanted).
        on_failure: ``"raise"`` or ``"drop"`` (see ``failures.py``).
        num_resamples: bootstrap resamples for the confidence intervals.
        conf_level: confidence level of the intervals, in (0, 1).
        seed: seed of the bootstrap (None: not reproducible).
        run: facts about the run to carry into the result.

    Raises:
        FailedSamplesError: see ``failures.apply_policy``.
        ValueError: bad settings or output shapes.
    """
    from SALib.analyze import sobol  # SALib imports pandas: keep it off the import path

    check_settings(num_resamples=num_resamples, conf_level=conf_level)
    step = space.rows_per_base_sample(second_order)
    outputs = {k: v for k, v in outputs.items() if not k.startswith(VALIDITY_PREFIX)}
    metrics, report = apply_policy(outputs, n=n, rows_per_base_sample=step, policy=on_failure)
    result = {}
    for name, y in metrics.items():
        if np.ptp(y) == 0.0:
            d = space.dim
            z = np.zeros(d)
            upper = np.triu(np.ones((d, d), dtype=bool), 1)
            s2 = np.where(upper, 0.0, np.nan) if second_order else None
            result[name] = MetricIndices(z, z, z, z, s2, s2, note="constant over the design: "
                                         "no variance to apportion, indices set to 0")
            continue
        # SALib treats seed=0 as 'no seed' (`if seed:`); a Generator is always honoured and
        # draws the same stream as the integer seed.
        rng = None if seed is None else np.random.default_rng(seed)
        si = sobol.analyze(space.problem, y, calc_second_order=second_order,
                           num_resamples=num_resamples, conf_level=conf_level, seed=rng)
        result[name] = MetricIndices(
            *(np.asarray(si[k], dtype=np.float64) for k in ("S1", "S1_conf", "ST", "ST_conf")),
            *((np.asarray(si["S2"]), np.asarray(si["S2_conf"])) if second_order else (None, None)))
    return SobolResult(space, result, report, second_order, conf_level, num_resamples, seed,
                       dict(run or {}))
