"""Weave patterns: lift plans of heald frames (DESIGN.md §7 "Lift plans").

* :mod:`~jaxdobby.weave.plan` — a frame's lift sequence: parsing, validation, picks;
* :mod:`~jaxdobby.weave.metrics` — metrics over the repeat and per pick (dwell vibration).
"""

from .metrics import pick_metrics, pick_of
from .plan import parse_plan, plan_text

__all__ = ["parse_plan", "plan_text", "pick_metrics", "pick_of"]
