"""A measured heald-frame trace: reading and checking the CSV file.

Columns (header row, comma-separated, any order, other columns ignored):

* ``time_s`` — sample times [s], strictly increasing and uniform (the time origin is
  arbitrary);
* ``heald_frame_acceleration_m_s2`` — heald-frame acceleration [m/s²], positive up, and/or
* ``heald_frame_position_mm`` — heald-frame position [mm], positive up (any zero).

Every check raises :class:`~jaxdobby.errors.InputError` with one line naming the file and the
fault.
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np

from ..errors import InputError

TIME = "time_s"
ACCELERATION = "heald_frame_acceleration_m_s2"
POSITION = "heald_frame_position_mm"
UNIFORM_TOLERANCE = 1e-3
"""Largest |Δt − mean Δt| / mean Δt accepted as uniform sampling (logger jitter, decimal
rounding of the times in the file)."""


@dataclasses.dataclass(frozen=True)
class Measurement:
    """Measured channels on uniform times (SI).

    Attributes:
        time: sample times [s], shape (n,).
        acceleration: heald-frame acceleration [m/s²], shape (n,), or None.
        position: heald-frame position [m], shape (n,), or None.
    """

    time: np.ndarray
    acceleration: np.ndarray | None = None
    position: np.ndarray | None = None

    @property
    def channels(self) -> tuple[str, ...]:
        """Names of the channels present (``acceleration``, ``position``)."""
        return tuple(n for n in ("acceleration", "position") if getattr(self, n) is not None)


def read_csv(path: str | Path) -> Measurement:
    """Read and check a measured trace (see the module docstring)."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise InputError(f"measured trace {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read measured trace {path}: {err}") from None
    if not rows:
        raise InputError(f"{path}: the file is empty (expected a header with {TIME} and "
                         f"{ACCELERATION} and/or {POSITION})")
    header = [h.strip() for h in rows[0]]
    if TIME not in header or not {ACCELERATION, POSITION} & set(header):
        raise InputError(f"{path}: the header must name {TIME} and one or both of "
                         f"{ACCELERATION}, {POSITION}; found {', '.join(header) or 'nothing'}")
    wanted = [c for c in (TIME, ACCELERATION, POSITION) if c in header]
    columns = {c: [] for c in wanted}
    for line, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        for c in wanted:
            i = header.index(c)
            try:
                x = float(row[i])
            except (IndexError, ValueError):
                raise InputError(f"{path}: line {line}: {c} is not a number "
                                 f"({row[i] if i < len(row) else 'missing'!r})") from None
            if not np.isfinite(x):
                raise InputError(f"{path}: line {line}: {c} = {x} (NaN or infinite rows are not "
                                 f"accepted: remove them)")
            columns[c].append(x)
    arrays = {c: np.asarray(v) for c, v in columns.items()}
    return check(Measurement(arrays[TIME], arrays.get(ACCELERATION),
                             None if POSITION not in arrays else arrays[POSITION] * 1e-3),
                 str(path))


def check(meas: Measurement, where: str = "measured trace") -> Measurement:
    """Check the times (≥ 3 samples, strictly increasing, uniform) and the channels (finite,
    as many as the times)."""
    t = np.asarray(meas.time, float)
    if t.ndim != 1 or t.size < 3:
        raise InputError(f"{where}: at least 3 samples are needed, got {t.size}")
    for name in ("time",) + meas.channels:
        x = getattr(meas, name)
        if np.shape(x) != t.shape:
            raise InputError(f"{where}: {name} has {np.size(x)} samples, time has {t.size}")
        if not np.all(np.isfinite(x)):
            raise InputError(f"{where}: {name} contains NaN or infinite values: remove those rows")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise InputError(f"{where}: {TIME} must increase strictly (sample {i + 1}: "
                         f"{t[i]:g} s after {t[i - 1]:g} s)")
    step = (t[-1] - t[0]) / (t.size - 1)
    jitter = float(np.max(np.abs(dt - step)) / step)
    if jitter > UNIFORM_TOLERANCE:
        raise InputError(f"{where}: {TIME} must be uniformly sampled (the largest step differs "
                         f"from the mean {step:g} s by {100 * jitter:.2g} %; "
                         f"valid: <= {100 * UNIFORM_TOLERANCE:g} %)")
    return meas


def check_length(meas: Measurement, period: float, where: str = "measured trace") -> None:
    """A trace shorter than one heald-frame cycle (``period`` [s]) cannot fix the phase."""
    span = float(meas.time[-1] - meas.time[0])
    if span < period:
        raise InputError(f"{where}: the trace spans {span:g} s, less than one heald-frame cycle "
                         f"({period:g} s at this speed); record at least one cycle")


def to_csv(meas: Measurement) -> str:
    """The measurement as a CSV text in the format :func:`read_csv` reads."""
    cols = [(TIME, meas.time)]
    if meas.acceleration is not None:
        cols.append((ACCELERATION, meas.acceleration))
    if meas.position is not None:
        cols.append((POSITION, meas.position * 1e3))
    lines = [",".join(c for c, _ in cols)]
    lines += [",".join(repr(float(v)) for v in row) for row in zip(*(x for _, x in cols))]
    return "\n".join(lines) + "\n"
