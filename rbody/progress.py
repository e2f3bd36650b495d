"""A progress line with the time left, for runs long enough to want one (simulate, and the validation commands).

    progress = Progress("rbody rk4", total=nsteps)   # nothing is printed until the first update
    progress.update(done)                            # "rbody rk4: 37 % (1.2e+06 of 3.3e+06 steps), 12 s left"
    progress.finish()

On a terminal the line is rewritten in place (carriage return), at most every UPDATE_SECONDS; on anything else
(a log file, a CI console) one line is written at most every LOG_SECONDS. The time left is the time so far
scaled by the work left over the work done.

shown(progress, seconds) decides whether a run shows one: progress=True always, False never, None (the
default of simulate) only in an interactive session (stderr a terminal, not under pytest, no CI variable) and
only when the run is estimated to take more than PROGRESS_AFTER_SECONDS.
"""

from __future__ import annotations

import os
import sys
import time
from typing import IO

PROGRESS_AFTER_SECONDS = 3.0  # progress=None shows a line for runs estimated longer than this
UPDATE_SECONDS = 0.5          # a terminal's line is rewritten at most this often
LOG_SECONDS = 10.0            # a log gets a line at most this often


def interactive(stream: IO | None = None) -> bool:
    """True in an interactive session: `stream` (default stderr) is a terminal, pytest is not running and no CI
    variable is set (the default of progress=None; tests and CI runs never show a line)."""
    stream = sys.stderr if stream is None else stream
    try:  # first: a stream that is no terminal answers at once (a call costs microseconds; os.environ is slower)
        if not stream.isatty():
            return False
    except (AttributeError, ValueError):
        return False
    return not ("PYTEST_CURRENT_TEST" in os.environ or os.environ.get("CI"))


def wanted(progress: bool | None) -> bool | None:
    """True (show), False (never), None (show if the run proves long): progress checked (ValueError otherwise)."""
    if progress is not None and not isinstance(progress, bool):
        raise ValueError(f"progress={progress!r}: expected True, False or None (None: shown in an interactive session "
                         f"for runs estimated longer than {PROGRESS_AFTER_SECONDS:g} s)")
    if progress is None:
        return None if interactive() else False
    return progress


def format_seconds(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


class Progress:
    """One progress line for `total` units of work (steps, element-steps) named `label`; see the module docstring."""

    def __init__(self, label: str, total: float, unit: str = "steps", stream: IO | None = None) -> None:
        self.label, self.total, self.unit = label, float(total), unit
        self.stream = sys.stderr if stream is None else stream
        try:
            self.terminal = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.terminal = False
        self.started = time.perf_counter()
        self.last_shown = -1e300
        self.shown = False

    def line(self, done: float) -> str:
        elapsed = time.perf_counter() - self.started
        fraction = min(1.0, done / self.total) if self.total > 0 else 1.0
        left = elapsed * (1.0 - fraction) / fraction if fraction > 0 else float("inf")
        when = format_seconds(left) + " left" if left != float("inf") else "estimating the time left"
        return (f"{self.label}: {100 * fraction:.0f} % ({done:.3g} of {self.total:.3g} {self.unit}, "
                f"{format_seconds(elapsed)} so far), {when}")

    def update(self, done: float) -> None:
        now = time.perf_counter()
        if now - self.last_shown < (UPDATE_SECONDS if self.terminal else LOG_SECONDS):
            return
        self.last_shown = now
        self._write(self.line(done))

    def finish(self, done: float | None = None) -> None:
        """The last line (100 %, or `done`), ended by a newline; nothing when nothing was shown."""
        if self.shown:
            self._write(self.line(self.total if done is None else done), end="\n")

    def _write(self, text: str, end: str = "") -> None:
        if self.terminal:
            self.stream.write("\r" + text + "\x1b[K" + end)
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
        self.shown = True


class Reporter:
    """A Progress line shown as progress=True|False|None asks (module docstring): with None, only once the work done
    so far predicts more than PROGRESS_AFTER_SECONDS in all (and only in an interactive session). For loops that
    cannot be cut at will (a simulator's chunks of steps): call update(done) after each piece, finish() at the end."""

    def __init__(self, progress: bool | None, label: str, total: float, unit: str = "steps",
                 stream: IO | None = None) -> None:
        self.show = wanted(progress)
        self.label, self.total, self.unit, self.stream = label, float(total), unit, stream
        self.started = time.perf_counter()
        self.line: Progress | None = None

    def update(self, done: float) -> None:
        if self.show is False:
            return
        if self.line is None:
            elapsed = time.perf_counter() - self.started
            if self.show is None and (done <= 0 or done >= self.total
                                      or elapsed * self.total / done <= PROGRESS_AFTER_SECONDS):
                return
            self.line = Progress(self.label, self.total, self.unit, self.stream)
            self.line.started = self.started
        self.line.update(done)

    def finish(self) -> None:
        if self.line is not None:
            self.line.finish()


__all__ = ["Progress", "Reporter", "wanted", "interactive", "format_seconds", "PROGRESS_AFTER_SECONDS"]
