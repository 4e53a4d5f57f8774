"""Named weaves as lift plans for a set of frames drawn in straight order (frame i carries the
ends i, i + F, … of a weave on F frames; the plan of frame i repeats every F frames).

The lift plan of a weave is an array (picks, frames) of 0/1, entry [k, i] = 1 when frame i is
up in pick k (the weaver's lift-plan grid; DESIGN.md §7). With k the pick and i the frame
(0-based):

* ``plain``    1/1:  up iff (i + k) even — "10" / "01", repeat 2 (the default machine's case);
* ``twill22``  2/2 twill: up iff (k − i) mod 4 ∈ {0, 1} — "1100" shifted a pick per frame;
* ``twill31``  3/1 twill: up iff (k − i) mod 4 ∈ {0, 1, 2} — "1110";
* ``satin5``   5-end satin, move 2: up iff (k − 2i) mod 5 = 0 — "10000", a frame up one
  pick in five;
* ``basket22`` 2/2 basket (hopsack): up iff (⌊k/2⌋ + ⌊i/2⌋) even — "1100" in pairs of frames.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def _plain(k, i):
    return (i + k) % 2 == 0


def _twill22(k, i):
    return (k - i) % 4 < 2


def _twill31(k, i):
    return (k - i) % 4 < 3


def _satin5(k, i):
    return (k - 2 * i) % 5 == 0


def _basket22(k, i):
    return (k // 2 + i // 2) % 2 == 0


WEAVES = {"plain": (2, _plain), "twill22": (4, _twill22), "twill31": (4, _twill31),
          "satin5": (5, _satin5), "basket22": (4, _basket22)}
"""Named weave → (repeat in picks, rule(pick, frame) → up)."""


def named_plan(name: str, frames: int) -> np.ndarray:
    """The lift plan (picks, frames) of weave ``name`` on ``frames`` frames (float 0/1)."""
    if name not in WEAVES:
        raise InputError(f"--weave = {name!r} is not valid: use one of {', '.join(WEAVES)}")
    if not 1 <= frames <= 64:
        raise InputError(f"--frames = {frames} is outside the valid range (an integer 1…64)")
    picks, rule = WEAVES[name]
    k, i = np.meshgrid(np.arange(picks), np.arange(frames), indexing="ij")
    return rule(k, i).astype(float)
