"""A heald frame's lift sequence b₀…b_{P−1} (DESIGN.md §7): 1 = the frame is up in that pick's
open shed; in pick k the eccentric turns 180° iff b_k ≠ b_{k−1} (cyclically), otherwise the
frame dwells through the pick. The law itself is :func:`jaxdobby.modulator.crank_angle`
(``plan=``); here the users' text form "1100" and its checks.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def parse_plan(plan, *, field: str = "lift_plan") -> np.ndarray:
    """The lift sequence as a float array (P,) of 0/1 from text ("1100") or a sequence.

    Raises :class:`~jaxdobby.errors.InputError` naming ``field`` for an empty plan or
    characters other than 0 and 1. A plan of one pick ("1", "0") never moves: the static
    case (:mod:`jaxdobby.weave.static`), like every plan without both 0 and 1.
    """
    if isinstance(plan, str):
        text = plan.strip()
        if not text:
            raise InputError(f"{field} is empty: give one 0/1 character per pick, e.g. 1100")
        bad = sorted(set(text) - {"0", "1"})
        if bad:
            raise InputError(f"{field} = {plan!r} has characters other than 0 and 1 "
                             f"({''.join(bad)!r}): give one 0/1 per pick, e.g. 1100")
        values = np.array([float(c) for c in text])
    else:
        values = np.asarray(plan, dtype=float).reshape(-1)
        if values.size == 0 or not np.all((values == 0.0) | (values == 1.0)):
            raise InputError(f"{field} must be a non-empty sequence of 0 and 1")
    return values


def plan_text(plan) -> str:
    """"1100" from a 0/1 array."""
    return "".join("1" if v > 0.5 else "0" for v in np.asarray(plan).reshape(-1))


def moves(plan) -> np.ndarray:
    """Picks in which the frame moves (b_k ≠ b_{k−1}, cyclic), bool (P,)."""
    b = np.asarray(plan) > 0.5
    return b != np.roll(b, 1)


def is_static(plan) -> bool:
    """True for a plan that never moves ("11", "0000"): no dynamics, the frame holds still."""
    return not np.any(moves(plan))


def shift(plan, k: int) -> np.ndarray:
    """The plan started k picks later (b_{(i+k) mod P})."""
    return np.roll(np.asarray(plan), -k)
