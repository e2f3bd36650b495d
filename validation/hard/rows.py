"""The rows of the hard-case tables and the outcome of a run: what every hard case reports."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

OUTCOMES = ("exact", "error", "wrong count", "blew up", "refused", "not run")


@dataclass(frozen=True)
class HardRow:
    """One run of one case.

    variant: what was run (parameters); backend: rbody, mujoco or pymunk; setting: method or
    integrator and step; outcome: one of OUTCOMES; value: the measured number (None when there is
    none) and measure: what it is; seconds: wall time of the run [s]; verdict: "pass"/"FAIL" for
    rbody rows, "" otherwise; note: why (an error message, an estimate, a reference value)."""

    variant: str
    backend: str
    setting: str
    outcome: str
    value: float | None
    measure: str
    seconds: float
    verdict: str = ""
    note: str = ""

    def __post_init__(self) -> None:
        if self.outcome not in OUTCOMES:
            raise ValueError(f"outcome={self.outcome!r}: expected one of {OUTCOMES}")


@dataclass
class CaseResult:
    """Everything one case reports: its rows, its figures (caption, file name), the findings in words."""

    number: int
    title: str
    requirement: str
    rows: list[HardRow] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)
    findings: list[str] = field(default_factory=list)
    seconds: float = 0.0


def timed(function: Callable, *args, **kwargs):
    """(result, seconds) of one call."""
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def attempt(function: Callable, *args, **kwargs):
    """(result or None, error or None, seconds): a call whose failure is a result to report."""
    start = time.perf_counter()
    try:
        result = function(*args, **kwargs)
    except Exception as error:  # blow-ups and refusals of every simulator are outcomes
        return None, error, time.perf_counter() - start
    return result, None, time.perf_counter() - start


def error_outcome(error: BaseException, *, started: bool = True) -> str:
    """The outcome of a run that raised: refused (the simulator cannot express the case, the method does
    not apply, rbody refused the step before any work, or the error came before the run: started=False)
    or blew up (anything raised while or after stepping: an unstable or non-finite state, and also an
    error of another type that escaped, which the rbody verdicts then count against rbody)."""
    from rbody.errors import MethodNotApplicable, SimulationError

    if isinstance(error, (NotImplementedError, MethodNotApplicable)) or not started:
        return "refused"
    text = str(error)
    if isinstance(error, SimulationError) and ("beyond its estimated stability limit" in text
                                               or "cannot run it" in text or "no stability interval" in text):
        return "refused"
    return "blew up"


def short(error: BaseException, limit: int = 240) -> str:
    text = f"{type(error).__name__}: {error}"
    return text if len(text) <= limit else text[:limit - 3] + "..."
