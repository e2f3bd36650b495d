"""rbody's own engine as a backend: rbody.simulate, unchanged."""

from __future__ import annotations

import time

import rbody
from rbody.trajectory import Trajectory

name = "rbody"


def check(scene: rbody.Scene) -> None:
    """rbody runs every scene that has a native model (time-stepped) or exact events (event-driven)."""
    if not scene.event_driven and type(scene).native is rbody.Scene.native:
        raise NotImplementedError(f"{type(scene).__name__} defines no native model (Scene.native) and is not "
                                  "event-driven: rbody has nothing to integrate")


def run(scene: rbody.Scene, dt: float, t_end: float | None = None, *, method: str | None = None,
        save_every: int = 1, ctrl=None) -> Trajectory:
    """rbody.simulate(scene, dt=dt, method=method, ctrl=ctrl, ...); meta["step_seconds"] and meta["run_seconds"]
    are both the wall time of the whole call (model, stability check, stepping, every observable) after a
    two-step warm-up has compiled the kernels (the cost a user pays on every later call)."""
    t_end = scene.t_end if t_end is None else t_end
    rbody.simulate(scene, dt=min(dt, t_end), method=method, t_end=min(2 * dt, t_end))  # compile once
    start = time.perf_counter()
    trajectory = rbody.simulate(scene, dt=dt, method=method, t_end=t_end, save_every=save_every, ctrl=ctrl)
    seconds = time.perf_counter() - start
    return Trajectory(trajectory.t, trajectory.data, trajectory.events,
                      dict(trajectory.meta, step_seconds=seconds, run_seconds=seconds))
