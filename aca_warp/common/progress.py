"""Progress of a long run where no terminal shows a bar (stderr to a log, a batch system, CI): a plain line on stderr
every :data:`LOG_INTERVAL` seconds of wall time, none for a run that ends sooner."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

LOG_INTERVAL = 30.0
"""Wall time between two progress lines in a log [s]."""


class LogProgress:
    """Progress lines for a log: ``update`` prints "aca-warp: <what> <done> of <total> <unit> (<%>), <rate>, <wall>
    elapsed" once ``interval`` seconds of wall time have passed since the start or the last line.

    Args:
        what: What runs, the line's start (e.g. "hf:").
        total: The amount of the whole run, in ``unit``.
        unit: The amount's unit ("s simulated").
        interval: Wall time between lines [s] (None: :data:`LOG_INTERVAL`).
        clock: Wall clock [s] (``time.perf_counter``).
        stream: Where the lines go (``sys.stderr`` at the time of each line).
    """

    def __init__(
        self,
        what: str,
        total: float,
        unit: str = "s simulated",
        interval: float | None = None,
        clock: Callable[[], float] = time.perf_counter,
        stream: TextIO | None = None,
    ) -> None:
        self.what, self.total, self.unit = what, total, unit
        self.interval = LOG_INTERVAL if interval is None else interval
        self.clock, self.stream = clock, stream
        self.start = self.last = clock()

    def update(self, done: float, rate: Callable[[], str] | str = "") -> bool:
        """Print a line if one is due (``done``: the amount so far, in ``unit``; ``rate``: what follows it, e.g.
        "1.2e+05 steps/s", or a function that makes it, called only for a line); whether one was printed."""
        now = self.clock()
        if now - self.last < self.interval:
            return False
        self.last = now
        rate = rate() if callable(rate) else rate
        share = f" ({100.0 * done / self.total:.0f} %)" if self.total > 0 else ""
        parts = [f"{done:.4g} of {self.total:.4g} {self.unit}{share}", *([rate] if rate else []),
                 f"{now - self.start:.0f} s elapsed"]  # fmt: skip
        print(f"aca-warp: {self.what} {', '.join(parts)}", file=self.stream or sys.stderr, flush=True)
        return True
