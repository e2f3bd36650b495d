"""The method records (rbody.engine.methods): each record's facts — order, symplectic, symmetric, stability
interval, what it needs — checked against what its compiled loop does on the harmonic oscillator, where every
one of them has a closed form; applicability and the stability rate read from a scene's native model, never
from its class (a user's own Scene subclass below)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
from numba import njit

import rbody
from rbody import MethodNotApplicable, Scene, SimulationError, simulate, stability
from rbody.engine import integrators, methods
from rbody.engine.native import NativeModel


# ----- the harmonic oscillator q'' = -k q, y = (q, v): every fact has a closed form --------------------------

@njit(cache=True)
def oscillator_rhs(y, p, out):
    out[0] = y[1]
    out[1] = -p[0] * y[0]


@njit(cache=True)
def oscillator_accel(q, p, out):
    out[0] = -p[0] * q[0]


@njit(cache=True)
def oscillator_verlet_step(y, p, h):
    """Kick-drift-kick over h: a scene's own symmetric one-step map (for the 'splitting' record)."""
    y[1] -= 0.5 * h * p[0] * y[0]
    y[0] += h * y[1]
    y[1] -= 0.5 * h * p[0] * y[0]


def oscillator(w, y0=(1.0, 0.0), *, accel=True, split=False, **extra) -> NativeModel:
    w = np.atleast_1d(np.asarray(w, dtype=np.float64))
    return NativeModel(y0=np.tile(np.asarray(y0, dtype=np.float64), (w.size, 1)), params=(w**2)[:, None],
                       rhs=oscillator_rhs, accel=oscillator_accel if accel else None,
                       split={"splitting": (oscillator_verlet_step, np.ones(1))} if split else {},
                       observe=lambda t, y: {"q": y[..., 0], "v": y[..., 1]}, **extra)


def run(record, model, dt, nsteps):
    """States (nsteps + 1, B, 2) of the record's loop, and failed (B,)."""
    out = np.empty((nsteps + 1,) + model.y0.shape)
    failed = record.integrate(model, np.ascontiguousarray(model.y0), np.ascontiguousarray(model.params), dt,
                              nsteps, 1, out)
    return out, failed


def step_matrix(record, w, dt) -> np.ndarray:
    """(2, 2): one step of the method on the oscillator (a linear map, columns from the unit states)."""
    model = dataclasses.replace(oscillator([w, w], split=True), y0=np.eye(2))
    out, _ = run(record, model, dt, 1)
    return out[1].T


# the constraint layer's own scheme (moreau) runs constrained trees only: its order is tested on them
# (tests/rbody/engine/test_constraint_scheme.py). MuJoCo's integrators step a tree (its mass matrix and velocity
# derivatives), not this oscillator: their records are checked on trees in test_mujoco_steps.py (order, stability
# limit, equality with MuJoCo).
ON_OSCILLATOR = [r for r in methods.RECORDS if r.needs not in ("constraints", "mujoco")]
FIXED_STEP = [r for r in ON_OSCILLATOR if r.name != "reference"]


# ----- the tables are the records ----------------------------------------------------------------------------

def test_tables_are_derived_from_the_records():
    assert rbody.METHODS == methods.METHODS == tuple(r.name for r in methods.RECORDS)
    assert rbody.METHOD_ORDER == {r.name: r.order for r in methods.RECORDS}
    assert set(methods.SYMMETRIC) == {r.name for r in methods.RECORDS if r.symmetric}
    assert set(methods.SYMPLECTIC) == {"symplectic_euler", "verlet", "yoshida6", "gauss6", "splitting"}
    for record in methods.RECORDS:
        assert stability.stability_interval(record.name) == record.interval


def test_unknown_method_and_unknown_need_are_value_errors():
    with pytest.raises(ValueError, match="method='rk5'.*'verlet'"):
        methods.method("rk5")
    with pytest.raises(ValueError, match="needs='jerk'"):
        methods.Method("x", 1, "jerk", symplectic=False, symmetric=False, explicit=True, beta=lambda: 1.0,
                       bind=lambda *a: None, summary="")


# ----- each record's facts against its loop -------------------------------------------------------------------

@pytest.mark.parametrize("record", [r for r in ON_OSCILLATOR if r.order is not None], ids=lambda r: r.name)
def test_observed_order_is_the_records(record):
    """Error at t = 1 of q = cos(w t) with w = 2, dt halved: the slope of log(error) is the record's order."""
    model = oscillator(2.0, split=True)
    errors = []
    for nsteps in (40, 80) if record.order < 6 else (10, 20):
        out, failed = run(record, model, 1.0 / nsteps, nsteps)
        assert failed[0] == -1
        errors.append(abs(out[-1, 0, 0] - math.cos(2.0)))
    assert math.log2(errors[0] / errors[1]) == pytest.approx(record.order, abs=0.25)


@pytest.mark.parametrize("record", FIXED_STEP, ids=lambda r: r.name)
def test_symplectic_is_an_area_preserving_step(record):
    """A linear step on the plane is symplectic exactly when its determinant is 1."""
    det = float(np.linalg.det(step_matrix(record, 2.0, 0.3)))
    if record.symplectic:
        assert det == pytest.approx(1.0, abs=1e-13)
    else:
        assert abs(det - 1.0) > 1e-6


@pytest.mark.parametrize("record", FIXED_STEP, ids=lambda r: r.name)
def test_symmetric_is_a_step_that_its_reverse_undoes(record):
    """Phi_{-h} Phi_h = identity for a symmetric method (time reversibility), and not for the others."""
    forward, backward = step_matrix(record, 2.0, 0.3), step_matrix(record, 2.0, -0.3)
    residual = float(np.max(np.abs(backward @ forward - np.eye(2))))
    if record.symmetric:
        assert residual < 1e-13
    else:
        assert residual > 1e-6


@pytest.mark.parametrize("record", [r for r in FIXED_STEP if r.interval > 0], ids=lambda r: r.name)
def test_interval_is_where_the_oscillation_stops_being_bounded(record):
    """Just inside the record's interval the loop keeps the amplitude bounded; just outside it grows (gauss6:
    its fixed-point iteration stops converging a little beyond 1 / (2 rho(A)), which keeps a margin of 2)."""
    beta = record.interval
    inside, _ = run(record, oscillator(1.0, split=True), 0.99 * beta, 2000)
    assert np.all(np.isfinite(inside)) and np.max(np.abs(inside[..., 0])) < 20.0
    if record.name == "gauss6":
        assert beta == pytest.approx(0.5 / np.max(np.abs(np.linalg.eigvals(integrators.GAUSS6_A))), rel=1e-15)
        _, failed = run(record, oscillator(1.0), 2.0 * 1.01 * beta, 50)
        assert failed[0] >= 1  # beyond the contraction limit the stage equations are not solved
        return
    outside, failed = run(record, oscillator(1.0, split=True), 1.01 * beta, 2000)
    assert failed[0] >= 0 or np.max(np.abs(outside[..., 0])) > 1e3


def test_euler_has_no_interval_its_amplitude_grows_at_any_step():
    record = methods.method("euler")
    assert record.interval == 0.0
    out, _ = run(record, oscillator(1.0), 0.01, 1000)
    energy = out[:, 0, 0] ** 2 + out[:, 0, 1] ** 2
    assert energy[-1] == pytest.approx((1 + 0.01**2) ** 1000, rel=1e-10)  # |1 + i dt w|^2 per step


# ----- applicability from the model, for a scene rbody has never seen ------------------------------------------

@dataclass(frozen=True, kw_only=True, eq=False)
class Spring(Scene):
    """A user's own scene: a mass on a spring, w [rad/s], its model chosen by the flags."""

    w: float = 2.0
    separable: bool = True
    own_rate: bool = False
    observables: ClassVar[tuple[str, ...]] = ("q", "v")

    def native(self) -> NativeModel:
        rate = (lambda method: np.array([self.w])) if self.own_rate else None
        return oscillator(self.w, accel=self.separable, rate=rate, rate_from_jacobian=not self.own_rate)


def test_methods_follow_from_what_the_model_provides():
    assert Spring(name="spring", t_end=1.0).methods == tuple(n for n in rbody.METHODS if n not in ("splitting", "moreau")
                                                             and methods.method(n).needs != "mujoco")
    plain = Spring(name="spring", t_end=1.0, separable=False)
    assert plain.methods == ("euler", "rk4", "gauss6", "reference")
    assert simulate(plain, dt=0.01).meta["method"] == "euler"  # the first that applies, verlet does not
    with pytest.raises(MethodNotApplicable) as error:
        simulate(plain, dt=0.01, method="yoshida6")
    message = str(error.value)
    assert "'yoshida6'" in message and "spring" in message and "q'' = a(q)" in message and "rk4" in message


def test_a_users_scene_runs_every_method_that_applies_to_the_closed_form():
    scene = Spring(name="spring", t_end=1.0)
    for name in scene.methods:
        q = simulate(scene, dt=1e-3, method=name)["q"]
        first_order = rbody.METHOD_ORDER[name] == 1  # error ~ w^2 t dt / 2 = 2e-3 (euler) or below
        assert q[-1] == pytest.approx(math.cos(2.0), abs=2e-3 if first_order else 1e-5), name


def test_events_method_is_refused_on_a_time_stepped_scene():
    with pytest.raises(MethodNotApplicable, match="event-driven"):
        simulate(Spring(name="spring", t_end=1.0), dt=0.01, method="events")


# ----- the stability rate from the model ---------------------------------------------------------------------

def test_rate_from_the_jacobian_of_a_users_model_gives_the_records_limits():
    scene = Spring(name="spring", t_end=1.0, w=3.0)
    assert stability.fastest_rate(scene, "rk4")[0] == pytest.approx(3.0, rel=1e-9)
    for record in methods.RECORDS:
        limit = stability.stability_limit(scene, record.name)
        if record.interval == 0.0:
            assert limit == pytest.approx(2 * math.log(2) / (9.0 * 1.0), rel=1e-8)
        else:
            assert limit == pytest.approx(record.interval / 3.0, rel=1e-8)
    with pytest.raises(SimulationError, match="stability limit"):
        simulate(scene, dt=1.01 * 2.0 / 3.0, method="verlet")


def test_a_models_own_rate_wins_over_its_jacobian():
    scene = Spring(name="spring", t_end=1.0, w=3.0, own_rate=True)
    assert stability.fastest_rate(scene, "verlet")[0] == 3.0
    assert stability.stability_limit(scene, "verlet") == 2.0 / 3.0


def test_rest_state_adds_the_fastest_normal_mode():
    """A pendulum (w0 = 2) held out horizontally: the Jacobian there has eigenvalues 0 (w0^2 cos(pi/2)); the
    model's rest state (the bottom) gives w0, the rate of the swing that follows. No rate stated: none (0)."""
    from rbody.scenes.pendulum import pendulum_rhs

    model = NativeModel(y0=np.array([[math.pi / 2, 0.0]]), params=np.array([[4.0, 1.0, 4.0]]), rhs=pendulum_rhs,
                        observe=None, rate_from_jacobian=True)
    assert stability.model_rate(model)[0] < 1e-6
    with_rest = dataclasses.replace(model, rest=np.zeros(2))
    assert stability.model_rate(with_rest)[0] == pytest.approx(2.0, rel=1e-9)
    assert stability.model_rate(dataclasses.replace(model, rate_from_jacobian=False))[0] == 0.0


def test_batch_rates_equal_the_rates_of_each_element():
    """The compiled batch Jacobian gives each element its own rate (no element's rate leaks into another's)."""
    w = np.random.default_rng(1).uniform(0.1, 50.0, 1000)
    rates = stability.jacobian_rate(oscillator_rhs, np.tile([0.3, -0.2], (w.size, 1)), (w**2)[:, None])
    np.testing.assert_allclose(rates, w, rtol=1e-8)


def test_kept_entry_points_give_the_dispatchers_bits_and_new_kinds_of_argument_are_typed_again():
    """integrators._launch skips numba's per-call typing once arguments of the same kinds were typed; an argument
    of another kind (a read-only y0, an int dt) goes through the dispatcher again, with the same result."""
    record = methods.method("verlet")
    model = oscillator([1.0, 2.0, 3.0])
    first, _ = run(record, model, 0.1, 50)
    again, _ = run(record, model, 0.1, 50)  # through the kept entry point
    np.testing.assert_array_equal(first, again)
    frozen = np.array(model.y0)
    frozen.setflags(write=False)
    out = np.empty((51,) + frozen.shape)
    record.integrate(model, frozen, np.ascontiguousarray(model.params), 0.1, 50, 1, out)
    np.testing.assert_array_equal(out, first)
    whole = np.empty((3,) + frozen.shape)
    record.integrate(model, frozen, np.ascontiguousarray(model.params), 1, 2, 1, whole)  # dt an int
    reference, _ = run(record, model, 1.0, 2)
    np.testing.assert_array_equal(whole, reference)
    loops = (integrators._composed_verlet_loop, integrators._SERIAL[integrators._composed_verlet_loop])
    kinds = {key[1:] for key in integrators._ENTRY_POINTS if key[0] in loops}
    assert len(kinds) >= 3  # writable y0 and float dt; read-only y0; int dt
