"""Errors raised for bad input, with messages that name the field and its valid range."""

from __future__ import annotations

import math


class InputError(ValueError):
    """A parameter, option or file the user gave is out of range or malformed.

    The message names the field (in the users' terms and units) and what would be valid; the
    command line prints it as one line and exits with status 2.
    """


def check_range(name: str, value, low=None, high=None, *, unit: str = "",
                low_open: bool = True, high_open: bool = False) -> float:
    """Return ``float(value)`` if it is a finite number within the range, else raise.

    ``low_open`` excludes ``low`` itself (e.g. a speed must be > 0); ``high_open`` likewise.
    """
    u = f" {unit}" if unit else ""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number{_range_text(low, high, u, low_open, high_open)}"
                         f", got {value!r}") from None
    bad = (not math.isfinite(x)
           or (low is not None and (x <= low if low_open else x < low))
           or (high is not None and (x >= high if high_open else x > high)))
    if bad:
        raise InputError(f"{name} = {value}{u} is outside the valid range"
                         f"{_range_text(low, high, u, low_open, high_open)}")
    return x


def _range_text(low, high, unit, low_open, high_open) -> str:
    if low is None and high is None:
        return " (a finite number)"
    if high is None:
        return f" ({'>' if low_open else '>='} {low:g}{unit})"
    if low is None:
        return f" ({'<' if high_open else '<='} {high:g}{unit})"
    return (f" ({low:g}{unit} {'<' if low_open else '<='} value "
            f"{'<' if high_open else '<='} {high:g}{unit})")
