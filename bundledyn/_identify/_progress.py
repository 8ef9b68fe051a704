"""A running fit's progress, on one line."""

import sys

from ._clock import FitClock

__all__ = ["FitProgress"]

# A fit shorter than this shows nothing unless asked to (`progress=True`).
_QUIET_SECONDS = 3.0


class FitProgress:
    """Shows a fit's continuation stage, Levenberg–Marquardt step, merit and time.

    On a terminal the line is rewritten in place; elsewhere (a log, a notebook) each update
    is a line of its own. `show=None` shows it on a terminal once the fit has run a few
    seconds; `True` always, `False` never.
    """

    def __init__(self, show: bool | None, clock: FitClock, *, stream=None):
        self.show, self.clock = show, clock
        self.stream = sys.stderr if stream is None else stream
        self._terminal = bool(getattr(self.stream, "isatty", lambda: False)())
        self._shown = False

    def _wanted(self) -> bool:
        if self.show is None:
            return self._terminal and self.clock.elapsed() > _QUIET_SECONDS
        return self.show

    def update(self, stage: int, stages: int, step: int, cost: float) -> None:
        """Report accepted step `step` of continuation stage `stage` (from 1) of `stages`."""
        if not self._wanted():
            return
        line = (
            f"fit: stage {stage}/{stages}, step {step}, cost {cost:.6e}, "
            f"{self.clock.elapsed():.1f} s (compiling {self.clock.compile_seconds:.1f} s)"
        )
        end = "" if self._terminal else "\n"
        self.stream.write(f"\r{line:<100}{end}" if self._terminal else f"{line}{end}")
        self.stream.flush()
        self._shown = True

    def close(self) -> None:
        """End the line on a terminal."""
        if self._shown and self._terminal:
            self.stream.write("\n")
            self.stream.flush()
