"""The control input of a run: simulate(scene, ..., ctrl=...) for a scene with actuators (rbody.layout.Actuator).

A control is held through a whole step, as in MuJoCo (every stage of rk4 and gauss6 sees the same value), so that
rbody's rk4 and MuJoCo's RK4 under the same control sequence agree to round-off. ctrl may be

- None: the scene's ctrl0 (a keyframe's ctrl, else 0), held through the run;
- a constant (nu,), or one per batch element (*batch, nu): written once into every params row (the compiled
  loops then run exactly as without controls);
- a schedule (n_steps, nu) or (n_steps, *batch, nu) (any leading batch axes that broadcast), row k held during
  step k (at least as many rows as the run has steps; rows beyond it are unused): appended to every params row,
  the state y gains one entry, the number of steps taken, and after every whole step the loops' finish hook
  writes the next row into the controls (rbody.engine.system.next_control) — still one compiled loop;
- a callable ctrl(t, qpos, qvel) -> (nu,) or (*batch, nu), called at the start of every step with the time t [s]
  and the state, qpos (*batch, nq), qvel (*batch, nv): the run goes one step per compiled call, so it costs one
  Python call (and one loop launch, ~10 us) per step.

A (*batch, nu) array is always one constant per batch element (a schedule for a batch of as many elements as
steps must be given in full, (n_steps, *batch, nu)). The run's dt is written into every row as well: actearly's
next activation and MuJoCo's exact filter read it. The observables ctrl and actuator_force are formed with the
controls actually held (rbody.scene.TreeScene).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from rbody.engine.native import NativeModel
from rbody.engine.runner import integrate_model


@dataclass
class ControlPlan:
    """How a run applies its controls: `model` with them written in; `stepwise` the callable (or schedule) to call
    once per step, or None for one compiled loop; `samples(save_every, count)` the controls (T, B, nu) held at the
    saved states, known once the run is over."""

    model: NativeModel
    stepwise: Callable[[int, float, np.ndarray], np.ndarray] | None
    history: np.ndarray | None          # (n_steps, B, nu) the controls of every step (schedule or recorded)
    constant: np.ndarray | None         # (B, nu) the controls of a constant run
    scheduled: bool = False             # stepwise reads a given schedule (history), rather than calling the user

    def samples(self, save_every: int, count: int) -> np.ndarray:
        """(count, B, nu): the control held through the step that starts at each saved time (the last: the last
        step's)."""
        if self.history is None:
            return np.broadcast_to(self.constant[None], (count,) + self.constant.shape)
        steps = np.minimum(np.arange(count) * save_every, self.history.shape[0] - 1)
        return self.history[steps]


def plan(scene, model: NativeModel, ctrl: Any, dt: float, nsteps: int, method: str) -> ControlPlan:
    """The ControlPlan of a run of `scene` (its native `model`) with `ctrl` (module docstring), nsteps steps of dt
    [s] by `method`; ValueError, naming the shape or the value, for a control the scene cannot take."""
    slots = model.controls
    if slots is None:
        if ctrl is not None:
            raise ValueError(f"ctrl given, but scene {scene.describe()} has no actuators (nu = 0): leave ctrl out")
        return ControlPlan(model, None, None, None)
    batch_shape = tuple(scene.batch_shape)
    batch = model.y0.shape[0]
    nu = slots.nu
    params = np.array(model.params, dtype=np.float64)  # the run's own rows: the scene's model is never changed
    params[:, slots.step] = dt
    if ctrl is None:
        constant = params[:, slots.ctrl:slots.ctrl + nu].copy()
        return ControlPlan(dataclasses.replace(model, params=params), None, None, constant)
    if callable(ctrl):
        if model.constraints is not None and batch > 1:
            raise ValueError(f"ctrl is a callable, and scene {scene.describe()} is a batch of {batch} constrained "
                             "trees, which the constraint layer runs one element at a time: give the controls as a "
                             "schedule (n_steps, *batch, nu), or run the elements one by one")
        function = _checked_callable(ctrl, scene, batch_shape, nu)
        return ControlPlan(dataclasses.replace(model, params=params), function, np.empty((nsteps, batch, nu)), None)
    array = np.asarray(ctrl, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != nu:
        raise ValueError(f"ctrl has shape {array.shape}: expected (nu,) = ({nu},), (*batch, nu), (n_steps, nu) or "
                         f"(n_steps, *batch, nu) for scene {scene.describe()} (batch {batch_shape}, {nsteps} steps), "
                         "or a callable ctrl(t, qpos, qvel)")
    if not np.all(np.isfinite(array)):
        raise ValueError("ctrl holds NaN or inf: expected finite controls")
    if array.shape == (nu,) or (batch_shape and array.shape == batch_shape + (nu,)):
        constant = np.ascontiguousarray(np.broadcast_to(array, batch_shape + (nu,)).reshape(batch, nu))
        params[:, slots.ctrl:slots.ctrl + nu] = constant
        return ControlPlan(dataclasses.replace(model, params=params), None, None, constant)
    if array.ndim not in (2, 2 + len(batch_shape)):
        raise ValueError(f"ctrl has shape {array.shape}: a schedule is (n_steps, nu) or (n_steps, *batch, nu) with "
                         f"batch {batch_shape}")
    if array.shape[0] < nsteps:
        raise ValueError(f"ctrl has {array.shape[0]} rows: the run takes {nsteps} steps (row k is held during step k); "
                         "give at least one row per step")
    try:
        history = np.broadcast_to(array[:nsteps].reshape((nsteps,) + (1,) * (len(batch_shape) + 2 - array.ndim)
                                                         + array.shape[1:]),
                                  (nsteps,) + batch_shape + (nu,)).reshape(nsteps, batch, nu)
    except ValueError:
        raise ValueError(f"ctrl has shape {array.shape}: its batch axes {array.shape[1:-1]} do not broadcast to the "
                         f"scene's batch {batch_shape}") from None
    history = np.ascontiguousarray(history)
    if method == "reference" or model.constraints is not None:  # DOP853 between samples, or the constraint
        # layer's own runs (rbody.engine.constraints.runner): the schedule's row written in before each step
        return ControlPlan(dataclasses.replace(model, params=params), lambda k, t, y: history[k], history, None,
                           scheduled=True)
    width = params.shape[1]
    rows = np.empty((batch, width + nsteps * nu))
    rows[:, :width] = params
    rows[:, width:] = history.transpose(1, 0, 2).reshape(batch, nsteps * nu)
    rows[:, slots.schedule], rows[:, slots.rows] = width, nsteps
    rows[:, slots.ctrl:slots.ctrl + nu] = history[0]
    y0 = np.concatenate([model.y0, np.zeros((batch, 1))], axis=1)  # the steps taken
    scheduled = dataclasses.replace(model, y0=y0, params=rows)
    return ControlPlan(scheduled, None, history, None)


def _checked_callable(function, scene, batch_shape: tuple, nu: int):
    """control(k, t, y) -> (B, nu) from the user's ctrl(t, qpos, qvel), its result checked."""
    model = scene.multibody
    nq, nv = model.nq, model.nv
    batch = int(np.prod(batch_shape)) if batch_shape else 1

    def control(k: int, t: float, y: np.ndarray) -> np.ndarray:
        qpos = y[:, :nq].reshape(batch_shape + (nq,)).copy()
        qvel = y[:, nq:nq + nv].reshape(batch_shape + (nv,)).copy()
        value = np.asarray(function(t, qpos, qvel), dtype=np.float64)
        if value.shape != (nu,) and value.shape != batch_shape + (nu,):
            raise ValueError(f"ctrl(t={t:.6g}, qpos, qvel) returned shape {value.shape} at step {k}: expected ({nu},) "
                             f"or {batch_shape + (nu,)}")
        if not np.all(np.isfinite(value)):
            raise ValueError(f"ctrl(t={t:.6g}, qpos, qvel) returned NaN or inf at step {k}: expected finite controls")
        return np.broadcast_to(value, batch_shape + (nu,)).reshape(batch, nu)
    return control


def run_stepwise(plan_: ControlPlan, record, dt: float, nsteps: int, save_every: int, out: np.ndarray) -> np.ndarray:
    """The run of a plan with a per-step control: for each step k, the control of step k written into every row,
    then one step of the method's compiled loop. out (nsteps // save_every + 1, B, n) filled; returns failed (B,).
    An element that fails is frozen at its last finite state (the others go on)."""
    model = plan_.model
    slots = model.controls
    params = np.array(model.params, dtype=np.float64)
    y = np.array(model.y0, dtype=np.float64)
    batch = y.shape[0]
    failed = np.full(batch, -1, dtype=np.int64)
    out[0] = y
    buffer = np.empty((2,) + y.shape)
    for k in range(nsteps):
        value = plan_.stepwise(k, k * dt, y)
        plan_.history[k] = value
        params[:, slots.ctrl:slots.ctrl + slots.nu] = value
        bad = integrate_model(dataclasses.replace(model, y0=y, params=params), record, dt, 1, 1, buffer)
        fresh = (bad >= 0) & (failed < 0)
        failed[fresh] = k + 1
        alive = failed < 0
        y[alive] = buffer[1][alive]
        if (k + 1) % save_every == 0:
            out[(k + 1) // save_every] = y
        if not np.any(alive):
            break
    return failed


def step_controls(plan_: ControlPlan):
    """For a constrained tree's run (rbody.engine.constraints.runner, one batch element at a time): None when the
    plan's controls are in its rows already (none or a constant), else (at, control) with `at` the controls' offset in
    the params row and control(k, b, t, y (n,)) -> (nu,) the control of element b held during step k, recorded in
    the plan's history for the observables."""
    if plan_.stepwise is None:
        return None
    slots = plan_.model.controls

    def control(k: int, b: int, t: float, y: np.ndarray) -> np.ndarray:
        if plan_.scheduled:  # a schedule: its row for step k and element b
            return plan_.history[k, b]
        value = plan_.stepwise(k, t, np.asarray(y)[None])[0]
        plan_.history[k, b] = value
        return value
    return slots.ctrl, control


def observing(plan_: ControlPlan, save_every: int, count: int, dt: float) -> NativeModel:
    """The plan's model whose observe forms the observables with the controls held at the `count` saved states."""
    if plan_.model.controls is None:
        return plan_.model
    model = plan_.model
    observe = model.observe
    samples = plan_.samples(save_every, count)

    def observe_with_controls(t, y):
        return observe(t, y, samples, dt)
    return dataclasses.replace(model, observe=observe_with_controls)


__all__ = ["ControlPlan", "plan", "run_stepwise", "observing", "step_controls"]
