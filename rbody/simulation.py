"""simulate(scene, dt, method): the native run, in the fewest coordinates of each scene.

The pipeline of a time-stepped run, as a short list of calls:

    model = scene.native_model                # minimal coordinates, compiled rhs/accel, batch of states
    out   = _integrate(model, method, ...)    # the compiled loop of the method
    data  = model.observe(t, out)             # observables, (T, *batch, ...)

Event-driven scenes (impacts) are run event by event instead (scene.run_events): the time step
only sets where the trajectory is sampled.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from rbody import control
from rbody.checks import run_times, whole_number
from rbody.engine.methods import BY_NAME, Method, method as method_record
from rbody.engine.runner import crosses_break, failure, integrate_model, step_count
from rbody.engine.stability import check_step
from rbody.errors import MethodNotApplicable, SimulationError
from rbody.scene import Scene
from rbody.trajectory import Trajectory

EVENT_METHOD = "events"


def simulate(scene: Scene, *, dt: float, method: str | None = None, t_end: float | None = None,
             save_every: int = 1, allow_large: bool = False, client: Any = None,
             chunk: int | None = None, ctrl: Any = None) -> Trajectory:
    """Run `scene` natively.

    dt:         time step [s] (event-driven scenes: the sampling interval of the trajectory only)
    method:     one of rbody.METHODS; default "verlet" where it applies, else the scene's first
                method; "events" (the only choice) for event-driven scenes
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
                scenes run here. None (default): everything runs here and Dask is not imported.
    ctrl:       the controls of a scene with actuators (rbody.control): None (the scene's ctrl0), a constant
                (nu,) or (*batch, nu), a schedule (n_steps, [*batch,] nu) whose row k is held during step k, or
                a callable ctrl(t, qpos, qvel) -> (nu,) called at the start of every step (one Python call per
                step). A control is held through a whole step, as in MuJoCo.
    Returns a Trajectory whose observables have shape (T, *scene.batch_shape, ...).
    Raises ValueError for bad arguments, a run too large to start (above), a closed client or a chunk
    without a client; MethodNotApplicable when the method cannot run the scene; SimulationError, before
    any step, when dt is beyond the method's estimated stability limit on the scene (rbody.engine.stability)
    and, after, when a step gives a non-finite state (never a trajectory holding NaN, except where an
    observable means "not yet": a race's arrival time), or when a task lost its worker more often than
    Dask retries it.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    dt, t_end = run_times(scene.t_end, dt, t_end)
    whole_number(save_every, "save_every")
    record = _choose_method(scene, method)
    method = record.name if record is not None else EVENT_METHOD
    if chunk is not None and client is None:
        raise ValueError(f"chunk={chunk!r}: rows per task of a Dask client; give client= too, or leave chunk out")
    refuse_large(estimate_work(scene, dt, t_end, save_every), allow_large)

    if scene.event_driven:
        return scene.run_events(t_end, dt * save_every)
    check_step(scene, method, dt, t_end)  # beyond the method's stability limit: refuse before any step

    model = getattr(scene, "native_model_for", lambda _method: scene.native_model)(method)  # built once per scene
    nsteps = step_count(t_end, dt, save_every)
    controls = control.plan(scene, model, ctrl, dt, nsteps, method)  # the run's own rows, controls written in
    if client is not None and (controls.stepwise is not None or controls.history is not None
                               or ctrl is not None):
        raise ValueError("ctrl with client=: a run with a given control goes in this process (the cluster's tasks "
                         "rebuild the scene's own model); leave client out")
    model = controls.model
    if model.break_time is not None and 0 < model.break_time < dt:
        raise SimulationError(
            f"scene {scene.describe()}: its right-hand side jumps at t = {model.break_time:.6g} s (e.g. a "
            f"rocket's burn-out), inside the first step dt={dt}: the whole phase before it would be one step of "
            f"{model.break_time:.3g} s, integrated with no step inside it; use dt <= {model.break_time / 10:.3g} s "
            "(ten steps or more before the jump)")
    out = np.empty((nsteps // save_every + 1,) + model.y0.shape)
    if client is not None:  # the batch's rows as tasks on a Dask cluster, each as below
        from rbody.engine.distributed import integrate_on_cluster
        failed = integrate_on_cluster(client, scene, model, method, dt, nsteps, save_every, out, chunk)
    elif controls.stepwise is not None:
        failed = control.run_stepwise(controls, record, dt, nsteps, save_every, out)
    else:
        failed = integrate_model(model, record, dt, nsteps, save_every, out)
    if failed.size and failed.max() >= 0:
        raise failure(scene.describe(), model, record, dt, save_every, out, failed)
    t = np.arange(out.shape[0]) * (dt * save_every)
    model = control.observing(controls, save_every, out.shape[0], dt)
    try:  # every state is finite here; one the observables cannot take (a quaternion of zero length) is a failure
        data = model.observe(t, out)
    except (ValueError, FloatingPointError) as error:
        raise SimulationError(f"scene {scene.describe()}: method {method!r} with dt={dt} gave states whose "
                              f"observables cannot be formed ({error}); try a smaller dt") from None
    data = {name: _shaped(value, (t.size,) + scene.batch_shape) for name, value in data.items()}
    return Trajectory(t, data, meta={"scene": scene.name, "backend": "rbody", "method": method, "dt": dt})


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


