"""The runner: a NativeModel integrated by a method's compiled loop, the step that fails explained.

Below simulate (rbody.simulation), which chooses the method and checks the run, and below the Dask worker
(rbody.engine.distributed), which runs rows of the same model: both call integrate_model, so a batch cut into
tasks gives the serial run's bits. Everything here reads the NativeModel only, never the scene that made it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rbody.engine.methods import RECORDS, Method, method as method_record
from rbody.engine.native import NativeModel
from rbody.errors import SimulationError


def failure(description: str, model: NativeModel, record: Method, dt: float, save_every: int, out: np.ndarray,
            failed: np.ndarray) -> SimulationError:
    """The SimulationError of a run whose element failed: the scene, method, dt, time, batch element, and what the
    model diagnoses at the last finite state before the failure (a tree: the body and joint whose mass matrix
    became singular)."""
    b = int(np.argmax(failed >= 0))
    step = int(failed[b])
    cause = ""
    if model.diagnose is not None and model.break_time is None and step >= 1:
        last = _last_finite_state(model, record, dt, save_every, out, b, step)
        if last is not None:
            cause = model.diagnose(last, np.asarray(model.y0)[b], dt)
    higher = [m.name for m in RECORDS if m.order is not None and m.order >= 4 and m.applies(model)]
    advice = "a smaller dt" + ("" if record.name in higher or not higher else
                               f" or a method of higher order ({', '.join(higher)})")
    where = f" at t={step * dt:.6g} s (batch element {b} of {failed.size})"
    if cause:
        return SimulationError(f"scene {description}: method {record.name!r} with dt={dt} failed{where}: {cause}")
    return SimulationError(f"scene {description}: method {record.name!r} with dt={dt} gave {record.failure}"
                           f"{where}; try {advice}")


def _last_finite_state(model, record: Method, dt: float, save_every: int, out: np.ndarray, b: int,
                       step: int) -> np.ndarray | None:
    """(n,) state of element b at step `step` - 1, the last before its failure: from the saved samples, re-run
    from the last one before it (at most save_every - 1 steps, element b alone)."""
    saved = (step - 1) // save_every
    start = out[saved, b]
    if not np.all(np.isfinite(start)):
        return None
    remaining = step - 1 - saved * save_every
    if remaining == 0:
        return start.copy()
    one = dataclasses.replace(model, y0=start[None, :], params=np.asarray(model.params)[b:b + 1])
    buffer = np.empty((remaining + 1, 1, start.size))
    record.integrate(one, one.y0, np.ascontiguousarray(one.params, dtype=np.float64), dt, remaining, 1, buffer)
    return buffer[-1, 0] if np.all(np.isfinite(buffer[-1, 0])) else None


def step_count(t_end: float, dt: float, save_every: int) -> int:
    """Number of steps: t_end/dt rounded up (to round-off), then up to a multiple of save_every."""
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    return -(-nsteps // save_every) * save_every


def crosses_break(model, nsteps: int, dt: float) -> bool:
    """Whether a run of nsteps steps of dt passes model.break_time (then the straddling step is cut there)."""
    return model.break_time is not None and 0 < model.break_time < nsteps * dt


def integrate_model(model, method: Method | str, dt: float, nsteps: int, save_every: int,
                    out: np.ndarray) -> np.ndarray:
    """The compiled run of `model` (a whole batch or some of its rows): cut at its break time where the run
    crosses it, else in one loop. method: its record or name. out (nsteps // save_every + 1, B, n) filled;
    returns failed (B,)."""
    method = method_record(method) if isinstance(method, str) else method
    if crosses_break(model, nsteps, dt):
        return _integrate_across_break(model, method, dt, nsteps, save_every, out)
    return _integrate(model, method, dt, nsteps, save_every, out)


def _integrate_across_break(model, method: Method, dt: float, nsteps: int, save_every: int,
                            out: np.ndarray) -> np.ndarray:
    """The run on the same grid, with the step that straddles model.break_time t_b split there:
    n_b = floor(t_b/dt) steps on the first side, then h1 = t_b - n_b dt on the first side and dt - h1
    on the second, then the rest on the second side; rhs is told its side through break_column, so
    no stage ever evaluates across the jump and each method keeps its order."""
    every = np.empty((nsteps + 1,) + model.y0.shape)
    before, after = np.array(model.params, dtype=np.float64), np.array(model.params, dtype=np.float64)
    before[:, model.break_column], after[:, model.break_column] = 1.0, 0.0
    n_b = int(np.floor(model.break_time / dt))
    h1 = model.break_time - n_b * dt
    every[0] = model.y0
    failed = np.full(model.y0.shape[0], -1, dtype=np.int64)

    def leg(params, start, steps, h, into):
        """`steps` steps of h from `start` (B, n), states written to into[1:]; returns the end state."""
        buffer = np.empty((steps + 1,) + model.y0.shape)
        bad = _integrate(dataclasses.replace(model, y0=start, params=params), method, h, steps, 1, buffer)
        failed[(failed < 0) & (bad >= 0)] = n_b  # the step near which it failed (for the message)
        if into is not None:
            into[:] = buffer[1:]
        return buffer[-1]

    state = every[0]
    if n_b > 0:
        state = leg(before, state, n_b, dt, every[1:n_b + 1])
    if h1 > 0:  # the straddling step, cut at the break
        state = leg(before, state, 1, h1, None)
        state = leg(after, state, 1, dt - h1, every[n_b + 1:n_b + 2])
        n_done = n_b + 1
    else:
        n_done = n_b
    if nsteps > n_done:
        leg(after, every[n_done], nsteps - n_done, dt, every[n_done + 1:])
    out[:] = every[::save_every]
    return failed


def _integrate(model, method: Method | str, dt: float, nsteps: int, save_every: int, out: np.ndarray) -> np.ndarray:
    """The method's compiled loop on the whole of `model` (its record, or name, says how: rbody.engine.methods)."""
    method = method_record(method) if isinstance(method, str) else method
    y0, p = np.ascontiguousarray(model.y0, dtype=np.float64), np.ascontiguousarray(model.params, dtype=np.float64)
    return method.integrate(model, y0, p, dt, nsteps, save_every, out)


# Methods whose step carries nothing from one step to the next but the state (euler, symplectic_euler, verlet and
# its compositions, rk4, a scene's splitting): a run cut into segments, each started from the last saved state,
# gives the one-loop run's bits. gauss6 starts each step's iteration from the last steps' slopes, and the
# reference solver chooses its own steps, so neither is cut.
NOT_SEGMENTED = ("gauss6", "reference")


def segmentable(model, method: Method | str, nsteps: int, dt: float) -> bool:
    """Whether a run of `method` on `model` may be cut into segments (integrate_segment) with the same bits."""
    name = method if isinstance(method, str) else method.name
    return name not in NOT_SEGMENTED and not crosses_break(model, nsteps, dt)


def integrate_segment(model, method: Method | str, dt: float, start: int, samples: int, save_every: int,
                      out: np.ndarray) -> np.ndarray:
    """Samples start+1 .. start+samples of a run (samples x save_every steps) from the saved state out[start]:
    out[start:start + samples + 1] filled, as the whole run's loop fills them (segmentable methods only).
    Returns failed (B,): each element's first non-finite step counted from the start of the whole run, or -1."""
    method = method_record(method) if isinstance(method, str) else method
    piece = dataclasses.replace(model, y0=out[start])
    failed = _integrate(piece, method, dt, samples * save_every, save_every, out[start:start + samples + 1])
    return np.where(failed >= 0, failed + start * save_every, failed)
