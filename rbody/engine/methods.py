"""The integration methods, one record each: what a method is, what it needs, how far it can step, how it runs.

A record is the single source of every fact about a method that simulate, the stability check and the
scenes read (no parallel tables):

    order       convergence order p (error ~ dt^p); None for the adaptive reference solver
    needs       what the scene's NativeModel must provide:
                  "rhs"    y' = f(y)                              (every general method)
                  "accel"  q'' = a(q), y = (q, q'): a separable Hamiltonian  (the explicit symplectic ones)
                  "split"  the scene's own symmetric one-step map under this method's name (model.split)
                  "constraints"  a constrained tree (model.constraints): the constraint layer's time-stepping
                A constrained tree (limits, dry friction, equalities) takes only the methods its constraint table
                names (rk4: event-driven, rk4 between events; moreau: time-stepping; mujoco_euler, implicitfast,
                implicit: the time-stepping with MuJoCo's step as its free motion): rbody.engine.constraints.
                A scene may also supply its own flow under any method's name in model.split (a free rotation's
                "yoshida6" composes its exact sub-rotations): that flow is then what runs.
    symplectic, symmetric, explicit
    interval    beta: the method keeps an oscillation y' = i w y bounded while dt w < beta (the imaginary
                axis; rbody.engine.stability takes every |eigenvalue| of the Jacobian as such a rate):
                  euler             0 (none: |1 + i dt w| > 1; rbody.engine.stability limits its growth instead)
                  symplectic_euler  2 (trace of the step matrix 2 - (dt w)^2 must stay in [-2, 2])
                  verlet            2 (the same trace)
                  rk4               2 sqrt(2) (|1 + z + z^2/2 + z^3/6 + z^4/24| <= 1 at z = i dt w)
                  yoshida6          2.26905...: where the trace of its seven verlet steps first leaves [-2, 2]
                  gauss6            1 / (2 rho(A)) = 2.32: A-stable, but its stage equations are solved by
                                    fixed-point iteration, which contracts by dt w rho(A) per sweep
                  splitting         2, a second-order symmetric splitting's (the yoshida6 composition of a
                                    scene's flow takes yoshida6's)
                  moreau            2, as symplectic Euler (its free motion between impulses)
                  mujoco_euler, implicitfast, implicit   2: semi-implicit Euler's on an undamped oscillation (their
                                    implicit velocity terms only damp; rbody.engine.mujoco_steps); the rate they are
                                    checked against is the stiffness's, sqrt of the spectral radius of d qacc/d q
                  reference         inf (scipy's DOP853 at rtol 1e-13, adaptive)
    bind        bind(model, flow, batch, dt, nsteps, save_every) -> runner(y0, params, out) -> failed (B,): the
                compiled loop with all but the states fixed (rbody.engine.integrators.Bound); flow is the
                scene's own (step, weights) for this method, or None

METHODS (the names, in this order), METHOD_ORDER, SYMPLECTIC and SYMMETRIC are derived from the records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any, Callable

import numpy as np

from rbody.engine import integrators

NEEDS = {"rhs": "y' = f(y) (the model's rhs)",
         "accel": "q'' = a(q) with y = (q, q'), a separable Hamiltonian (the model's accel)",
         "split": "the scene's own symmetric one-step map (the model's split flows)",
         "constraints": "a constrained tree (the model's constraint table: rbody.engine.constraints)",
         "mujoco": "a tree's MuJoCo step (rbody.engine.mujoco_steps: its mass matrix, forces and velocity derivatives)"}


@dataclass(frozen=True, eq=False)
class Method:
    """One integration method (module docstring). `beta` computes the stability interval on first use."""

    name: str
    order: int | None
    needs: str
    symplectic: bool
    symmetric: bool
    explicit: bool
    beta: Callable[[], float]
    bind: Callable[..., Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]]
    summary: str
    failure: str = "a non-finite state"  # what a failed step means, for simulate's message

    def __post_init__(self) -> None:
        if self.needs not in NEEDS:
            raise ValueError(f"method {self.name!r}: needs={self.needs!r}, expected one of {tuple(NEEDS)}")

    @cached_property
    def interval(self) -> float:
        """beta (float): stable on an oscillation of angular frequency w while dt w < beta (module docstring)."""
        return float(self.beta())

    def flow(self, model) -> Any:
        """The scene's own (step, weights) for this method (model.split), or None."""
        return model.split.get(self.name) if model.split else None

    def missing(self, model) -> str:
        """"" when `model` (a NativeModel) provides what this method needs, else what it lacks."""
        table = getattr(model, "constraints", None)
        if table is not None:  # the constraint layer runs its own schemes
            if self.name == "rk4" and table.events_refused:
                return table.events_refused
            return "" if self.name in table.methods else (
                f"{self.name!r} does not run a constrained tree (limits, dry friction, equalities, contacts): the "
                f"constraint layer runs {', '.join(table.methods)} (rbody.engine.constraints)")
        if self.needs == "constraints":
            return "" if table is not None else f"{self.name!r} needs {NEEDS['constraints']}"
        if self.flow(model) is not None:
            return ""
        if self.needs == "rhs" and model.rhs is not None:
            return ""
        if self.needs == "accel" and model.accel is not None:
            return ""
        return f"{self.name!r} needs {NEEDS[self.needs]}, which the scene's model does not provide"

    def applies(self, model) -> bool:
        """Whether `model` (a NativeModel) provides what this method needs."""
        return not self.missing(model)

    def bound(self, model, batch: int, dt: float, nsteps: int, save_every: int):
        """runner(y0 (B, n), params (B, p), out) -> failed (B,): this method's loop on `model` with everything but the
        states fixed (a prepared run calls it again and again; rbody.engine.integrators.Bound)."""
        return self.bind(model, self.flow(model), batch, dt, nsteps, save_every)

    def integrate(self, model, y0: np.ndarray, params: np.ndarray, dt: float, nsteps: int, save_every: int,
                  out: np.ndarray) -> np.ndarray:
        """Run the compiled loop on (y0 (B, n), params (B, p)) of any layout; out (nsteps // save_every + 1, B, n)
        filled; returns failed (B,): the first failed step of each element, or -1."""
        y0 = np.ascontiguousarray(y0, dtype=np.float64)
        params = np.ascontiguousarray(params, dtype=np.float64)
        runner = self.bound(model, y0.shape[0], dt, nsteps, save_every)
        return getattr(runner, "launch", runner)(y0, params, out)


# ----- how each method runs (the loops are in rbody.engine.integrators) ------------------------------------
# bind(model, flow, batch, dt, nsteps, save_every) -> runner(y0, params, out) -> failed: everything but the states
# fixed once (integrators.Bound: its compiled entry found on the first call); run follows from bind.

def _bind_flow(flow, batch, dt, nsteps, save_every):
    step, weights = flow
    return integrators.bind_composed_flow(step, weights, batch, dt, nsteps, save_every)


def _bind_euler(model, flow, batch, dt, nsteps, save_every):
    return integrators.bind_euler(model.rhs, batch, dt, nsteps, save_every, finish=model.finish)


def _bind_rk4(model, flow, batch, dt, nsteps, save_every):
    return integrators.bind_rk4(model.rhs, batch, dt, nsteps, save_every, finish=model.finish, lanes=model.rhs_lanes)


def _bind_gauss6(model, flow, batch, dt, nsteps, save_every):
    return integrators.bind_gauss6(model.rhs, integrators.GAUSS6_A, integrators.GAUSS6_B, batch, dt, nsteps,
                                   save_every, finish=model.finish)


def _bind_reference(model, flow, batch, dt, nsteps, save_every):
    def runner(y0, params, out):
        return integrators.run_reference(model.rhs, y0, params, dt, nsteps, save_every, out, finish=model.finish)
    return runner


def _bind_symplectic_euler(model, flow, batch, dt, nsteps, save_every):
    if flow is not None:
        return _bind_flow(flow, batch, dt, nsteps, save_every)
    return integrators.bind_symplectic_euler(model.accel, batch, dt, nsteps, save_every)


def _bind_composed_verlet(weights):
    def bind(model, flow, batch, dt, nsteps, save_every):
        if flow is not None:  # the scene's own flow under this name (free rotation: yoshida6 of its rotations)
            return _bind_flow(flow, batch, dt, nsteps, save_every)
        return integrators.bind_composed_verlet(model.accel, weights, batch, dt, nsteps, save_every)
    return bind


def _bind_splitting(model, flow, batch, dt, nsteps, save_every):
    return _bind_flow(flow, batch, dt, nsteps, save_every)


def _bind_constrained(model, flow, batch, dt, nsteps, save_every):
    raise NotImplementedError("a constrained tree runs through rbody.engine.constraints.runner (simulate routes it "
                              "there), never through a fixed-step loop")


# ----- the stability intervals that need a computation ----------------------------------------------------

@lru_cache(maxsize=None)
def yoshida6_interval() -> float:
    """h w bound of yoshida6 on the harmonic oscillator: the first h at which the trace of the composed verlet
    steps (weights YOSHIDA6) leaves [-2, 2] (a grid of 1e-3, then bisection to round-off)."""

    def trace(h: float) -> float:
        step = np.eye(2)
        for w in integrators.YOSHIDA6:
            kick = np.array([[1.0, 0.0], [-0.5 * w * h, 1.0]])
            drift = np.array([[1.0, w * h], [0.0, 1.0]])
            step = kick @ drift @ kick @ step
        return float(np.trace(step))

    grid = np.arange(1, 4001) * 1e-3  # the first exit on this grid (the unstable windows beyond it are wider)
    first = next(i for i, h in enumerate(grid) if abs(trace(h)) > 2.0)
    low, high = float(grid[first - 1]), float(grid[first])
    for _ in range(60):
        middle = 0.5 * (low + high)
        if abs(trace(middle)) <= 2.0:
            low = middle
        else:
            high = middle
    return low


def gauss6_interval() -> float:
    """1 / (2 rho(A)): fixed-point iteration of the stage equations contracts by 1/2 or better."""
    return 0.5 / float(np.max(np.abs(np.linalg.eigvals(integrators.GAUSS6_A))))


# ----- the records --------------------------------------------------------------------------------------

RECORDS: tuple[Method, ...] = (
    Method("euler", 1, "rhs", symplectic=False, symmetric=False, explicit=True, beta=lambda: 0.0, bind=_bind_euler,
           summary="y += dt f(y)"),
    Method("symplectic_euler", 1, "accel", symplectic=True, symmetric=False, explicit=True, beta=lambda: 2.0,
           bind=_bind_symplectic_euler, summary="v += dt a(q); q += dt v"),
    Method("verlet", 2, "accel", symplectic=True, symmetric=True, explicit=True, beta=lambda: 2.0,
           bind=_bind_composed_verlet(np.ones(1)), summary="velocity Verlet (kick-drift-kick)"),
    Method("rk4", 4, "rhs", symplectic=False, symmetric=False, explicit=True, beta=lambda: 2.0 * math.sqrt(2.0),
           bind=_bind_rk4, summary="classical Runge-Kutta"),
    Method("yoshida6", 6, "accel", symplectic=True, symmetric=True, explicit=True, beta=yoshida6_interval,
           bind=_bind_composed_verlet(integrators.YOSHIDA6),
           summary="Yoshida's 7-stage symmetric composition of verlet (solution A), or of the scene's own flow"),
    Method("gauss6", 6, "rhs", symplectic=True, symmetric=True, explicit=False, beta=gauss6_interval, bind=_bind_gauss6,
           summary="3-stage Gauss-Legendre collocation, stage equations by fixed-point iteration",
           failure="a non-finite state or stage equations that fixed-point iteration could not solve "
                   "(dt |df/dy| too large)"),
    Method("splitting", 2, "split", symplectic=True, symmetric=True, explicit=True, beta=lambda: 2.0,
           bind=_bind_splitting, summary="the scene's own symmetric splitting into exact flows"),
    Method("moreau", 1, "constraints", symplectic=False, symmetric=False, explicit=True, beta=lambda: 2.0,
           bind=_bind_constrained, summary="Moreau-Jean time-stepping of a constrained tree: impulses at the velocity level, "
           "a complementarity problem per step (rbody.engine.constraints.stepping)"),
    Method("mujoco_euler", 1, "mujoco", symplectic=False, symmetric=False, explicit=False, beta=lambda: 2.0,
           bind=_bind_splitting, summary="MuJoCo's Euler (MJCF's default): (M + h B) qacc = f with the joints' damping B "
                                         "implicit, qvel += h qacc, then qpos with the new qvel (semi-implicit)"),
    Method("implicitfast", 1, "mujoco", symplectic=False, symmetric=False, explicit=False, beta=lambda: 2.0,
           bind=_bind_splitting, summary="MuJoCo's implicitfast: (M - h D) qacc = f, D = d(passive + actuator)/d qvel "
                                         "symmetrised (Coriolis left out), then as mujoco_euler"),
    Method("implicit", 1, "mujoco", symplectic=False, symmetric=False, explicit=False, beta=lambda: 2.0,
           bind=_bind_splitting, summary="MuJoCo's implicit: D with the Coriolis and centrifugal derivative, solved by "
                                         "LU, then as mujoco_euler"),
    Method("reference", None, "rhs", symplectic=False, symmetric=False, explicit=True, beta=lambda: math.inf,
           bind=_bind_reference, summary="scipy DOP853 at rtol 1e-13: for checks only, never for speed",
           failure="a failed solve (scipy's DOP853 could not reach its tolerance)"),
)

BY_NAME: dict[str, Method] = {record.name: record for record in RECORDS}
METHODS: tuple[str, ...] = tuple(BY_NAME)
METHOD_ORDER: dict[str, int | None] = {record.name: record.order for record in RECORDS}
SYMPLECTIC: tuple[str, ...] = tuple(record.name for record in RECORDS if record.symplectic)
SYMMETRIC: tuple[str, ...] = tuple(record.name for record in RECORDS if record.symmetric)


def method(name: str) -> Method:
    """The record of method `name`; ValueError listing the valid names for any other."""
    try:
        return BY_NAME[name]
    except (KeyError, TypeError):
        raise ValueError(f"method={name!r}: expected one of {', '.join(map(repr, METHODS))}") from None


def applicable(model, preferred: tuple[str, ...] = ()) -> tuple[str, ...]:
    """Names of the methods whose needs `model` (a NativeModel) meets: those of `preferred` first, in its
    order, then the rest in METHODS order."""
    table = getattr(model, "constraints", None)  # a constrained tree: its layer's default scheme first
    if table is not None:  # its own order: its default scheme, the other, then MuJoCo's integrators
        preferred = tuple(table.methods)
    names = tuple(name for name in preferred if name in BY_NAME) + tuple(n for n in METHODS if n not in preferred)
    return tuple(name for name in names if BY_NAME[name].applies(model))


__all__ = ["Method", "RECORDS", "BY_NAME", "METHODS", "METHOD_ORDER", "SYMPLECTIC", "SYMMETRIC", "NEEDS", "method",
           "applicable", "yoshida6_interval", "gauss6_interval"]
