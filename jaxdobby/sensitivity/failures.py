"""Failed samples: which rows failed, why, and what the Sobol estimate does about them.

A sample *fails* when the model's ``"ok"`` entry says so (False, or a nonzero integer code) or
when any of its metrics is not finite. Failed samples are never passed to SALib: one NaN turns
every index of that metric into NaN.

Policies (``on_failure``):

``"raise"`` (default)
    Compute no indices; raise :class:`FailedSamplesError` listing the rows and reasons. The
    finished chunks stay on disk, so nothing is lost.
``"drop"``
    Drop every *base sample* that holds a failed row, with all of its rows. The Saltelli
    estimators (Saltelli et al. 2010) are means over base samples j of terms built from the
    rows A_j, B_j, AB_j^i (and BA_j^i) of that base sample, so single rows cannot be dropped
    (the matrix's structure would break and SALib would misalign the blocks), but whole base
    samples can: the indices are then the estimate from the N' = N − (dropped) remaining base
    samples. Two effects are reported: the intervals widen (fewer samples, and the scrambled
    Sobol' points lose their balance, so the QMC rate is lost), and the indices describe the
    model *on the region where it succeeds*: if failures cluster in one corner of the space,
    the indices are biased toward the rest. Replacing failed outputs by a value (mean, nearest
    neighbour) is not offered: it invents outputs and shrinks the variance the indices divide.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .models import VALIDITY_PREFIX

POLICIES = ("raise", "drop")
STATUS = "ok"
"""Name of the optional per-sample status entry in a model's outputs."""


@dataclasses.dataclass(frozen=True)
class SampleFailure:
    """One failed sample.

    Attributes:
        row: the row of the sample matrix (0-based).
        reason: why, e.g. ``"status ok=False"`` or ``"non-finite metric(s): y=nan"``.
    """

    row: int
    reason: str


def find_failures(outputs: Mapping[str, np.ndarray]) -> tuple[SampleFailure, ...]:
    """The failed rows of a model's outputs, in row order.

    Args:
        outputs: per-row arrays of shape (M,): the metrics, and optionally ``"ok"`` (bool, True
            = success; or an integer code, 0 = success).
    """
    status = outputs.get(STATUS)
    metrics = {k: np.asarray(v) for k, v in outputs.items()
               if k != STATUS and not k.startswith(VALIDITY_PREFIX)}
    bad = np.zeros(len(next(iter(outputs.values()))), dtype=bool)
    if status is not None:
        status = np.asarray(status)
        status_bad = ~status if status.dtype == np.bool_ else status != 0
        bad |= status_bad
    for v in metrics.values():
        bad |= ~np.isfinite(v)
    failures = []
    for row in np.flatnonzero(bad):
        reasons = []
        if status is not None and status_bad[row]:
            reasons.append("status ok=False" if status.dtype == np.bool_
                           else f"status code {int(status[row])}")
        nonfinite = [f"{k}={float(v[row])}" for k, v in metrics.items() if not np.isfinite(v[row])]
        if nonfinite:
            reasons.append("non-finite metric(s): " + ", ".join(nonfinite))
        failures.append(SampleFailure(int(row), "; ".join(reasons)))
    return tuple(failures)


def describe(failures: tuple[SampleFailure, ...], limit: int = 10) -> str:
    """One line per failed row (the first ``limit``), for messages."""
    lines = [f"  row {f.row}: {f.reason}" for f in failures[:limit]]
    if len(failures) > limit:
        lines.append(f"  … and {len(failures) - limit} more")
    return "\n".join(lines)


class FailedSamplesError(RuntimeError):
    """Samples failed and the policy is ``"raise"``; ``.failures`` lists them."""

    def __init__(self, failures: tuple[SampleFailure, ...], total: int):
        self.failures, self.total = failures, total
        super().__init__(
            f"{len(failures)} of {total} samples failed; no indices computed (policy 'raise'; "
            f"'drop' would estimate them without the failed base samples):\n{describe(failures)}")

    def to_dict(self) -> dict:
        """JSON-ready form: the failed rows and reasons."""
        return {"policy": "raise", "count": len(self.failures), "samples": self.total,
                "failures": _rows(self.failures)}


@dataclasses.dataclass(frozen=True)
class FailureReport:
    """What failed and how the indices were affected.

    Attributes:
        policy: the policy applied.
        failures: the failed samples.
        dropped_base_samples: base samples left out of the estimate (``"drop"``).
        n: base samples of the design; ``n_used``: base samples in the estimate.
    """

    policy: str
    failures: tuple[SampleFailure, ...]
    dropped_base_samples: tuple[int, ...]
    n: int
    n_used: int

    @property
    def summary(self) -> str:
        """One sentence on how the indices were affected."""
        if not self.failures:
            return f"no failed samples; indices from all {self.n} base samples"
        rows = _short([f.row for f in self.failures])
        return (f"{len(self.failures)} failed sample(s) (rows {rows}); policy 'drop' left out "
                f"{len(self.dropped_base_samples)} base sample(s) "
                f"({_short(self.dropped_base_samples)}): indices from {self.n_used} of {self.n} "
                "base samples, with wider intervals, and describing the model where it succeeds")

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {"policy": self.policy, "count": len(self.failures),
                "failures": _rows(self.failures),
                "dropped_base_samples": list(self.dropped_base_samples),
                "n": self.n, "n_used": self.n_used, "summary": self.summary}


def apply_policy(outputs: Mapping[str, np.ndarray], *, n: int, rows_per_base_sample: int,
                 policy: str = "raise") -> tuple[dict[str, np.ndarray], FailureReport]:
    """Apply a failure policy to the outputs of a whole Saltelli design.

    Args:
        outputs: per-row arrays (M,) with M = n · rows_per_base_sample, rows grouped by base
            sample as SALib's ``sobol.sample`` lays them out.
        n: base samples N.
        rows_per_base_sample: 2D + 2 (second order) or D + 2.
        policy: ``"raise"`` or ``"drop"`` (see the module docstring).

    Returns:
        The metrics (status removed) restricted to the kept base samples, and the report.

    Raises:
        FailedSamplesError: samples failed and the policy is ``"raise"``, or every base sample
            failed.
        ValueError: unknown policy or a row count that is not ``n · rows_per_base_sample``.
    """
    if policy not in POLICIES:
        raise ValueError(f"on_failure must be one of {POLICIES}; got {policy!r}")
    metrics = {k: np.asarray(v, dtype=np.float64) for k, v in outputs.items() if k != STATUS}
    total = n * rows_per_base_sample
    for k, v in metrics.items():
        if v.shape != (total,):
            raise ValueError(f"output {k!r}: expected shape ({total},) for n = {n} base samples of "
                             f"{rows_per_base_sample} rows; got {v.shape}")
    failures = find_failures(outputs)
    if failures and policy == "raise":
        raise FailedSamplesError(failures, total)
    dropped = tuple(sorted({f.row // rows_per_base_sample for f in failures}))
    if len(dropped) == n:
        raise FailedSamplesError(failures, total)
    keep = np.ones(n, dtype=bool)
    keep[list(dropped)] = False
    kept = {k: v.reshape(n, rows_per_base_sample)[keep].reshape(-1) for k, v in metrics.items()}
    return kept, FailureReport(policy, failures, dropped, n, int(keep.sum()))


def _rows(failures):
    return [{"row": f.row, "reason": f.reason} for f in failures]


def _short(values, limit: int = 8) -> str:
    values = list(values)
    text = ", ".join(str(v) for v in values[:limit])
    return text + (f", … ({len(values)} in all)" if len(values) > limit else "")
