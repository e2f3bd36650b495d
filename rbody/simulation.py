"""simulate(scene, dt, method): the native run, in the fewest coordinates of each scene.

The pipeline of a time-stepped run, as a short list of calls:

    model = scene.native_model                # minimal coordinates, compiled rhs/accel, batch of states
    out   = _integrate(model, method, ...)    # the compiled loop of the method
    data  = model.observe(t, out)             # observables, (T, *batch, ...)

Event-driven scenes (impacts) are run event by event instead (scene.run_events): the time step
only sets where the trajectory is sampled.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from typing import Any

import numpy as np

from rbody import control
from rbody import progress as progress_lines
from rbody.checks import run_times, whole_number
from rbody.engine.accuracy import accuracy_problem
from rbody.engine.distributed import PREPARED_KEY, integrate_on_cluster
from rbody.engine.methods import BY_NAME, Method, method as method_record
from rbody.engine.runner import (crosses_break, failure, integrate_model, integrate_segment, segmentable,
                                 step_count)
from rbody.engine.stability import (DENSE_STATE_LIMIT, JACOBIAN_BLOCK, KRYLOV_VECTORS, check_state, check_step,
                                    fastest_rate)
from rbody.errors import AccuracyWarning, MethodNotApplicable, SimulationError
from rbody.resources import MEMORY_FRACTION, available_memory
from rbody.scene import Scene
from rbody.trajectory import Trajectory

EVENT_METHOD = "events"


def simulate(scene: Scene, *, dt: float, method: str | None = None, t_end: float | None = None,
             save_every: int = 1, allow_large: bool = False, client: Any = None,
             chunk: int | None = None, progress: bool | None = None, error_estimate: bool = False,
             ctrl: Any = None) -> Trajectory:
    """Run `scene` natively.

    dt:         time step [s] (event-driven scenes: the sampling interval of the trajectory only)
    method:     one of rbody.METHODS; default "verlet" where it applies, else the scene's first
                method; "events" (the only choice) for event-driven scenes
    t_end:      duration [s], default scene.t_end
    save_every: keep every n-th step (1 <= n <= ceil(t_end/dt)); the run takes ceil(t_end/dt) steps
                rounded up to a multiple of save_every, so the last saved time is t_end or up to
                save_every dt past it
    allow_large: run even when the work estimated before the run (estimate_work: steps, saved
                samples, the memory at the peak, impacts) is beyond its limits; without it such a run is refused
                with a ValueError giving the estimate
    client:     a dask.distributed.Client: the batch's rows run as tasks on its cluster, `chunk` rows each
                (default: about 4 tasks per worker thread, at least a few thousand rows; see
                rbody.engine.distributed); the result equals the serial run's bit for bit. Event-driven
                scenes and constrained trees (limits, dry friction, equalities: rbody.engine.constraints) run
                here. None (default): everything runs here and Dask is not imported.
    progress:   a line on stderr with the share done and the time left (rbody.progress): True always, False
                never, None (default) in an interactive session (a terminal, not pytest, not CI) when the run
                proves longer than a few seconds (PROGRESS_AFTER_SECONDS, timed on its first steps). The run is
                then stepped in segments, each from the last saved state, with the bits of one loop (gauss6 and
                the reference solver, which carry more than the state between steps, run in one loop: no line);
                a run on a Dask client shows none.
    error_estimate: also run at dt/2 (step doubling) and put in trajectory.meta["error_estimate"] each observable's
                estimated largest error over the run, max |y(dt) - y(dt/2)| 2^p / (2^p - 1) for a method of order
                p (Richardson), with meta["error_estimate_how"] saying so; costs a second run of twice the steps.
    Warns (rbody.errors.AccuracyWarning), before any step, when dt times the scene's fastest rate w is beyond the
    method's accuracy threshold (rbody.engine.accuracy: one period of that mode carried with more than 1 % error).
    ctrl:       the controls of a scene with actuators (rbody.control): None (the scene's ctrl0), a constant
                (nu,) or (*batch, nu), a schedule (n_steps, [*batch,] nu) whose row k is held during step k, or
                a callable ctrl(t, qpos, qvel) -> (nu,) called at the start of every step (one Python call per
                step). A control is held through a whole step, as in MuJoCo. A constrained tree (limits, dry
                friction, equalities) takes it too (rbody.engine.constraints). Not with client= (a given control
                runs in this process).
    Returns a Trajectory whose observables have shape (T, *scene.batch_shape, ...).
    Raises ValueError for bad arguments, a run too large to start (above), a closed client or a chunk
    without a client; MethodNotApplicable when the method cannot run the scene; SimulationError, before
    any step, when dt is beyond the method's estimated stability limit on the scene (rbody.engine.stability)
    or the model cannot be carried by float64 over the run (a tree's precision_problem: hinge angles too large to
    carry a step), and, after, when a step gives a
    non-finite state (never a trajectory holding NaN, except where an observable means "not yet": a race's
    arrival time), or when a task lost its worker more often than Dask retries it.

    Without a client this is prepare(scene, ...).run(progress=...): the checks, the model and the bound loop are
    made on the first call with these arguments and kept with the scene, so a repeated call costs the run alone.
    """
    if not isinstance(error_estimate, bool):
        raise ValueError(f"error_estimate={error_estimate!r}: expected True or False")
    show = progress_lines.wanted(progress)  # ValueError for anything but True, False, None
    if chunk is not None and client is None:
        raise ValueError(f"chunk={chunk!r}: rows per task of a Dask client; give client= too, or leave chunk out")
    prepared = _prepare(scene, dt, method, t_end, save_every, allow_large)
    if error_estimate and prepared.record is not None:  # the second run at dt/2, held beside the first
        refuse_large(combined_work(prepared.work, estimate_work(scene, prepared.dt / 2, prepared.t_end,
                                                                2 * prepared.save_every)), allow_large)
    if client is not None and ctrl is not None:
        raise ValueError("ctrl with client=: a run with a given control goes in this process (the cluster's tasks "
                         "rebuild the scene's own model); leave client out")
    prepared.warn(stacklevel=3)
    trajectory = (prepared.run(progress=show, ctrl=ctrl) if client is None
                  else prepared.run_on_cluster(client, chunk))
    if error_estimate:
        if prepared.record is None:
            trajectory.meta["error_estimate_how"] = ("none: an event-driven scene's impacts are found exactly; dt only "
                                                     "samples the trajectory")
        else:
            _estimate_error(scene, prepared.record, trajectory, prepared.dt, prepared.t_end, prepared.save_every,
                            client, chunk, progress, ctrl)
    return trajectory


def prepare(scene: Scene, *, dt: float, method: str | None = None, t_end: float | None = None,
            save_every: int = 1, allow_large: bool = False, ctrl: Any = None) -> "PreparedRun":
    """Everything of a run that depends only on (scene, dt, method, t_end, save_every), done once: the arguments
    checked, the method chosen, the work estimated and refused if too large, the precision, stability and
    resolution checks, the native model built and the method's compiled loop bound to it. Arguments, warnings and
    errors as simulate's.

    The result is kept with the scene (a frozen scene never changes), so prepare, and simulate, called again
    with the same arguments return it at once. PreparedRun.run() then costs what the integration costs.
    ctrl: the controls its runs hold by default (simulate's ctrl=; checked here), which PreparedRun.run(ctrl=...)
    may replace run by run; the kept run is shared, so a ctrl given here goes with the returned object only.
    """
    prepared = _prepare(scene, dt, method, t_end, save_every, allow_large)
    prepared.warn(stacklevel=3)
    return prepared if ctrl is None else prepared.with_controls(ctrl)


def _prepare(scene: Scene, dt, method, t_end, save_every, allow_large) -> "PreparedRun":
    """The PreparedRun of these arguments, kept in the scene's __dict__ under PREPARED_KEY (made on first use)."""
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    key = (dt, method, t_end, save_every, allow_large)
    kept = scene.__dict__.setdefault(PREPARED_KEY, {})  # frozen: no setattr, but __dict__ is writable
    try:
        found = kept.get(key)
    except TypeError:  # an unhashable argument (an array): checked, and refused, below
        key, found = None, None
    if found is not None and all(type(a) is type(b) for a, b in zip(key, found.arguments)):
        return found
    prepared = PreparedRun(scene, dt=dt, method=method, t_end=t_end, save_every=save_every, allow_large=allow_large)
    if key is not None:
        kept[key] = prepared
    return prepared


class PreparedRun:
    """A run of one scene with (dt, method, t_end, save_every) fixed and checked (rbody.prepare).

    run(qpos0=None, qvel0=None, ctrl=None) -> Trajectory: the scene from its own initial state, or (trees) from
    qpos0 (*batch, nq) and qvel0 (*batch, nv) of the scene's batch shape, which are checked as the scene checks its
    own (shapes, finite numbers, unit quaternions) and for the stability of the step at that state; ctrl: the
    controls of a tree with actuators (simulate's ctrl=, rbody.control), default the prepared run's own (`ctrl`,
    given to prepare) or else the scene's ctrl0.
    Attributes: scene, method (its name), dt [s], t_end [s], save_every, nsteps, t (T,) [s] the saved times, ctrl.
    """

    ctrl: Any = None

    def __init__(self, scene: Scene, *, dt: float, method: str | None, t_end: float | None, save_every: int,
                 allow_large: bool) -> None:
        self.arguments = (dt, method, t_end, save_every, allow_large)
        self.dt, self.t_end = run_times(scene.t_end, dt, t_end)
        self.save_every = whole_number(save_every, "save_every")
        self.scene = scene
        self.record = _choose_method(scene, method)
        self.method = self.record.name if self.record is not None else EVENT_METHOD
        self.work = estimate_work(scene, self.dt, self.t_end, self.save_every)
        self.allow_large = allow_large
        refuse_large(self.work, allow_large)
        self.accuracy = None  # why dt resolves the fastest mode poorly (warned by simulate and prepare), or None
        if scene.event_driven:
            return
        _check_precision(scene, self.dt, self.t_end)  # before the stability check: a model float64 cannot carry
        check_step(scene, self.method, self.dt, self.t_end)  # beyond the method's stability limit: refuse now
        self.accuracy = accuracy_problem(self.method, self.dt, float(np.max(fastest_rate(scene, self.method))))
        # built once per scene (a planar tree run by MuJoCo's integrators: the 3-D engine's rows)
        self.model = model = getattr(scene, "native_model_for", lambda _method: scene.native_model)(self.method)
        self.nsteps = step_count(self.t_end, self.dt, self.save_every)
        if model.break_time is not None and 0 < model.break_time < self.dt:
            raise SimulationError(
                f"scene {scene.describe()}: its right-hand side jumps at t = {model.break_time:.6g} s (e.g. a "
                f"rocket's burn-out), inside the first step dt={self.dt}: the whole phase before it would be one step "
                f"of {model.break_time:.3g} s, integrated with no step inside it; use dt <= "
                f"{model.break_time / 10:.3g} s (ten steps or more before the jump)")
        self.y0 = np.array(model.y0, dtype=np.float64, order="C")         # the loops' own writable copies
        # a tree with actuators: the run's step and the scene's ctrl0 written into every row (rbody.control)
        self._plan = control.plan(scene, model, None, self.dt, self.nsteps, self.method)
        self.params = np.array(self._plan.model.params, dtype=np.float64, order="C")
        self.t = np.arange(self.nsteps // self.save_every + 1) * (self.dt * self.save_every)
        self.t.setflags(write=False)
        self.leading = (self.t.size,) + scene.batch_shape
        self.meta = {"scene": scene.name, "backend": "rbody", "method": self.method, "dt": self.dt}
        # limits, dry friction, equalities: the constraint layer's own schemes (rbody.engine.constraints), no loop
        self.constrained = model.constraints is not None
        self._runner = (None if self.constrained or crosses_break(model, self.nsteps, self.dt)
                        else self.record.bound(model, self.y0.shape[0], self.dt, self.nsteps, self.save_every))

    def warn(self, stacklevel: int = 2) -> None:
        """An AccuracyWarning when dt times the scene's fastest rate is beyond the method's accuracy threshold."""
        if self.accuracy is not None:
            warnings.warn(AccuracyWarning(f"scene {self.scene.describe()}: method {self.method!r}: {self.accuracy}"),
                          stacklevel=stacklevel)

    def with_controls(self, ctrl: Any) -> "PreparedRun":
        """A copy of this prepared run whose runs hold `ctrl` by default (prepare's ctrl=), checked now."""
        if ctrl is not None:
            if self.scene.event_driven:
                raise ValueError(f"ctrl given, but scene {self.scene.describe()} is event-driven (no actuators)")
            control.plan(self.scene, self.model, ctrl, self.dt, self.nsteps, self.method)  # ValueError: bad ctrl
        copy = object.__new__(PreparedRun)
        copy.__dict__.update(self.__dict__)
        copy.ctrl = ctrl
        return copy

    def run(self, *, qpos0: Any = None, qvel0: Any = None, progress: bool | None = False,
            ctrl: Any = None) -> Trajectory:
        """The run, from the scene's initial state or (trees) from qpos0/qvel0, under the controls ctrl (default:
        the prepared run's own, else the scene's ctrl0); a Trajectory as simulate's.
        progress: as simulate's (rbody.progress); False (default) steps in one loop."""
        show = progress_lines.wanted(progress)
        scene = self.scene
        ctrl = self.ctrl if ctrl is None else ctrl
        if scene.event_driven:
            if ctrl is not None:
                raise ValueError(f"ctrl given, but scene {scene.describe()} is event-driven (no actuators)")
            if qpos0 is not None or qvel0 is not None:
                raise ValueError(f"scene {scene.name!r} is event-driven: it starts from its own state (qpos0 and "
                                 "qvel0 are for trees of bodies and joints)")
            if self.work["bytes"] > MEMORY_CHECKED_ABOVE:
                refuse_large(self.work, self.allow_large)
            return scene.run_events(self.t_end, self.dt * self.save_every)
        y0 = self.y0 if qpos0 is None and qvel0 is None else self._start(qpos0, qvel0)
        if self.work["bytes"] > MEMORY_CHECKED_ABOVE:  # the memory available may have changed since prepare
            refuse_large(self.work, self.allow_large)
        model = self.model if y0 is self.y0 else dataclasses.replace(self.model, y0=y0)
        if ctrl is None:  # the scene's own controls (ctrl0), written in once (self.params)
            plan = self._plan if y0 is self.y0 else dataclasses.replace(
                self._plan, model=dataclasses.replace(self._plan.model, y0=y0))
        else:
            plan = control.plan(scene, model, ctrl, self.dt, self.nsteps, self.method)
        if self.constrained:
            return self._constrained_run(plan)
        model = plan.model
        out = np.empty((self.t.size,) + model.y0.shape)
        if plan.stepwise is not None:  # a callable control: one compiled step per call
            failed = control.run_stepwise(plan, self.record, self.dt, self.nsteps, self.save_every, out)
        elif show is not False and segmentable(model, self.record, self.nsteps, self.dt):
            failed = _integrate_showing_progress(scene, model, self.record, self.dt, self.nsteps, self.save_every,
                                                 out, show)
        elif self._runner is None or plan.history is not None:  # a break in the rhs, or a schedule's wider rows
            failed = integrate_model(model, self.record, self.dt, self.nsteps, self.save_every, out)
        else:
            failed = self._runner(model.y0, model.params if ctrl is not None else self.params, out)
        return self._trajectory(plan, out, failed)

    def run_on_cluster(self, client: Any, chunk: int | None = None) -> Trajectory:
        """The batch's rows as tasks on the Dask cluster of `client` (simulate's client=, chunk=); event-driven and
        constrained scenes run here."""
        if self.scene.event_driven or self.constrained:
            return self.run()
        if self.ctrl is not None:
            raise ValueError("ctrl with client=: a run with a given control goes in this process (the cluster's tasks "
                             "rebuild the scene's own model); leave client out")
        out = np.empty((self.t.size,) + self.y0.shape)
        failed = integrate_on_cluster(client, self.scene, self._plan.model, self.method, self.dt, self.nsteps,
                                      self.save_every, out, chunk)
        return self._trajectory(self._plan, out, failed)

    def _start(self, qpos0: Any, qvel0: Any) -> np.ndarray:
        """y0 (B, n) of a tree from qpos0 and qvel0 (the scene's own where one is None), checked; SimulationError
        when the step is beyond the stability limit at that state."""
        start = getattr(self.scene, "native_start", None)
        if start is None:
            raise ValueError(f"scene {self.scene.describe()}: qpos0 and qvel0 are for trees of bodies and joints "
                             "(Scene.from_layout, from_mjcf); a family scene takes its initial state as parameters")
        y0 = np.array(start(qpos0, qvel0, method=self.method), dtype=np.float64, order="C")
        if y0.shape != self.y0.shape:
            raise ValueError(f"qpos0/qvel0 give a batch of {y0.shape[0]} states: this run was prepared for "
                             f"{self.y0.shape[0]} (the scene's batch shape {self.scene.batch_shape}); prepare the "
                             "scene with that batch")
        model = dataclasses.replace(self.model, y0=y0)
        rates_for = getattr(self.scene, "rates_for", None)
        if rates_for is not None and self.model.rate is not None:  # the rates at the state given, not the scene's
            model = dataclasses.replace(model, rate=rates_for(model))
        check_state(model, self.scene.describe(), self.method, self.dt, self.t_end)
        return y0

    def _constrained_run(self, plan: "control.ControlPlan") -> Trajectory:
        """A constrained tree's run: events located exactly between smooth steps (rk4), or Moreau-Jean
        time-stepping (moreau), by rbody.engine.constraints.runner, under the plan's controls (a schedule or a
        callable: written into the row before each step)."""
        from rbody.engine.constraints.runner import run_constrained

        def observe(t, y):  # the controls held, known once the run is over
            return control.observing(plan, self.save_every, t.size, self.dt).observe(t, y)

        t, data, events, meta = run_constrained(self.scene.describe(), plan.model, self.method, self.dt, self.nsteps,
                                                self.save_every, controls=control.step_controls(plan), observe=observe)
        data = {name: _shaped(value, (t.size,) + self.scene.batch_shape) for name, value in data.items()}
        return Trajectory(t, data, events=events, meta={**self.meta, **meta})

    def _trajectory(self, plan: "control.ControlPlan", out: np.ndarray, failed: np.ndarray) -> Trajectory:
        model = plan.model
        if (failed[0] >= 0) if failed.size == 1 else (failed.size and failed.max() >= 0):  # one element: no reduction
            raise failure(self.scene.describe(), model, self.record, self.dt, self.save_every, out, failed)
        model = control.observing(plan, self.save_every, out.shape[0], self.dt)  # the controls held, observed
        try:  # every state is finite here; one the observables cannot take (a zero quaternion) is a failure
            if getattr(model.observe, "any_batch", False):
                data = model.observe(self.t, out.reshape(self.leading + out.shape[2:]))
            else:
                data = {name: _shaped(value, self.leading) for name, value in model.observe(self.t, out).items()}
        except (ValueError, FloatingPointError) as error:
            raise SimulationError(f"scene {self.scene.describe()}: method {self.method!r} with dt={self.dt} gave "
                                  f"states whose observables cannot be formed ({error}); try a smaller dt") from None
        return Trajectory(self.t, data, meta=dict(self.meta))

    def __call__(self, *, qpos0: Any = None, qvel0: Any = None, progress: bool | None = False,
                 ctrl: Any = None) -> Trajectory:
        return self.run(qpos0=qpos0, qvel0=qvel0, progress=progress, ctrl=ctrl)

    def __repr__(self) -> str:
        return (f"PreparedRun({self.scene.describe()}, method={self.method!r}, dt={self.dt:g}, t_end={self.t_end:g}, "
                f"save_every={self.save_every})")


# The first segment of a run that may show progress: about this many element-steps (a few ms), timed to estimate the
# whole run; then segments of about SEGMENT_SECONDS each, the line updated between them.
PROBE_ELEMENT_STEPS = 200_000
SEGMENT_SECONDS = 0.5


def _integrate_showing_progress(scene: Scene, model, record: Method, dt: float, nsteps: int, save_every: int,
                                out: np.ndarray, show: bool | None) -> np.ndarray:
    """integrate_model's run, in segments (integrate_segment: the same bits), with a progress line when `show` is
    True, or when None and the first segment predicts more than PROGRESS_AFTER_SECONDS for the whole run."""
    samples = nsteps // save_every
    batch = model.y0.shape[0]
    failed = np.full(batch, -1, dtype=np.int64)
    out[0] = model.y0  # every segment starts from a saved state, the first from the initial one
    done, line = 0, None
    seconds_per_sample = None
    while done < samples:
        if seconds_per_sample is None:
            size = max(1, min(samples, PROBE_ELEMENT_STEPS // max(1, save_every * batch)))
        else:
            size = max(1, min(samples - done, int(SEGMENT_SECONDS / max(seconds_per_sample, 1e-12))))
        size = min(size, samples - done)
        started = time.perf_counter()
        piece = integrate_segment(model, record, dt, done, size, save_every, out)
        seconds_per_sample = (time.perf_counter() - started) / size
        first = (failed < 0) & (piece >= 0)
        failed[first] = piece[first]
        done += size
        if np.all(failed >= 0):
            break
        if line is None and done < samples:
            if show is None and seconds_per_sample * (samples - done) <= progress_lines.PROGRESS_AFTER_SECONDS:
                rest = integrate_segment(model, record, dt, done, samples - done, save_every, out)
                first = (failed < 0) & (rest >= 0)
                failed[first] = rest[first]
                return failed
            line = progress_lines.Progress(f"rbody {record.name} {scene.name}", nsteps * batch, unit="element-steps")
        if line is not None:
            line.update(done * save_every * batch)
    if line is not None:
        line.finish(done * save_every * batch)
    return failed


def _estimate_error(scene: Scene, record: Method, trajectory: Trajectory, dt: float, t_end: float, save_every: int,
                    client, chunk, progress, ctrl=None) -> None:
    """meta["error_estimate"] of `trajectory` by step doubling (simulate's error_estimate), in place."""
    meta = trajectory.meta
    if record.order is None:
        meta["error_estimate_how"] = f"none: {record.name!r} is an adaptive solver held to its own tolerance"
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # said once, for the run itself
        finer = simulate(scene, dt=dt / 2, method=record.name, t_end=t_end, save_every=2 * save_every,
                         allow_large=True, client=client, chunk=chunk, progress=progress,
                         ctrl=_finer_controls(scene, ctrl))
    factor = 2.0**record.order / (2.0**record.order - 1.0)
    estimates = {}
    for name in trajectory.observables:
        coarse, fine = np.asarray(trajectory[name], dtype=float), np.asarray(finer[name], dtype=float)
        if coarse.shape != fine.shape or coarse.dtype.kind != "f":
            continue
        difference = np.abs(coarse - fine)
        if name.endswith("arrival_time") or not np.all(np.isfinite(difference)):
            difference = difference[np.isfinite(difference)]
        estimates[name] = float(np.max(difference) * factor) if difference.size else 0.0
    meta["error_estimate"] = estimates
    meta["error_estimate_how"] = (f"step doubling: the run repeated at dt/2 = {dt / 2:g} s; for each observable the "
                                  f"largest |y(dt) - y(dt/2)| over the samples and the batch, times 2^p/(2^p - 1) = "
                                  f"{factor:.4g} for {record.name}'s order p = {record.order} (Richardson): an estimate "
                                  "of the run's own error, in the observable's unit")


def _finer_controls(scene: Scene, ctrl):
    """The controls of the step-doubled run: a schedule's rows each held for two steps of dt/2 (a constant, one per
    batch element or not, and a callable as they are; rbody.control tells them apart the same way)."""
    if ctrl is None or callable(ctrl):
        return ctrl
    array = np.asarray(ctrl, dtype=np.float64)
    if array.ndim < 2 or array.shape[:-1] == tuple(scene.batch_shape):
        return array
    return np.repeat(array, 2, axis=0)


def _check_precision(scene: Scene, dt: float, t_end: float) -> None:
    """SimulationError, before any step, when the scene says float64 cannot carry its model over the run (a tree:
    TreeScene.precision_problem)."""
    check = getattr(scene, "precision_problem", None)
    if check is None:
        return
    problem = check(dt, t_end)
    if problem:
        raise SimulationError(f"scene {scene.describe()}: cannot be run in float64 as the engine works now: {problem}")


def _shaped(value, leading: tuple[int, ...]):
    """An observable (T, B, ...) reshaped to (T, *batch_shape, ...): a view where numpy can make one (theta
    of a pendulum, a strided view of the states, stays one); a lazy observable (a callable) stays lazy."""
    if callable(value):
        return lambda: _shaped(value(), leading)
    return value.reshape(leading + value.shape[2:])


def _choose_method(scene: Scene, method: str | None) -> Method | None:
    """The record of the method that runs `scene` (None for an event-driven scene), checked against what the
    scene's native model provides (never its class): default verlet where it applies, else the scene's first."""
    record = method_record(method) if method not in (None, EVENT_METHOD) else None  # ValueError: unknown name
    if scene.event_driven:
        if method not in (None, EVENT_METHOD):
            raise MethodNotApplicable(
                f"scene {scene.name!r} is event-driven: its impacts are found exactly and there is no "
                f"integrator to choose (method={method!r}); use method='events' or leave it out — dt only "
                "sets the sampling")
        return None
    if method == EVENT_METHOD:
        raise MethodNotApplicable(f"method='events' is for event-driven scenes; scene {scene.name!r} is integrated "
                                  f"in time: use one of {', '.join(scene.methods)}")
    if record is None:
        names = scene.methods
        return BY_NAME["verlet"] if "verlet" in names else BY_NAME[names[0]]
    missing = record.missing(scene.native_model)
    if missing or record.name not in scene.methods:
        why = scene.why_not(record.name)
        if missing and missing not in why:
            why += f" ({missing})"
        raise MethodNotApplicable(f"method={record.name!r} cannot run scene {scene.describe()}: {why}; methods that "
                                  f"apply: {', '.join(scene.methods)}")
    return record


# ----- the work of a run, estimated before it starts ------------------------------------------------
# Limits beyond which simulate refuses unless allow_large=True: each is far beyond any run of the
# chapter's scenes and below what would keep a machine busy for hours or exhaust its memory.
MAX_ELEMENT_STEPS = 10**10    # steps x batch: ~2 min at 10 ns per pendulum step, hours for a long chain
MAX_IMPACTS = 10**10          # impacts of an event-driven run: ~25 ns each (pi, 3.1e9 impacts in ~65 s)
MAX_ELEMENT_SAMPLES = 10**9   # saved states x batch
MEMORY_CHECKED_ABOVE = 2**20  # bytes at the peak below which the memory available is not read (any machine has it)
# The peak of a run, beside its saved states (measured with tracemalloc, tests/rbody/test_memory.py):
BUILD_FACTOR = 3.0            # building a batch's native model: up to ~2.4 x its arrays y0 and params (broadcast
                              # copies, concatenations), for a model not built yet (a TreeScene's, on first use)
OBSERVE_FACTOR = 5.0          # forming the observables: their arrays, and up to 4x as much in temporaries (a chain's energy)
DEFAULT_OBSERVED = 4.0        # numbers observed per state number where they are not probed (runs below the check)
BATCH_PROBED_ABOVE = 1024     # a batch larger than this, whose model is not built yet, is sized from one element


def _element(scene: Scene):
    """One element of `scene` as an unbatched scene (scene.item of the first index); `scene` itself if unbatched."""
    return scene.item((0,) * len(scene.batch_shape)) if scene.batch_shape else scene


def _widths(scene: Scene, batch: float) -> tuple[int, int, bool]:
    """(n, p, built): numbers of a batch element's state and parameters, and whether the native model was already
    built; a large batch not yet built is sized from one element (building it is what is being estimated)."""
    if "native_model" in scene.__dict__ or batch <= BATCH_PROBED_ABOVE:
        built = "native_model" in scene.__dict__
        model = scene.native_model
        return model.y0.shape[1], model.params.shape[1], built
    model = _element(scene).native_model
    return model.y0.shape[1], model.params.shape[1], False


def observed_numbers(scene: Scene) -> float:
    """Numbers (float64) of the observables a run forms per saved sample and batch element, not counting lazy ones
    (formed only when asked for, after the run): from the observables of one element at two samples of its initial
    state. DEFAULT_OBSERVED x the state's numbers when they cannot be formed so."""
    model = _element(scene).native_model
    state = np.ascontiguousarray(np.broadcast_to(model.y0, (2,) + model.y0.shape))
    try:
        data = model.observe(np.zeros(2), state)
    except Exception:  # noqa: BLE001 - any failure only means the generous default below
        return DEFAULT_OBSERVED * model.y0.shape[1]
    total = 0.0
    for value in data.values():
        if not callable(value):
            array = np.asarray(value)
            if not np.shares_memory(array, state):  # a view of the saved states (a pendulum's theta) costs nothing
                total += array.size * array.itemsize / 8.0
    return total / (2.0 * model.y0.shape[0])


def estimate_work(scene: Scene, dt: float, t_end: float, save_every: int) -> dict[str, float]:
    """The work of a run, before it starts (floats, so that 1e300 steps is a number, not an overflow):
    steps (per batch element), batch, samples (saved times), impacts (event-driven scenes that know their count,
    else 0), and the memory at the peak in bytes: state_bytes (the saved states, and the every-step buffer of a
    run cut at a break), observable_bytes (the observables formed from them, OBSERVE_FACTOR x their arrays),
    build_bytes (the batch's native model where it is not built yet, BUILD_FACTOR x its arrays), work_bytes (the
    stability check's Jacobians), constraint_bytes (a constrained tree's rows: constraint_numbers) and bytes, their
    sum. The observables are probed (observed_numbers) only for runs
    whose saved states pass MEMORY_CHECKED_ABOVE, the size the check reads the memory for.
    Raises ValueError when save_every is beyond the run."""
    steps = max(1.0, math.ceil(t_end / dt * (1 - 1e-12))) if t_end / dt < 2.0**62 else t_end / dt
    if save_every > steps:
        raise ValueError(f"save_every={save_every}: beyond the run of {steps:.6g} steps (t_end={t_end} s, dt={dt} s); "
                         "give save_every <= t_end/dt (a larger one would run the scene past t_end)")
    samples = -(-steps // save_every) + 1
    batch = float(np.prod(scene.batch_shape)) if scene.batch_shape else 1.0
    impacts = build = observed = work = rows = 0.0
    if scene.event_driven:
        state = 3 * getattr(scene, "n", 1) + 4      # gaps, velocities, counts of each sample
        expected = getattr(scene, "expected_events", None)
        impacts = float(expected(t_end)) if callable(expected) else 0.0
        held = samples * state
        observed = samples * state * OBSERVE_FACTOR
    else:
        n, p, built = _widths(scene, batch)
        held = samples * n * batch
        if not built:
            build = BUILD_FACTOR * batch * (n + p)
        if held * 8.0 > MEMORY_CHECKED_ABOVE:
            observed = OBSERVE_FACTOR * samples * batch * observed_numbers(scene)
        else:
            observed = OBSERVE_FACTOR * samples * batch * DEFAULT_OBSERVED * n
        if built and crosses_break(scene.native_model, steps, dt):
            held += (steps + 1) * n * batch          # _integrate_across_break keeps every step
        work = 3.0 * min(float(JACOBIAN_BLOCK), batch * n * n) if n <= DENSE_STATE_LIMIT else (KRYLOV_VECTORS + 8) * n
        rows = constraint_numbers(scene)
    parts = {"state_bytes": 8.0 * held, "observable_bytes": 8.0 * observed, "build_bytes": 8.0 * build,
             "work_bytes": 8.0 * work, "constraint_bytes": 8.0 * rows}
    return {"steps": float(steps), "batch": batch, "samples": float(samples), "impacts": impacts,
            "bytes": sum(parts.values()), **parts}


def constraint_numbers(scene: Scene) -> float:
    """Numbers (float64) a constrained tree's run may hold at once in its constraint layer, per batch element run
    after run: M and its factor (2 nv^2), and two arrays of one row of nv numbers per constraint row (J, and M^-1/2
    J^T in the time-stepping or the sliding columns in the event-driven scheme), contact candidates included: their
    rows are formed only where a contact is near, but a pile whose every pair is near forms them all. 0 for a scene
    without a constraint layer."""
    model = scene.native_model if "native_model" in scene.__dict__ else _element(scene).native_model
    table = getattr(model, "constraints", None)
    multibody = getattr(scene, "multibody", None)
    if table is None or multibody is None:
        return 0.0
    nv = float(multibody.nv)
    return 2.0 * nv * nv + 2.0 * float(table.rows) * nv


def combined_work(first: dict[str, float], second: dict[str, float]) -> dict[str, float]:
    """The work of two runs made one after the other with both results held (simulate's error estimate): steps
    added, the memory of both results held at once (the second's build and workspaces counted once)."""
    combined = dict(first)
    combined["steps"] = first["steps"] + second["steps"]
    combined["samples"] = max(first["samples"], second["samples"])
    combined["state_bytes"] = first["state_bytes"] + second["state_bytes"]
    combined["observable_bytes"] = first["observable_bytes"] + second["observable_bytes"]
    combined["bytes"] = sum(combined.get(k, 0.0) for k in ("state_bytes", "observable_bytes", "build_bytes", "work_bytes",
                                                          "constraint_bytes"))
    return combined


def run_work(steps: float, samples: float, numbers_per_sample: float, *, batch: float = 1.0,
             extra_bytes: float = 0.0) -> dict[str, float]:
    """The work of any engine's run in refuse_large's terms (the validation commands check MuJoCo's and pymunk's
    runs with it): steps per element, saved samples, numbers (float64) held per sample and element (states,
    observables, buffers), and any other bytes at the peak."""
    state = 8.0 * samples * batch * numbers_per_sample
    return {"steps": float(steps), "batch": float(batch), "samples": float(samples), "impacts": 0.0,
            "bytes": state + extra_bytes, "state_bytes": state, "observable_bytes": 0.0, "build_bytes": extra_bytes,
            "work_bytes": 0.0, "constraint_bytes": 0.0}


def work_problems(work: dict[str, float]) -> list[str]:
    """What in `work` (estimate_work, run_work) is beyond the limits above, one phrase each with its figures."""
    steps, batch, samples, size, impacts = (work[k] for k in ("steps", "batch", "samples", "bytes", "impacts"))
    free = available_memory() if size > MEMORY_CHECKED_ABOVE else None  # reading /proc costs ~50 us a call
    problems = []
    if steps * batch > MAX_ELEMENT_STEPS:
        problems.append(f"{steps:.3g} steps x {batch:.3g} batch elements = {steps * batch:.3g} element-steps, beyond "
                        f"{MAX_ELEMENT_STEPS:.0e} (too many steps: the step dt is too small for t_end, or the batch too large)")
    if impacts > MAX_IMPACTS:
        problems.append(f"about {impacts:.3g} impacts, beyond {MAX_IMPACTS:.0e} (~25 ns each: {impacts * 25e-9 / 60:.3g} min)")
    if samples * batch > MAX_ELEMENT_SAMPLES:
        problems.append(f"{samples:.3g} saved samples x {batch:.3g} batch elements, beyond {MAX_ELEMENT_SAMPLES:.0e} "
                        "(raise save_every)")
    if free is not None and size > MEMORY_FRACTION * free:
        parts = ", ".join(f"{label} {work[key] / 1e9:.3g} GB" for key, label in (
            ("state_bytes", "saved states"), ("observable_bytes", "observables"), ("build_bytes", "building the batch"),
            ("work_bytes", "workspaces"), ("constraint_bytes", "constraint rows, contact candidates included"))
            if work.get(key))
        problems.append(f"{size / 1e9:.3g} GB at the peak ({parts}), more than {MEMORY_FRACTION:g} of the "
                        f"{free / 1e9:.3g} GB this process can still allocate (raise save_every or split the batch; "
                        "for many bodies, fewer contact pairs: contype/conaffinity, <exclude>)")
    return problems


def refuse_large(work: dict[str, float], allow_large: bool = False) -> None:
    """ValueError, with the estimate, when `work` (estimate_work, run_work) is beyond the limits above (unless
    allow_large)."""
    if allow_large:
        return
    problems = work_problems(work)
    if problems:
        raise ValueError("run refused before it starts: " + "; ".join(problems)
                         + ". Pass allow_large=True to run it anyway.")
