"""simulate(): argument checks, method choice, failures reported (never NaN returned), sampling, and the
Trajectory it returns (save/load round trip). The physics of the runs is tested with each scene."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

import rbody
from rbody import MethodNotApplicable, SimulationError, Trajectory, simulate
from rbody.scenes import pendulum_chain, rocket, rolling, swinging_rod, two_body


engine = importlib.import_module("rbody.simulation")  # the module (rbody.simulate is the function)
from rbody.engine import runner  # noqa: E402


@pytest.fixture
def rod():
    return swinging_rod(1.0, theta0=1.0, t_end=1.0)


# ----- arguments ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt, words", [(0.0, "dt"), (-1e-3, "dt"), (2.0, "t_end"), (np.nan, "finite"),
                                       (np.inf, "finite"), ([1e-3, 2e-3], "dt"), ("small", "dt")])
def test_bad_dt(rod, dt, words):
    with pytest.raises(ValueError, match=words):
        simulate(rod, dt=dt)


@pytest.mark.parametrize("t_end", [0.0, -1.0, np.nan, [1.0, 2.0]])
def test_bad_t_end(rod, t_end):
    with pytest.raises(ValueError, match="t_end"):
        simulate(rod, dt=1e-3, t_end=t_end)


def test_dt_equal_to_t_end_is_one_step():
    # rolling has constant accelerations: no step is beyond a stability limit
    scene = rolling("disc", radius=0.1, incline=0.3, t_end=1.0)
    run = simulate(scene, dt=1.0, method="rk4")
    np.testing.assert_array_equal(run.t, [0.0, 1.0])
    assert run["distance"][-1] == pytest.approx(scene.exact([1.0])["distance"][0], rel=1e-14)


def test_unknown_method_lists_the_valid_ones(rod):
    with pytest.raises(ValueError, match="method='rk5'") as error:
        simulate(rod, dt=1e-3, method="rk5")
    for name in rbody.METHODS:
        assert repr(name) in str(error.value)


def test_method_not_applicable_is_a_value_error():
    chain = pendulum_chain(2, theta0=[1.0, 0.5], t_end=1.0)
    with pytest.raises(MethodNotApplicable) as error:
        simulate(chain, dt=1e-3, method="verlet")
    assert isinstance(error.value, ValueError)
    assert "separable" in str(error.value) and "gauss6" in str(error.value)  # why, and what applies
    with pytest.raises(ValueError):
        simulate(chain, dt=1e-3, method="yoshida6")
    rod = swinging_rod(1.0, theta0=1.0, t_end=1.0)
    with pytest.raises(MethodNotApplicable, match="splitting"):
        simulate(rod, dt=1e-3, method="splitting")


@pytest.mark.parametrize("save_every", [0, -2, 2.0, 1.5, "2", True, None])
def test_bad_save_every(rod, save_every):
    with pytest.raises(ValueError, match="save_every"):
        simulate(rod, dt=1e-3, save_every=save_every)


def test_not_a_scene():
    with pytest.raises(ValueError, match="Scene"):
        simulate({"theta0": 1.0}, dt=1e-3)


def test_default_method_is_verlet_where_it_applies(rod):
    assert simulate(rod, dt=1e-2).meta["method"] == "verlet"


# ----- failures -----------------------------------------------------------------------------------------


def test_step_beyond_the_stability_limit_is_refused_before_any_step():
    """rk4 keeps an oscillation bounded while dt w0 < 2 sqrt(2) (rbody.engine.stability): at dt = 1 s on the rod
    (w0 = 3.84 rad/s) simulate refuses, naming the limit it estimated, instead of returning a wrong run."""
    rod = swinging_rod(1.0, theta0=1.0, t_end=10.0)
    with pytest.raises(SimulationError, match=r"stability limit 0\.737\d* s") as error:
        simulate(rod, dt=1.0, method="rk4")
    assert "swinging_rod" in str(error.value) and "use dt <=" in str(error.value)


def test_non_finite_state_raises_and_names_scene_time_and_step():
    """A step that overflows: two bodies flung apart at 1e10 m/s with dt = 1e300 s reach x = inf at the
    first step. (The two-body scene has no stability estimate, so the loop itself must catch it.)"""
    # The factory refuses a scene whose exact motion overflows by t_end; the class itself (replace) does not,
    # which is what this test needs: the loop's own guard.
    scene = dataclasses.replace(two_body(1.0, 1.0, separation=1.0, relative_velocity=1e10, t_end=1.0), t_end=1e305)
    with pytest.raises(SimulationError) as error:
        simulate(scene, dt=1e300, method="euler")
    message = str(error.value)
    assert "two_body" in message and "dt=1e+300" in message and "t=1e+300 s" in message
    assert "non-finite" in message


def test_failure_names_the_batch_element():
    # element 1 exhausts at 1e308 m/s: within its 5 s burn its speed passes the largest float; elements
    # 0 and 2 stay finite (a burn longer than the step: one shorter is refused before any step)
    batch = dataclasses.replace(rocket(1.0, burn_rate=0.1, exhaust_speed=[1.0, 1.0, 2.0], dry_mass=0.5, t_end=10.0),
                                exhaust_speed=[1.0, 1e308, 2.0])  # past the factory's check that exact() is finite
    with pytest.raises(SimulationError, match="batch element 1 of 3"):
        simulate(batch, dt=1.0, method="euler")


def test_gauss6_reports_stage_equations_it_cannot_solve():
    """dt = 1 s on a whirling rod (|df/dy| ~ 20 /s): simulate refuses it beyond gauss6's limit, and the
    compiled loop itself, run there anyway, reports the step whose fixed-point iteration diverged."""
    whirling = swinging_rod(1.0, theta0=1.0, omega0=20.0, t_end=10.0)
    with pytest.raises(SimulationError, match="stability limit"):
        simulate(whirling, dt=1.0, method="gauss6")
    model = whirling.native()
    out = np.empty((11,) + model.y0.shape)
    failed = runner._integrate(model, "gauss6", 1.0, 10, 1, out)
    assert failed[0] >= 1
    # at dt = 0.01 it converges and the run is accurate
    run = simulate(whirling, dt=1e-2, method="gauss6", t_end=1.0)
    assert np.max(np.abs(run["theta"] - whirling.exact(run.t)["theta"])) < 1e-9


def test_simulation_error_is_a_runtime_error_not_a_value_error():
    assert issubclass(SimulationError, RuntimeError)
    assert not issubclass(SimulationError, ValueError)
    assert issubclass(MethodNotApplicable, SimulationError)


# ----- sampling and the time grid -----------------------------------------------------------------------


@pytest.mark.parametrize("method", ["verlet", "rk4", "gauss6"])
def test_save_every_keeps_every_nth_state(method):
    scene = swinging_rod(1.0, theta0=1.0, t_end=2.0)
    full = simulate(scene, dt=1e-3, method=method)
    sampled = simulate(scene, dt=1e-3, method=method, save_every=50)
    assert sampled.t.size == 2000 // 50 + 1
    np.testing.assert_allclose(sampled.t, full.t[::50], rtol=1e-15, atol=0)
    for name in ("theta", "omega", "energy"):
        np.testing.assert_array_equal(sampled[name], full[name][::50])


def test_time_grid_rounds_up_to_cover_t_end():
    scene = swinging_rod(1.0, theta0=1.0, t_end=1.0)
    run = simulate(scene, dt=0.3, method="rk4")  # 1/0.3 = 3.33 -> 4 steps
    np.testing.assert_allclose(run.t, [0.0, 0.3, 0.6, 0.9, 1.2], rtol=1e-15)
    run = simulate(scene, dt=0.1, method="rk4")  # 1/0.1 = 10.000000000000002 is 10 steps, not 11
    assert run.t.size == 11 and run.t[-1] == pytest.approx(1.0, rel=1e-15)
    run = simulate(scene, dt=0.1, method="rk4", save_every=3)  # 10 steps -> 12, a multiple of 3
    np.testing.assert_allclose(run.t, [0.0, 0.3, 0.6, 0.9, 1.2], rtol=1e-15)
    run = simulate(scene, dt=0.1, method="rk4", t_end=0.5)
    assert run.t[-1] == pytest.approx(0.5, rel=1e-15)


def test_trajectory_shapes_and_meta():
    batch = swinging_rod([0.5, 1.0], theta0=[[0.1], [0.2], [0.3]], t_end=1.0)
    run = simulate(batch, dt=0.01, method="rk4")
    assert run["theta"].shape == (101, 3, 2)
    assert run.observables == ("theta", "omega", "energy")
    assert run.meta == {"scene": "swinging_rod", "backend": "rbody", "method": "rk4", "dt": 0.01}
    np.testing.assert_array_equal(run.t, np.arange(101) * 0.01)


# ----- Trajectory ---------------------------------------------------------------------------------------


def test_trajectory_save_load_round_trip(tmp_path):
    chain = pendulum_chain(3, theta0=[[0.3, 0.2, 0.1], [1.0, 0.0, -1.0]], t_end=0.5)
    run = simulate(chain, dt=1e-2, method="rk4", save_every=5)
    path = run.save(tmp_path / "chain")  # the suffix is added
    assert path.suffix == ".npz" and path.exists()
    loaded = Trajectory.load(path)
    np.testing.assert_array_equal(loaded.t, run.t)
    assert loaded.observables == run.observables
    for name in run.observables:
        np.testing.assert_array_equal(loaded[name], run[name])
        assert loaded[name].dtype == run[name].dtype
    assert loaded.meta == run.meta
    assert loaded.final("theta").shape == (2, 3)


def test_trajectory_rejects_mismatched_lengths_and_unknown_names():
    with pytest.raises(ValueError, match="observable 'x'"):
        Trajectory(np.arange(3.0), {"x": np.zeros(4)})
    run = Trajectory(np.arange(3.0), {"x": np.zeros(3)})
    with pytest.raises(KeyError, match="'y'"):
        run["y"]


# ----- methods from the native model, for every family -----------------------------------------------------------

def test_each_familys_method_tuple_is_what_its_model_provides():
    """Scene modules may still list their methods; the records decide what applies, and the two agree (the lists
    can be derived from the records: rbody.engine.methods.applicable(model, preferred))."""
    from rbody.engine.methods import applicable
    from rbody.scene import Scene as Base
    from rbody.scenes import free_rotation

    from tests.rbody.test_fuzz_scenes import FACTORIES

    scenes = [factory(**arguments) for factory, arguments in FACTORIES.values()]
    scenes.append(free_rotation(rbody.Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])), omega0=(0.1, 2.0, 0.1),
                                t_end=1.0))
    checked = 0
    for scene in scenes:
        if scene.event_driven:
            assert scene.methods == ()
            continue
        derived = Base.methods.fget(scene)  # the base class's: from the native model
        assert set(scene.methods) == set(derived) == set(applicable(scene.native_model)), scene.name
        checked += 1
    assert checked >= 8


# ----- a mass matrix that becomes singular during a run ------------------------------------------------------------

def gimbal(**joint_changes):
    """A body held at its centre by three hinges z, y, z (Euler angles), turning about y at 1 rad/s from a middle
    angle of 0.5 rad, no gravity: the first and last axes line up, and M is singular, at t = 0.5 s."""
    body = rbody.Body("ball", rbody.Inertia(1.0, (0, 0, 0), np.diag([0.4, 0.5, 0.6])))
    joints = (rbody.Joint("yaw", "hinge", "ball", axis=(0, 0, 1)),
              rbody.Joint("pitch", "hinge", "ball", axis=(0, 1, 0), qpos0=0.5, qvel0=-1.0),
              rbody.Joint("roll", "hinge", "ball", axis=(0, 0, 1), **joint_changes))
    return rbody.Scene.from_layout(rbody.Layout((body,), joints), t_end=1.0, gravity=0.0, name="gimbal")


@pytest.mark.parametrize("method, dt, save_every", [("euler", 0.01, 3), ("rk4", 0.01, 1), ("rk4", 0.02, 7),
                                                    ("rk4", 0.1, 1)])
def test_singular_mass_matrix_during_a_run_names_time_body_and_joint(method, dt, save_every):
    with pytest.raises(SimulationError) as error:
        simulate(gimbal(), dt=dt, method=method, save_every=save_every)
    message = str(error.value)
    assert "gimbal" in message and "singular" in message and "'ball'" in message and "'yaw'" in message
    time = float(message.split(" at t=")[1].split(" s")[0])
    assert 0.5 - 1e-9 <= time <= 0.5 + dt + 1e-9  # the step that met (or followed) the singular pose


def test_a_run_that_stays_away_from_the_singular_pose_is_not_refused():
    """Armature on the last hinge keeps M regular: the same motion runs through t = 0.5 s (the middle angle
    crosses 0 and goes on at -1 rad/s, the other two stay 0 by symmetry)."""
    run = simulate(gimbal(armature=0.1), dt=0.01, method="rk4")
    np.testing.assert_allclose(run["qpos"][-1], [0.0, -0.5, 0.0], rtol=0, atol=1e-12)


def test_a_non_finite_state_of_a_tree_far_from_any_singular_pose_says_only_what_it_knows():
    """A blow-up that is not a singular M (euler far beyond any limit on a regular tree) is not blamed on a joint."""
    scene = gimbal(armature=0.1)
    record = importlib.import_module("rbody.engine.methods").method("euler")
    model = scene.native_model
    y = np.ascontiguousarray(model.y0)
    assert model.diagnose(y[0], y[0], 0.01) == ""
    out = np.empty((2,) + y.shape)
    out[0] = y
    out[1] = np.nan
    error = runner.failure(scene.describe(), model, record, 0.01, 1, out, np.array([1]))
    assert "non-finite" in str(error) and "singular" not in str(error)


def test_small_runs_do_not_read_the_memory_available(monkeypatch, rod):
    def unavailable():
        raise AssertionError("read the memory for a run of a few kB")

    monkeypatch.setattr(engine, "available_memory", unavailable)
    assert simulate(rod, dt=1e-2).t.size == 101


@pytest.mark.parametrize("scene_name", ["rod", "chain", "rotation"])
def test_the_stability_limit_is_the_same_on_the_hand_kernel_and_on_the_engine(monkeypatch, scene_name):
    """A family's rate comes from what it is, not from which native model runs it: the rod released
    horizontally (its Jacobian there is 0, its rate w0), a chain, a tumbling body."""
    from rbody import stability
    from rbody.scenes import free_rotation

    chain_module, pendulum_module, rotation_module = (importlib.import_module(f"rbody.scenes.{name}")
                                                      for name in ("chain", "pendulum", "free_rotation"))

    def build():
        if scene_name == "rod":
            return swinging_rod(1.0, theta0=np.pi / 2, t_end=1.0)
        if scene_name == "chain":
            return pendulum_chain(2, theta0=[1.0, 0.5], t_end=1.0)
        return free_rotation(rbody.Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])),
                                           omega0=(0.1, 2.0, 0.1), t_end=1.0)

    limits = []
    for fast in (True, False):
        monkeypatch.setattr(pendulum_module, "FAST_PATH", fast)
        monkeypatch.setattr(rotation_module, "FAST_PATH", fast)
        monkeypatch.setattr(chain_module, "HAND_KERNEL_MAX_LINKS", chain_module.MAX_LINKS if fast else 0)
        scene = build()
        limits.append([stability.stability_limit(scene, m) for m in ("rk4", "gauss6")])
    np.testing.assert_allclose(limits[0], limits[1], rtol=1e-6)
    if scene_name == "rod":
        w0 = np.sqrt(1.5 * 9.81)
        assert limits[1][0] == pytest.approx(2 * np.sqrt(2) / w0, rel=1e-12)
