"""Input checks shared by every constructor: each failure is a ValueError naming the value and the rule."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def finite_array(value: Any, name: str, *, shape: tuple | None = None, ndim: int | None = None) -> np.ndarray:
    """float64 copy of `value`, checked real, finite and (optionally) of a given shape or rank.

    Text ("1.5") and complex numbers are refused rather than converted. A copy that would not fit in the memory
    this process can still allocate (a broadcast view of 10^9 elements) is refused before it is made.
    """
    number = _plain_number(value)
    if number is not None and shape in (None, ()) and ndim in (None, 0):  # one finite number: no array pass needed
        return np.array(number)
    try:
        viewed = np.asarray(value)
        kind = viewed.dtype.kind
        if kind in "USVcmM":  # text, bytes, void, complex, timedelta, datetime
            raise TypeError(f"got dtype kind {kind!r}")
        if viewed.size > LARGE_ARRAY:
            from rbody.resources import memory_problem

            problem = memory_problem(8.0 * viewed.size, f"a float64 copy of {name} (shape {viewed.shape})")
            if problem:
                raise MemoryError(problem)
        array = np.array(value, dtype=np.float64)
    except MemoryError as error:
        raise ValueError(f"{name}: {error}; give a smaller batch") from None
    except (TypeError, ValueError, OverflowError) as error:  # (an int beyond float64's range: OverflowError)
        raise ValueError(f"{name}={_short(value)}: expected real numbers ({error})") from None
    if shape is not None and array.shape != tuple(shape):
        raise ValueError(f"{name} has shape {array.shape}: expected {tuple(shape)}")
    if ndim is not None and array.ndim != ndim:
        raise ValueError(f"{name} has {array.ndim} dimensions: expected {ndim}")
    finite = np.isfinite(array)
    if not np.all(finite):
        if array.size <= 6:
            raise ValueError(f"{name}={describe_values(array)}: every value must be finite (no NaN or inf)")
        bad = np.argwhere(~finite)
        raise ValueError(f"{name} (shape {array.shape}): {len(bad)} of {array.size} values are not finite, the first "
                         f"at index {tuple(int(i) for i in bad[0])} ({array[tuple(bad[0])]!r}); every value must be "
                         "finite (no NaN or inf)")
    return array


def _plain_number(value: Any) -> float | None:
    """`value` as a float when it is one finite Python or numpy float, or a Python int (not a bool), else None: the
    checks' fast path (a model of many bodies checks hundreds of thousands of such scalars as it loads)."""
    if type(value) in (float, int, np.float64):
        try:
            number = float(value)
        except OverflowError:  # an int beyond float64: the array path reports it
            return None
        return number if math.isfinite(number) else None
    return None


LARGE_ARRAY = 2**23  # elements (64 MB as float64) above which finite_array checks that its copy fits in memory


def _short(value: Any, limit: int = 200) -> str:
    """repr(value) cut to `limit` characters (a message never echoes a huge value whole)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def positive(value: Any, name: str) -> Any:
    """`value` (scalar or array) checked finite and > 0; a float for a scalar, else a float64 array."""
    number = _plain_number(value)
    if number is not None and number > 0:
        return number
    array = finite_array(value, name)
    if np.any(array <= 0):
        raise ValueError(f"{name}={describe_values(array)}: must be > 0")
    return float(array) if array.ndim == 0 else array


def nonnegative(value: Any, name: str) -> Any:
    """`value` checked finite and >= 0."""
    number = _plain_number(value)
    if number is not None and number >= 0:
        return number
    array = finite_array(value, name)
    if np.any(array < 0):
        raise ValueError(f"{name}={describe_values(array)}: must be >= 0")
    return float(array) if array.ndim == 0 else array


def in_interval(value: Any, name: str, low: float, high: float, *, closed: bool = False) -> Any:
    """`value` checked finite and inside (low, high), or [low, high] when closed."""
    number = _plain_number(value)
    if number is not None and (low <= number <= high if closed else low < number < high):
        return number
    array = finite_array(value, name)
    inside = (array >= low) & (array <= high) if closed else (array > low) & (array < high)
    if not np.all(inside):
        brackets = "[]" if closed else "()"
        raise ValueError(f"{name}={describe_values(array)}: must lie in {brackets[0]}{low}, {high}{brackets[1]}")
    return float(array) if array.ndim == 0 else array


def single_number(value: Any, name: str, check=finite_array) -> float:
    """One number (not an array: an event-driven scene is not a batch), checked by `check`."""
    array = finite_array(value, name)
    if array.ndim != 0:
        raise ValueError(f"{name}={value!r}: expected one number (an event-driven scene is not a batch)")
    return float(check(array, name))


def whole_number(value: Any, name: str, minimum: int = 1) -> int:
    """A whole number (not a bool) >= minimum."""
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name}={value!r}: expected a whole number >= {minimum}")
    return int(value)


def run_times(scene_t_end: float, dt: Any, t_end: Any = None) -> tuple[float, float]:
    """(dt, t_end) of a run [s], checked: t_end (default the scene's) > 0 and 0 < dt <= t_end; both
    single finite numbers. Every backend checks its time arguments with this, before any work."""
    t_end = scene_t_end if t_end is None else float(finite_array(t_end, "t_end", ndim=0))
    if not t_end > 0:
        raise ValueError(f"t_end={t_end!r}: must be > 0 [s]")
    dt = float(finite_array(dt, "dt", ndim=0))
    if not 0 < dt <= t_end:
        raise ValueError(f"dt={dt!r}: must satisfy 0 < dt <= t_end={t_end} [s]")
    return dt, t_end


def one_of(value: Any, name: str, choices) -> Any:
    """`value` checked to be one of `choices` (the message lists them)."""
    try:
        found = any(bool(value == choice) for choice in choices)
    except (TypeError, ValueError):  # e.g. an array compared with a string
        found = False
    if not found:
        raise ValueError(f"{name}={value!r}: expected one of {', '.join(map(repr, choices))}")
    return value


def describe_values(array: np.ndarray) -> str:
    """A short text of an array's values for an error message."""
    if array.ndim == 0:
        return repr(float(array))
    if array.size <= 6:
        return repr(array.tolist())
    return f"array of shape {array.shape} containing {array.ravel()[:3].tolist()}..."


def scene_arguments(gravity: Any, t_end: Any = None) -> None:
    """The arguments every scene factory shares, checked before the scene is built: gravity one number >= 0
    [m/s^2]; t_end (None: the scene's own) one number > 0 [s]."""
    single_number(gravity, "gravity", nonnegative)
    if t_end is not None:
        single_number(t_end, "t_end", positive)


# A batch larger than this is checked on its model arrays only (evaluating the exact solution of every
# element would cost more than building the scene).
REPRESENTABLE_EXACT_BATCH = 1000


def representable(scene, *, exact: bool = True):
    """`scene`, checked that float64 can carry it: its native model's arrays and (continuous scenes, batches up
    to REPRESENTABLE_EXACT_BATCH elements, unless exact=False: a line of balls replays its impacts in rationals)
    its exact solution at t = 0 and t = t_end are finite. ValueError naming the scene
    and its parameters otherwise (a parameter too large or too small for float64: an overflow to inf, an
    underflow to 0 that divides). Observables that mean "not yet" (an arrival time) may be NaN."""
    size = int(np.prod(scene.batch_shape)) if scene.batch_shape else 1
    refuse_batch_memory(scene)
    with np.errstate(all="ignore"):
        problem = None
        if not scene.event_driven:
            model = scene.native_model
            for label, values in (("initial state", model.y0), ("model parameters", model.params)):
                if not np.all(np.isfinite(values)):
                    problem = f"its {label} are not finite ({describe_values(np.asarray(values, dtype=float))})"
        if problem is None and exact and size <= REPRESENTABLE_EXACT_BATCH:
            exact = {}
            for times in ([0.0, float(scene.t_end)], [0.0]):  # exact() may hold only up to some time
                try:
                    exact = scene.exact(np.array(times))
                    break
                except (NotImplementedError, ValueError):
                    continue
            for name, values in exact.items():
                values = np.asarray(values)
                if "arrival" in name or values.dtype.kind not in "fc":
                    continue
                if not np.all(np.isfinite(values)):
                    problem = f"its exact {name} at t = 0 or t_end = {float(scene.t_end):.6g} s is not finite"
                    break
    if problem is not None:
        raise ValueError(f"scene {scene.describe()}: {problem}; a parameter is too large or too small for "
                         "float64 arithmetic (an overflow to inf or an underflow to 0): give it in other units "
                         "or nearer the scene's scale")
    return scene


# A batch larger than this is checked against the memory before its native model is built.
BATCH_MEMORY_CHECKED_ABOVE = 2**16
# Building a batch's native model holds up to ~2.4 x its arrays y0 and params at once (broadcast copies,
# concatenations; measured with tracemalloc on the rod, chain, rocket and two-body factories): 3 x is the estimate.
BATCH_BUILD_FACTOR = 3.0


def refuse_batch_memory(scene) -> None:
    """ValueError, before a batched scene's native model is built, when its arrays (y0 and params for every batch
    element, BATCH_BUILD_FACTOR x as built) would not fit in the memory this process can still allocate
    (rbody.resources). The sizes of one element come from the scene's first element, built alone."""
    if scene.event_driven or not scene.batch_shape:
        return
    size = float(np.prod([float(n) for n in scene.batch_shape]))
    if size <= BATCH_MEMORY_CHECKED_ABOVE or "native_model" in scene.__dict__:
        return
    from rbody.resources import memory_problem

    try:
        one = scene.item((0,) * len(scene.batch_shape)).native_model
    except NotImplementedError:
        return
    numbers = one.y0.shape[1] + one.params.shape[1]
    problem = memory_problem(BATCH_BUILD_FACTOR * 8.0 * size * numbers,
                             f"scene {scene.name!r}: a batch of {size:.3g} elements ({scene.batch_shape}), "
                             f"{numbers} numbers of state and parameters each,")
    if problem:
        raise ValueError(f"{problem}; refused before building it: split the batch")
