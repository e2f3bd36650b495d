"""NativeModel: the problem a native run integrates, as the engine's integrators and checks read it.

A scene (rbody.scene) builds one; everything below it (the integrators, the stability check, the runner,
the Dask worker) reads only this record, never the scene that made it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class NativeModel:
    """How rbody integrates a continuous scene in minimal coordinates (see rbody.engine).

    y0:        (B, n) initial state, batch flattened
    params:    (B, p) parameters the kernels read
    rhs:       compiled f(y (n,), params (p,), out (n,)): y' = f(y), for every general method
    accel:     compiled a(q (m,), params, out (m,)) when y = (q, q') and q'' depends on q only
               (enables the symplectic methods); None otherwise
    split:     name -> (step, weights): the scene's own symmetric one-step map step(y, p, h) and the
               composition weights (free rotation: "splitting" and its 6th-order "yoshida6")
    rhs, accel and step must be numba @njit functions over C-contiguous float64 arrays: the engine
    calls them through C function pointers (see rbody/engine/integrators.py)
    observe:   function (t (T,), y (T, B, n)) -> dict of observables (T, B, ...); an observe marked by
               any_batch (below) takes states of any leading axes (T, *batch, n) and keeps them (T, *batch, ...),
               so simulate reshapes the states once instead of every observable (a mark on the function itself:
               a model whose observe is replaced loses it)
    """

    y0: np.ndarray
    params: np.ndarray
    rhs: Any
    observe: Any
    accel: Any = None
    split: Mapping[str, Any] = field(default_factory=dict)
    # A time [s] at which rhs jumps (a rocket's burn-out), shared by the batch, and the params column
    # that tells rhs which side it is on (1 before, 0 after, -1 decide from the state). simulate splits
    # the step that straddles it at the break, so that no step integrates across the jump.
    break_time: float | None = None
    break_column: int | None = None
    # finish(y, p): compiled, run after every whole step of euler, rk4 and gauss6 and at every sample of
    # reference (a tree folds its rotation vectors into its quaternions: rbody.engine.multibody); None: nothing.
    finish: Any = None
    # rhs_lanes(y, p, out): rhs over rbody.engine.simd.WIDTH states side by side (y, out structures of arrays: entry k
    # of state l at k * WIDTH + l), each state's result with the bits rhs gives it; the rk4 loop steps a batch whose
    # parameter rows are all one this way (rbody.engine.integrators.bind_rk4). None: rhs only.
    rhs_lanes: Any = None
    # How the stability check (rbody.engine.stability) finds the fastest rate w [1/s] of the linearised motion of each
    # batch element, so that it never asks which scene it has:
    #   rate: fastest(method name) -> (B,) w, the scene's own estimate where it knows its motion (a pendulum's
    #         w0, a free rotation's rate over one period); it wins over the two below
    #   rate_from_jacobian: True: the spectral radius of df/dy by central differences at y0, and also at
    #         `rest` (n,) when given, a state of equilibrium (there: the fastest normal mode)
    #   neither: no estimate (rate 0, an infinite limit; the non-finite check after every step remains)
    rate: Any = None
    rate_from_jacobian: bool = False
    rest: Any = None
    # (B,) |1 - k^2| of a motion near a separatrix (a pendulum released near the top), whose margin the state
    # carries only to ~eps: rbody.engine.stability.resolution_problem refuses runs whose round-off would decide it.
    separatrix_margin: Any = None
    # diagnose(y (n,), y0 (n,), dt) -> str: why the motion cannot go on from state y, started from y0 ("" when nothing
    # is found), for the message of a failed run (a tree: the body and joint whose mass-matrix pivot vanished).
    diagnose: Any = None
    # The constraint table (rbody.engine.constraints.table.ConstraintTable) of a tree with limits, dry friction or
    # equalities, whose run simulate hands to the constraint layer (rbody.engine.constraints.runner); None: none.
    constraints: Any = None
    # Where a run writes its controls, time step and control schedule into params, and where act sits in y
    # (rbody.engine.system.ControlSlots), for a model driven by controls (a tree with actuators); None otherwise.
    controls: Any = None


@runtime_checkable
class Experiment(Protocol):
    """What the engine reads of a scene (rbody.scene.Scene provides it): the engine never imports the scene layer.

    name, t_end [s], batch_shape; event_driven (impacts found exactly, no time step); native_model (the
    NativeModel, built once); describe() (one line for messages). The stability check keeps its per-method
    rates in the object's __dict__ (a frozen scene never changes, so they never go stale).
    """

    name: str
    t_end: float
    event_driven: bool

    @property
    def batch_shape(self) -> tuple[int, ...]: ...

    @property
    def native_model(self) -> NativeModel: ...

    def describe(self) -> str: ...


def any_batch(observe: Any) -> Any:
    """Mark `observe` (NativeModel.observe) as taking states of any leading axes (T, *batch, n); returns it."""
    observe.any_batch = True
    return observe
