"""rbody.prepare: a run's checks, model and bound loop made once (rbody/simulation.py), and simulate built on it.

A prepared run must give exactly what simulate gives (bit for bit: the same loop on the same numbers), start a
tree from any state it is given as the scene would start from it, and refuse what simulate refuses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Scene, SimulationError, simulate
from rbody.engine import integrators
from rbody.scenes import pendulum_chain, swinging_rod
from rbody.simulation import PreparedRun, prepare


def double_pendulum(**kwargs) -> Scene:
    upper = Body("upper", Inertia.rod(1.0, 0.8, "z").translated([0, 0, -0.4]))
    lower = Body("lower", Inertia.rod(0.5, 0.5, "z").translated([0, 0, -0.25]), parent="upper", pos=(0, 0, -0.8))
    layout = Layout(bodies=(upper, lower), joints=(Joint("shoulder", "hinge", "upper", axis=(0, 1, 0), qpos0=1.0),
                                                  Joint("elbow", "hinge", "lower", axis=(1, 1, 0), qpos0=0.3)))
    return Scene.from_layout(layout, t_end=0.5, **kwargs)


def test_prepare_is_kept_with_the_scene_and_simulate_uses_it():
    rod = swinging_rod(1.0, theta0=1.0, t_end=0.2)
    first = prepare(rod, dt=1e-3, method="rk4")
    assert isinstance(first, PreparedRun)
    assert prepare(rod, dt=1e-3, method="rk4") is first
    assert prepare(rod, dt=2e-3, method="rk4") is not first
    assert prepare(rod, dt=1e-3, method="verlet") is not first
    a, b = first.run(), simulate(rod, dt=1e-3, method="rk4")
    np.testing.assert_array_equal(a["theta"], b["theta"])
    np.testing.assert_array_equal(a.t, first.t)
    assert a.meta == b.meta == {"scene": rod.name, "backend": "rbody", "method": "rk4", "dt": 1e-3}


def test_repeated_runs_are_equal_and_independent():
    rod = swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 7), t_end=0.1)
    run = prepare(rod, dt=1e-3, method="rk4")
    one, two = run.run(), run.run()
    assert one["theta"] is not two["theta"]
    np.testing.assert_array_equal(one["theta"], two["theta"])
    assert one["theta"].shape == (101, 7)


def test_the_bound_entry_point_gives_the_bits_of_the_typed_call():
    """integrators.Bound called twice (the second time through its kept entry point) and launched (typed)."""
    scene = double_pendulum()
    model = scene.native_model
    bound = integrators.bind_rk4(model.rhs, 1, 1e-3, 50, 1, finish=model.finish)
    y0, params = np.array(model.y0), np.array(model.params)
    outs = [np.empty((51, 1, y0.shape[1])) for _ in range(3)]
    bound.launch(y0, params, outs[0])
    bound(y0, params, outs[1])
    assert bound.entry is not None
    bound(y0, params, outs[2])
    np.testing.assert_array_equal(outs[0], outs[1])
    np.testing.assert_array_equal(outs[0], outs[2])


@pytest.mark.parametrize("planar", [True, False], ids=["planar path", "3-D path"])
def test_a_tree_started_from_a_given_state_equals_the_scene_built_with_it(planar):
    scene = pendulum_chain(2, theta0=[0.5, 0.3], t_end=0.5) if planar else double_pendulum()
    tree = scene if isinstance(scene, rbody.scene.TreeScene) else Scene.from_layout(scene.layout, t_end=0.5)
    qpos, qvel = np.array([0.2, -0.4]), np.array([1.0, 0.5])
    run = prepare(tree, dt=1e-3, method="rk4")
    given = run.run(qpos0=qpos, qvel0=qvel)
    built = simulate(dataclasses.replace(tree, qpos0=qpos, qvel0=qvel), dt=1e-3, method="rk4")
    for name in ("qpos", "qvel", "energy"):
        np.testing.assert_array_equal(given[name], built[name])
    np.testing.assert_array_equal(run.run()["qpos"], simulate(tree, dt=1e-3, method="rk4")["qpos"])  # unchanged


def test_a_given_state_is_checked_as_the_scene_checks_its_own():
    tree = double_pendulum()
    run = prepare(tree, dt=1e-3, method="rk4")
    with pytest.raises(ValueError, match=r"qpos0 has shape \(3,\): expected \(\.\.\., 2\)"):
        run.run(qpos0=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="qvel0 holds NaN"):
        run.run(qvel0=[np.nan, 0.0])
    with pytest.raises(ValueError, match="batch of 3 states: this run was prepared for 1"):
        run.run(qpos0=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="qpos0 and qvel0 are for trees"):
        prepare(swinging_rod(1.0, theta0=1.0, t_end=0.1), dt=1e-3).run(qpos0=[0.1])


def test_a_step_beyond_the_stability_limit_is_refused_when_prepared():
    """A hinge spring of stiffness k on a unit moment of inertia: w = sqrt(k) = 1000 rad/s; rk4 is stable while
    dt w < 2 sqrt 2, so dt = 1e-2 is refused by prepare (before any run) and dt = 1e-3 runs from any angle."""
    body = Body("wheel", Inertia(1.0, np.zeros(3), np.eye(3)))
    layout = Layout(bodies=(body,), joints=(Joint("spin", "hinge", "wheel", axis=(0, 0, 1), stiffness=1e6),))
    tree = Scene.from_layout(layout, t_end=0.01, gravity=0.0)
    with pytest.raises(SimulationError, match="stability limit"):
        prepare(tree, dt=1e-2, method="rk4")
    run = prepare(tree, dt=1e-3, method="rk4")
    assert np.all(np.isfinite(run.run(qpos0=[0.5])["qpos"]))


def test_an_unstable_step_at_a_given_state_is_refused():
    """A step half the limit at the scene's own state (the double pendulum released from rest) is refused at a
    state spinning 50 times faster than its rate w: the Coriolis and centrifugal terms of the linearised motion
    grow with the speed, so the fastest rate there is far above w."""
    tree = double_pendulum()
    rate = float(np.max(rbody.stability.fastest_rate(tree, "rk4")))
    limit = 2 * np.sqrt(2) / rate
    run = prepare(tree, dt=0.5 * limit, method="rk4", t_end=10 * limit)
    with pytest.raises(SimulationError, match="at the initial state given"):
        run.run(qvel0=[50 * rate, -50 * rate])  # fast spin: the gyroscopic terms raise the rate far beyond w0
