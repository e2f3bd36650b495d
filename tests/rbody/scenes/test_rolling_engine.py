"""The rolling scenes on the general engine: a roll joint per body (Rolling.rolling_tree), against the closed
form x'' = g sin(alpha) / (1 + k) and against the hand kernel rolling_rhs (the engine's oracle).

A rolling body's accelerations are constant, so rk4 and verlet are exact up to round-off: every comparison
here is to round-off of the quantities compared (1e-12 of their scale).
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import rbody
from rbody import Inertia, Scene
from rbody.scenes import rolling, rolling_race
from rbody.scenes.rolling import rolling_rhs

rolling_module = importlib.import_module("rbody.scenes.rolling")  # the module (rbody.scenes.rolling is the factory)

G = 9.81
RATIO = {"disc": 1 / 2, "hollow_cylinder": 1.0, "solid_sphere": 2 / 5, "spherical_shell": 2 / 3}
METHODS = ("rk4", "verlet")
# An Inertia body that is none of the named ones: a yo-yo (thin disc of radius sqrt(6) a on an axle of radius
# a, k = 3), its centre of mass off the body origin.
YOYO = Inertia.disc(0.5, np.sqrt(6) * 0.1, axis="y").translated([0.03, -0.02, 0.01])
BODIES = [*RATIO, YOYO]
IDS = [*RATIO, "inertia"]


def _close(got, want, scale, rtol=1e-12):
    np.testing.assert_allclose(np.asarray(got, float), np.asarray(want, float), rtol=0, atol=rtol * scale)


def on_engine(scene):
    """The scene with the general engine as its native model (whatever FAST_PATH chooses for native())."""
    scene.__dict__["native_model"] = scene.engine_native()  # the cached model (a scene is otherwise frozen)
    assert scene.native_model.rhs is engine_rhs(scene)
    return scene


def engine_rhs(scene):
    """The right-hand side the general engine gives the scene's rolling tree (Scene.from_layout), whichever of
    its kernels that is (a planar tree's, or the general one)."""
    tree = scene.item((0,) * len(scene.batch_shape)).rolling_tree()  # the first element of a batch
    rhs = Scene.from_layout(tree, t_end=1.0).native().rhs
    assert rhs is not rolling_rhs
    return rhs


def on_kernel(scene):
    """The scene with the hand kernel rolling_rhs, the engine's oracle, as its native model."""
    scene.__dict__["native_model"] = scene.kernel_native()
    assert scene.native_model.rhs is rolling_rhs
    return scene


# ----- one body, every named body and an Inertia body, rk4 and verlet --------------------------------------

@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("body", BODIES, ids=IDS)
def test_engine_run_equals_the_closed_form(body, method):
    radius, incline = 0.1, 0.5
    scene = on_engine(rolling(body, radius=radius, incline=incline, t_end=1.0))
    assert scene.rolls
    run = rbody.simulate(scene, dt=1e-3, method=method)
    exact = scene.exact(run.t)
    k = RATIO[body] if isinstance(body, str) else body.tensor[1, 1] / (body.mass * radius**2)
    accel = G * np.sin(incline) / (1 + k)
    assert scene.acceleration == pytest.approx(accel, rel=1e-14)
    for name, scale in (("distance", accel / 2), ("speed", accel), ("spin", accel / radius)):
        _close(run[name], exact[name], scale)
    assert np.all(run["slip"] == 0)  # held by the coordinate
    mass = scene.mass
    _close(run["energy"], exact["energy"], mass * G * np.sin(incline) * accel / 2)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("body", BODIES, ids=IDS)
def test_engine_and_hand_kernel_agree_to_round_off(body, method):
    engine = rbody.simulate(on_engine(rolling(body, radius=0.1, incline=0.7, t_end=1.0)), dt=1e-3, method=method)
    kernel = rbody.simulate(on_kernel(rolling(body, radius=0.1, incline=0.7, t_end=1.0)), dt=1e-3, method=method)
    for name in ("distance", "speed", "spin", "slip", "energy"):
        scale = max(float(np.max(np.abs(kernel[name]))), float(np.max(np.abs(kernel["speed"]))))
        _close(engine[name], kernel[name], scale)


def test_the_engine_accelerations_are_the_kernels():
    """One evaluation: the engine's q'' = x'' / a of the hand kernel, q' carried, for each body."""
    for body in BODIES:
        scene = rolling(body, radius=0.15, incline=0.4)
        engine, kernel = scene.engine_native(), scene.kernel_native()
        y = np.array([0.3, 2.0])
        out = np.empty(2)
        engine.rhs(y, np.ascontiguousarray(engine.params[0]), out)
        want = np.empty(4)
        kernel.rhs(np.array([0.045, 0.3, 0.3, 2.0]), np.ascontiguousarray(kernel.params[0]), want)
        assert out[0] == 2.0
        assert out[1] == pytest.approx(want[3], rel=1e-14)
        if engine.accel is not None:
            accel = np.empty(1)
            engine.accel(y[:1].copy(), np.ascontiguousarray(engine.params[0]), accel)
            assert accel[0] == pytest.approx(want[3], rel=1e-14)


# ----- the tree: l = y x n points down the slope ------------------------------------------------------------

@pytest.mark.parametrize("incline", [0.2, 0.5, 1.2])
def test_rolling_tree_moves_the_centre_down_the_slope_and_holds_the_contact(incline):
    radius = 0.2
    scene = rolling("solid_sphere", radius=radius, incline=incline)
    tree = scene.rolling_tree()
    (joint,) = tree.joints
    down = np.array([np.cos(incline), 0.0, -np.sin(incline)])
    normal = np.array([np.sin(incline), 0.0, np.cos(incline)])
    np.testing.assert_allclose(joint.line, down, rtol=0, atol=1e-15)
    assert joint.kind == "roll" and joint.radius == radius
    model = Scene.from_layout(tree, t_end=1.0).multibody
    angle, rate = np.array([[0.0], [0.7]]), np.array([[0.0], [1.3]])
    states = model.body_states(angle, rate)
    com, velocity, omega = states["com"][:, 0], states["velocity"][:, 0], states["omega"][:, 0]
    np.testing.assert_allclose(com[1] - com[0], radius * 0.7 * down, rtol=0, atol=1e-15)
    np.testing.assert_allclose(velocity[1], radius * 1.3 * down, rtol=0, atol=1e-15)
    np.testing.assert_allclose(omega[1], [0.0, 1.3, 0.0], rtol=0, atol=1e-15)
    # the contact point, a below the centre along -n, is at rest
    np.testing.assert_allclose(velocity[1] + np.cross(omega[1], -radius * normal), 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(com[0], radius * normal, rtol=0, atol=1e-15)


def test_engine_energy_of_the_tree_is_conserved():
    """The engine's own energy (kinetic of the roll joint + gravity), not the scene's formula: constant."""
    scene = rolling("disc", radius=0.1, incline=0.5, t_end=1.0)
    tree_scene = Scene.from_layout(scene.rolling_tree(), t_end=1.0)
    run = rbody.simulate(tree_scene, dt=1e-3, method="rk4")
    energy = run["energy"]
    scale = scene.mass * G * np.sin(0.5) * float(scene.exact([1.0])["distance"][0])
    _close(energy - energy[0], 0.0, scale)
    _close(0.1 * run["qpos"][:, 0], scene.exact(run.t)["distance"], scale)


# ----- batches ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_batch_of_radii_and_inclines_runs_on_the_engine(method):
    radius = np.array([[0.05], [0.1], [0.3]])
    incline = np.array([0.2, 0.6, 1.0, 0.6])
    scene = on_engine(rolling("hollow_cylinder", radius=radius, incline=incline, t_end=0.8))
    assert scene.batch_shape == (3, 4)
    run = rbody.simulate(scene, dt=1e-3, method=method)
    exact = scene.exact(run.t)
    assert run["distance"].shape == (run.t.size, 3, 4)
    accel = np.max(G * np.sin(incline) / 2)
    for name, scale in (("distance", accel), ("speed", accel), ("spin", accel / 0.05)):
        _close(run[name], exact[name], scale)
    for index in [(0, 0), (2, 3), (1, 2)]:
        single = rbody.simulate(on_engine(scene.item(index)), dt=1e-3, method=method)
        _close(run["distance"][(slice(None),) + index], single["distance"], accel)


def test_sliding_keeps_the_hand_kernel_and_the_engine_refuses_it():
    sliding = rolling("disc", radius=0.1, incline=0.5, friction=0.05)
    assert not sliding.rolls
    assert sliding.native_model.rhs is rolling_rhs
    with pytest.raises(ValueError, match="slides"):
        sliding.engine_native()
    mixed = rolling("disc", radius=0.1, incline=0.5, friction=np.array([0.05, 1.0]), t_end=0.5)
    assert mixed.native_model.rhs is rolling_rhs  # one call, one right-hand side for the whole batch
    run = rbody.simulate(mixed, dt=1e-3, method="verlet")
    _close(run["distance"], mixed.exact(run.t)["distance"], 1.0)


# ----- the race ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_race_on_the_engine_equals_the_closed_form(method):
    bodies = ("disc", "hollow_cylinder", "solid_sphere", "spherical_shell", YOYO)
    race = on_engine(rolling_race(bodies, radius=0.1, incline=0.3, length=1.0, mass=0.5))
    assert race.native_model.y0.shape == (1, 2 * len(bodies))  # one tree, one roll joint per body
    run = rbody.simulate(race, dt=1e-3, method=method)
    exact = race.exact(run.t)
    accel = float(np.max(race.acceleration))
    for name, scale in (("distance", accel), ("speed", accel), ("spin", accel / 0.1)):
        assert run[name].shape == (run.t.size, len(bodies))
        _close(run[name], exact[name], scale)
    assert np.all(run["slip"] == 0)
    np.testing.assert_allclose(run["arrival_time"][-1], race.arrival_time, rtol=1e-12)
    kernel = rbody.simulate(on_kernel(rolling_race(bodies, radius=0.1, incline=0.3, length=1.0, mass=0.5)),
                            dt=1e-3, method=method)
    for name in ("distance", "speed", "spin", "energy", "arrival_time"):
        _close(run[name], kernel[name], max(1.0, float(np.max(np.abs(kernel[name])))))


def test_race_with_a_sliding_body_keeps_the_hand_kernel():
    race = rolling_race(("disc", "hollow_cylinder"), radius=0.1, incline=0.5, length=1.0, friction=0.2)
    assert list(race.rolls) == [True, False]
    assert race.native_model.rhs is rolling_rhs
    with pytest.raises(ValueError, match="slide"):
        race.engine_native()


@pytest.mark.parametrize("fast", [True, False])
def test_native_follows_fast_path_where_the_body_rolls(monkeypatch, fast):
    monkeypatch.setattr(rolling_module, "FAST_PATH", fast)
    for scene in (rolling("disc", radius=0.1, incline=0.5), rolling("disc", radius=np.array([0.1, 0.2]), incline=0.5),
                  rolling_race(radius=0.1, incline=0.5, length=1.0)):
        assert scene.native_model.rhs is (rolling_rhs if fast else engine_rhs(scene))
