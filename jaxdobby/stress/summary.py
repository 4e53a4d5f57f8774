"""The arm's stress in a run's summary (users' units) and the warnings it raises."""

from __future__ import annotations

from .cycle import CycleStress, run_stress
from .recovery import EDGES

MPA = 1e-6
MM = 1e3

WARNINGS = {
    "yield_exceeded": "the peak stress in the arm ({stress_max_mpa:.0f} MPa) exceeds the yield "
                      "strength ({yield_strength_mpa:.0f} MPa): the arm deforms plastically and "
                      "the elastic model is not valid there",
    "fatigue_limit_exceeded": "the fatigue safety factor of the arm is {fatigue_safety_factor:.2f} "
                              "(< 1, Goodman, endurance limit {endurance_limit_mpa:.0f} MPa): it "
                              "will not survive 10^9 cycles",
}
"""Warning names (as in ``stress_warnings``) and their texts."""


def stress_summary(run, stress: CycleStress | None = None) -> dict:
    """Stress keys of ``jaxdobby simulate``'s summary (MPa, mm), with ``stress_warnings``."""
    stress = run_stress(run) if stress is None else stress
    return _summary({k: float(v) for k, v in stress.metrics.items()}, run.model.machine.arm)


def stress_summary_of(arrays: dict, arm) -> dict:
    """:func:`stress_summary` from the ``stress.metric.*`` entries of a run's report arrays
    (:func:`jaxdobby.simulate.report_arrays`) and its arm (:class:`~jaxdobby.arm.ArmDesign`)."""
    return _summary({k.removeprefix("stress.metric."): float(v) for k, v in arrays.items()
                     if k.startswith("stress.metric.")}, arm)


def _summary(m: dict, arm) -> dict:
    out = {
        "stress_max_mpa": m["stress_max"] * MPA,
        "stress_max_position_mm": m["stress_max_position"] * MM,
        "stress_max_edge": EDGES[int(m["stress_max_edge"])],
        "stress_range_mpa": m["stress_range"] * MPA,
        "stress_mean_mpa": m["stress_mean"] * MPA,
        "fatigue_safety_factor": m["fatigue_safety_factor"],
        "fatigue_position_mm": m["fatigue_position"] * MM,
        "fatigue_edge": EDGES[int(m["fatigue_edge"])],
        "endurance_limit_mpa": m["endurance_limit"] * MPA,
        "yield_strength_mpa": float(arm.yield_strength) * MPA,
    }
    warnings = []
    if out["stress_max_mpa"] > out["yield_strength_mpa"]:
        warnings.append("yield_exceeded")
    if out["fatigue_safety_factor"] < 1.0:
        warnings.append("fatigue_limit_exceeded")
    out["stress_warnings"] = warnings
    return out


def warning_texts(summary: dict) -> list[str]:
    """One line per warning of ``summary['stress_warnings']``, named."""
    return [f"{name}: " + WARNINGS[name].format(**summary)
            for name in summary.get("stress_warnings", [])]


def warning_entries(summary: dict) -> list[dict]:
    """The stress warnings of ``summary['stress_warnings']`` as entries of the summary's
    ``warnings`` list (code, message, value, limit; :mod:`jaxdobby.validity`)."""
    limits = {"yield_exceeded": ("stress_max_mpa", "yield_strength_mpa"),
              "fatigue_limit_exceeded": ("fatigue_safety_factor", None)}
    out = []
    for name in summary.get("stress_warnings", []):
        value, limit = limits[name]
        out.append({"code": name, "message": WARNINGS[name].format(**summary),
                    "value": float(summary[value]),
                    "limit": 1.0 if limit is None else float(summary[limit])})
    return out
