"""A one-line progress bar for long batch runs, with samples/s and ETA.

The library reports progress through a ``progress(done, total)`` callback and never prints; this
bar is the command line's callback. It draws on a stream (stderr by default) with carriage
returns, so it stays on one line.
"""

from __future__ import annotations

import sys
import time


class ProgressBar:
    """A one-line progress bar with samples/s and ETA, for ``progress=`` (CLI side: it prints).

    The rate counts only the samples computed since the first call (compilation and chunks
    read back on resume excluded).

    Args:
        stream: where to draw (default: ``sys.stderr`` at call time).
        width: bar width in characters.
        min_interval: least time between redraws [s] (the final one is always drawn).
    """

    def __init__(self, stream=None, width: int = 28, min_interval: float = 0.2):
        self.stream, self.width, self.min_interval = stream, width, min_interval
        self._t0 = self._done0 = None
        self._last = -float("inf")

    def __call__(self, done: int, total: int) -> None:
        now = time.perf_counter()
        if self._t0 is None:
            self._t0, self._done0 = now, done
        if done < total and now - self._last < self.min_interval:
            return
        self._last = now
        stream = self.stream or sys.stderr
        stream.write("\r" + self.line(done, total, now - self._t0, done - self._done0))
        if done >= total:
            stream.write("\n")
        stream.flush()

    def line(self, done: int, total: int, elapsed: float, computed: int) -> str:
        """The bar's text for ``done`` of ``total`` after ``computed`` samples in ``elapsed`` s."""
        frac = done / total if total else 1.0
        fill = int(round(frac * self.width))
        rate = computed / elapsed if elapsed > 0 and computed > 0 else None
        eta = (total - done) / rate if rate else None
        return (f"[{'#' * fill}{'.' * (self.width - fill)}] {done}/{total} samples {frac:4.0%}  "
                f"{f'{rate:,.0f}' if rate else '-'} samples/s  ETA {_clock(eta)}")


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "--:--"
    m, s = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"
