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
import os
from typing import Any

import numpy as np

from rbody.checks import run_times, whole_number
from rbody.engine.distributed import PREPARED_KEY, integrate_on_cluster
from rbody.engine.methods import BY_NAME, Method, method as method_record
from rbody.engine.runner import crosses_break, failure, integrate_model, step_count
from rbody.engine.stability import check_state, check_step
from rbody.errors import MethodNotApplicable, SimulationError
from rbody.scene import Scene
from rbody.trajectory import Trajectory

EVENT_METHOD = "events"


def simulate(scene: Scene, *, dt: float, method: str | None = None, t_end: float | None = None,
             save_every: int = 1, allow_large: bool = False, client: Any = None,
             chunk: int | None = None) -> Trajectory:
    """Run `scene` natively.

    dt:         time step [s] (event-driven scenes: the sampling interval of the trajectory only)
    method:     one of rbody.METHODS; default "verlet" where it applies, else the scene's first
                method; "events" (the only choice) for event-driven scenes; a tree with limits, dry friction
                or equalities takes "rk4" (event-driven: rk4 between events located exactly, the default) or
                "moreau" (time-stepping), and reports its events in trajectory.events and meta["events"]
                (rbody.engine.constraints)
    t_end:      duration [s], default scene.t_end
    save_every: keep every n-th step (1 <= n <= ceil(t_end/dt)); the run takes ceil(t_end/dt) steps
                rounded up to a multiple of save_every, so the last saved time is t_end or up to
                save_every dt past it
    allow_large: run even when the work estimated before the run (estimate_work: steps, saved
                samples, memory, impacts) is beyond its limits; without it such a run is refused
                with a ValueError giving the estimate
    client:     a dask.distributed.Client: the batch's rows run as tasks on its cluster, `chunk` rows each
                (default: about 4 tasks per worker thread, at least a few thousand rows; see
                rbody.engine.distributed); the result equals the serial run's bit for bit. Event-driven
                scenes and constrained trees (limits, dry friction, equalities: rbody.engine.constraints) run
                here, element by element. None (default): everything runs here and Dask is not imported.
    Returns a Trajectory whose observables have shape (T, *scene.batch_shape, ...).
    Raises ValueError for bad arguments, a run too large to start (above), a closed client or a chunk
    without a client; MethodNotApplicable when the method cannot run the scene; SimulationError, before
    any step, when dt is beyond the method's estimated stability limit on the scene (rbody.engine.stability)
    and, after, when a step gives a non-finite state (never a trajectory holding NaN, except where an
    observable means "not yet": a race's arrival time), or when a task lost its worker more often than
    Dask retries it.

    Without a client this is prepare(scene, ...).run(): the checks, the model and the bound loop are made on the
    first call with these arguments and kept with the scene, so a repeated call costs the run alone.
    """
    if chunk is not None and client is None:
        raise ValueError(f"chunk={chunk!r}: rows per task of a Dask client; give client= too, or leave chunk out")
    prepared = prepare(scene, dt=dt, method=method, t_end=t_end, save_every=save_every, allow_large=allow_large)
    if client is None:
        return prepared.run()
    return prepared.run_on_cluster(client, chunk)


def prepare(scene: Scene, *, dt: float, method: str | None = None, t_end: float | None = None,
            save_every: int = 1, allow_large: bool = False) -> "PreparedRun":
    """Everything of a run that depends only on (scene, dt, method, t_end, save_every), done once: the arguments
    checked, the method chosen, the work estimated and refused if too large, the stability and resolution checks,
    the native model built and the method's compiled loop bound to it. Arguments and errors as simulate's.

    The result is kept with the scene (a frozen scene never changes), so prepare, and simulate, called again
    with the same arguments return it at once. PreparedRun.run() then costs what the integration costs.
    """
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

    run(qpos0=None, qvel0=None) -> Trajectory: the scene from its own initial state, or (trees) from qpos0
    (*batch, nq) and qvel0 (*batch, nv) of the scene's batch shape, which are checked as the scene checks its
    own (shapes, finite numbers, unit quaternions) and for the stability of the step at that state.
    Attributes: scene, method (its name), dt [s], t_end [s], save_every, nsteps, t (T,) [s] the saved times.
    """

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
        if scene.event_driven:
            return
        check_step(scene, self.method, self.dt, self.t_end)  # beyond the method's stability limit: refuse now
        self.model = model = scene.native_model  # built once per scene
        self.nsteps = step_count(self.t_end, self.dt, self.save_every)
        if model.break_time is not None and 0 < model.break_time < self.dt:
            raise SimulationError(
                f"scene {scene.describe()}: its right-hand side jumps at t = {model.break_time:.6g} s (e.g. a "
                f"rocket's burn-out), inside the first step dt={self.dt}: the whole phase before it would be one step "
                f"of {model.break_time:.3g} s, integrated with no step inside it; use dt <= "
                f"{model.break_time / 10:.3g} s (ten steps or more before the jump)")
        self.y0 = np.array(model.y0, dtype=np.float64, order="C")         # the loops' own writable copies
        self.params = np.array(model.params, dtype=np.float64, order="C")
        self.t = np.arange(self.nsteps // self.save_every + 1) * (self.dt * self.save_every)
        self.t.setflags(write=False)
        self.leading = (self.t.size,) + scene.batch_shape
        self.meta = {"scene": scene.name, "backend": "rbody", "method": self.method, "dt": self.dt}
        # limits, dry friction, equalities: the constraint layer's own schemes (rbody.engine.constraints), no loop
        self.constrained = model.constraints is not None
        self._runner = (None if self.constrained or crosses_break(model, self.nsteps, self.dt)
                        else self.record.bound(model, self.y0.shape[0], self.dt, self.nsteps, self.save_every))

    def run(self, *, qpos0: Any = None, qvel0: Any = None) -> Trajectory:
        """The run, from the scene's initial state or (trees) from qpos0/qvel0; a Trajectory as simulate's."""
        scene = self.scene
        if scene.event_driven:
            if qpos0 is not None or qvel0 is not None:
                raise ValueError(f"scene {scene.name!r} is event-driven: it starts from its own state (qpos0 and "
                                 "qvel0 are for trees of bodies and joints)")
            if self.work["bytes"] > MEMORY_CHECKED_ABOVE:
                refuse_large(self.work, self.allow_large)
            return scene.run_events(self.t_end, self.dt * self.save_every)
        y0 = self.y0 if qpos0 is None and qvel0 is None else self._start(qpos0, qvel0)
        if self.work["bytes"] > MEMORY_CHECKED_ABOVE:  # the memory available may have changed since prepare
            refuse_large(self.work, self.allow_large)
        if self.constrained:
            return self._constrained_run(y0)
        out = np.empty((self.t.size,) + y0.shape)
        if self._runner is None:  # the run crosses a break in the rhs: cut there (integrate_model)
            failed = integrate_model(self.model if y0 is self.y0 else dataclasses.replace(self.model, y0=y0),
                                     self.record, self.dt, self.nsteps, self.save_every, out)
        else:
            failed = self._runner(y0, self.params, out)
        return self._trajectory(y0, out, failed)

    def run_on_cluster(self, client: Any, chunk: int | None = None) -> Trajectory:
        """The batch's rows as tasks on the Dask cluster of `client` (simulate's client=, chunk=); event-driven and
        constrained scenes run here."""
        if self.scene.event_driven or self.constrained:
            return self.run()
        out = np.empty((self.t.size,) + self.y0.shape)
        failed = integrate_on_cluster(client, self.scene, self.model, self.method, self.dt, self.nsteps,
                                      self.save_every, out, chunk)
        return self._trajectory(self.y0, out, failed)

    def _start(self, qpos0: Any, qvel0: Any) -> np.ndarray:
        """y0 (B, n) of a tree from qpos0 and qvel0 (the scene's own where one is None), checked; SimulationError
        when the step is beyond the stability limit at that state."""
        start = getattr(self.scene, "native_start", None)
        if start is None:
            raise ValueError(f"scene {self.scene.describe()}: qpos0 and qvel0 are for trees of bodies and joints "
                             "(Scene.from_layout, from_mjcf); a family scene takes its initial state as parameters")
        y0 = np.array(start(qpos0, qvel0), dtype=np.float64, order="C")
        if y0.shape != self.y0.shape:
            raise ValueError(f"qpos0/qvel0 give a batch of {y0.shape[0]} states: this run was prepared for "
                             f"{self.y0.shape[0]} (the scene's batch shape {self.scene.batch_shape}); prepare the "
                             "scene with that batch")
        check_state(dataclasses.replace(self.model, y0=y0), self.scene.describe(), self.method, self.dt,
                    self.t_end)
        return y0

    def _constrained_run(self, y0: np.ndarray) -> Trajectory:
        """A constrained tree's run: events located exactly between smooth steps (rk4), or Moreau-Jean
        time-stepping (moreau), by rbody.engine.constraints.runner."""
        from rbody.engine.constraints.runner import run_constrained

        model = self.model if y0 is self.y0 else dataclasses.replace(self.model, y0=y0)
        t, data, events, meta = run_constrained(self.scene.describe(), model, self.method, self.dt, self.nsteps,
                                                self.save_every)
        data = {name: _shaped(value, (t.size,) + self.scene.batch_shape) for name, value in data.items()}
        return Trajectory(t, data, events=events, meta={**self.meta, **meta})

    def _trajectory(self, y0: np.ndarray, out: np.ndarray, failed: np.ndarray) -> Trajectory:
        model = self.model if y0 is self.y0 else dataclasses.replace(self.model, y0=y0)
        if (failed[0] >= 0) if failed.size == 1 else (failed.size and failed.max() >= 0):  # one element: no reduction
            raise failure(self.scene.describe(), model, self.record, self.dt, self.save_every, out, failed)
        try:  # every state is finite here; one the observables cannot take (a zero quaternion) is a failure
            if getattr(model.observe, "any_batch", False):
                data = model.observe(self.t, out.reshape(self.leading + out.shape[2:]))
            else:
                data = {name: _shaped(value, self.leading) for name, value in model.observe(self.t, out).items()}
        except (ValueError, FloatingPointError) as error:
            raise SimulationError(f"scene {self.scene.describe()}: method {self.method!r} with dt={self.dt} gave "
                                  f"states whose observables cannot be formed ({error}); try a smaller dt") from None
        return Trajectory(self.t, data, meta=dict(self.meta))

    def __call__(self, *, qpos0: Any = None, qvel0: Any = None) -> Trajectory:
        return self.run(qpos0=qpos0, qvel0=qvel0)

    def __repr__(self) -> str:
        return (f"PreparedRun({self.scene.describe()}, method={self.method!r}, dt={self.dt:g}, t_end={self.t_end:g}, "
                f"save_every={self.save_every})")


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
MEMORY_FRACTION = 0.5         # of the memory available now: the observables formed from the states take more
MEMORY_CHECKED_ABOVE = 2**20  # bytes of saved states below which the memory available is not read (any machine has it)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation now (Linux MemAvailable; else free pages), or None."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def estimate_work(scene: Scene, dt: float, t_end: float, save_every: int) -> dict[str, float]:
    """The work of a run, before it starts (floats, so that 1e300 steps is a number, not an overflow):
    steps (per batch element), batch, samples (saved times), bytes (the saved states, and the every-step
    buffer of a run cut at a break), impacts (event-driven scenes that know their count, else 0).
    Raises ValueError when save_every is beyond the run."""
    steps = max(1.0, math.ceil(t_end / dt * (1 - 1e-12))) if t_end / dt < 2.0**62 else t_end / dt
    if save_every > steps:
        raise ValueError(f"save_every={save_every}: beyond the run of {steps:.6g} steps (t_end={t_end} s, dt={dt} s); "
                         "give save_every <= t_end/dt (a larger one would run the scene past t_end)")
    samples = -(-steps // save_every) + 1
    batch = float(np.prod(scene.batch_shape)) if scene.batch_shape else 1.0
    impacts = 0.0
    if scene.event_driven:
        state = 3 * getattr(scene, "n", 1) + 4      # gaps, velocities, counts of each sample
        expected = getattr(scene, "expected_events", None)
        impacts = float(expected(t_end)) if callable(expected) else 0.0
        held = samples * state
    else:
        model = scene.native_model
        state = model.y0.shape[1]
        held = samples * state * batch
        if crosses_break(model, steps, dt):
            held += (steps + 1) * state * batch      # _integrate_across_break keeps every step
    return {"steps": float(steps), "batch": batch, "samples": float(samples), "bytes": 8.0 * held,
            "impacts": impacts}


def refuse_large(work: dict[str, float], allow_large: bool = False) -> None:
    """ValueError, with the estimate, when `work` (estimate_work) is beyond the limits above (unless allow_large)."""
    if allow_large:
        return
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
        problems.append(f"{size / 1e9:.3g} GB of saved states, more than {MEMORY_FRACTION:g} of the {free / 1e9:.3g} GB "
                        "of memory available (raise save_every or split the batch)")
    if problems:
        raise ValueError("run refused before it starts: " + "; ".join(problems)
                         + ". Pass allow_large=True to run it anyway.")


