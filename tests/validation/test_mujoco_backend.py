"""The MuJoCo backend against the exact solutions.

Measured with mujoco 4.0 (python -m pytest tests/validation/test_mujoco_backend.py; the figures in the
tests): MuJoCo's RK4 on the swinging rod's hinge is rbody's RK4 on theta'' = -w0^2 sin(theta) to
round-off (8e-16), so its error is the method's: 1.07e-10 rad at dt = 2e-3 and 6.73e-12 at dt = 1e-3
over 2 s from theta0 = 1 (ratio 15.9: fourth order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from rbody import Inertia, Layout, Scene  # noqa: E402
from rbody.errors import SimulationError  # noqa: E402
from rbody.scenes import rolling, swinging_rod  # noqa: E402
from rbody.scenes.pendulum import SwingingRod  # noqa: E402
from validation.backends import mujoco as backend  # noqa: E402

pytestmark = pytest.mark.crosssim


def rod(t_end: float = 2.0):
    return swinging_rod(1.0, 1.0, theta0=1.0, t_end=t_end)


# ----- the swinging rod: a hinge, RK4 --------------------------------------------------------------

def test_hinge_carries_no_extra_physics():
    """No damping, armature, friction loss, spring or limit on the hinge: MuJoCo integrates the rod's
    own equation (otherwise it would not agree with rbody's RK4 to round-off below)."""
    model, _xml = backend.build(rod(), 1e-3)
    for field in ("dof_damping", "dof_armature", "dof_frictionloss", "jnt_stiffness"):
        assert np.all(getattr(model, field) == 0), field
    assert not np.any(model.jnt_limited)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4


def rk4_pendulum(theta0: float, w0_squared: float, dt: float, steps: int) -> np.ndarray:
    """theta (steps + 1,) of the classical RK4 on theta'' = -w0^2 sin(theta), from rest."""
    def f(y):
        return np.array([y[1], -w0_squared * math.sin(y[0])])

    y, out = np.array([theta0, 0.0]), [theta0]
    for _ in range(steps):
        k1 = f(y)
        k2 = f(y + dt / 2 * k1)
        k3 = f(y + dt / 2 * k2)
        k4 = f(y + dt * k3)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(y[0])
    return np.array(out)


def test_swinging_rod_rk4_is_fourth_order_against_the_exact_solution():
    """RK4's global error is C dt^4 + O(dt^5): halving dt divides it by 16 (observed order in
    [3.8, 4.2]); and MuJoCo's step is the classical RK4 on the rod's equation theta'' = -(3g/2L) sin(theta)
    to round-off (a few ulps of theta per step: <= 1e-13 after 2000 steps), so the error is the
    method's, not the model's."""
    scene = rod()
    errors = {}
    for dt in (2e-3, 1e-3):
        run = backend.run(scene, dt)
        exact = scene.exact(run.t)
        errors[dt] = np.max(np.abs(run["theta"] - exact["theta"]))
        reference = rk4_pendulum(1.0, 1.5 * 9.81, dt, run.t.size - 1)
        assert np.max(np.abs(run["theta"] - reference)) < 1e-13
        assert np.max(np.abs(run["energy"] - exact["energy"])) < 1e-9 * abs(exact["energy"][0])
    order = math.log2(errors[2e-3] / errors[1e-3])
    assert 3.8 < order < 4.2
    assert errors[1e-3] < 1e-11  # 6.7e-12 measured; C dt^4 with C = 6.7 rad/s^4 over 2 s
    assert run.meta["backend"] == "mujoco" and run.meta["integrator"] == "RK4"
    assert run.meta["mujoco_version"] == mujoco.__version__ and run.meta["step_seconds"] > 0


@dataclass(frozen=True, kw_only=True)
class WatchedRod(SwingingRod):
    """The swinging rod whose observables also report the body states MuJoCo gave."""

    def observe(self, t, bodies, joints):
        out = super().observe(t, bodies, joints)
        states = bodies["body"]
        out.update(com=states.com, velocity=states.velocity, omega_world=states.omega, quat=states.quat)
        return out


def test_body_states_are_centre_of_mass_and_world_frame():
    """From theta: com = (-L/2 sin, 0, -L/2 cos), v = w x com, omega = (0, theta', 0), quat = turn about y."""
    scene = WatchedRod(name="swinging_rod", t_end=0.5, length=1.0, mass=1.0, theta0=1.0)
    run = backend.run(scene, 1e-3, save_every=10)
    theta, omega = run["theta"], run["omega"]
    com = 0.5 * np.stack([-np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=1)
    w = np.stack([np.zeros_like(omega), omega, np.zeros_like(omega)], axis=1)
    np.testing.assert_allclose(run["com"], com, rtol=0, atol=1e-15)
    np.testing.assert_allclose(run["velocity"], np.cross(w, com), rtol=0, atol=1e-14)
    np.testing.assert_allclose(run["omega_world"], w, rtol=0, atol=1e-15)
    quat = np.stack([np.cos(theta / 2), 0 * theta, np.sin(theta / 2), 0 * theta], axis=1)
    np.testing.assert_allclose(run["quat"], quat, rtol=0, atol=1e-15)


def test_save_every_and_chunks_give_the_same_samples(monkeypatch):
    scene = rod(0.5)
    every = backend.run(scene, 1e-3)
    tenth = backend.run(scene, 1e-3, save_every=10)
    np.testing.assert_array_equal(tenth.t, every.t[::10])
    np.testing.assert_array_equal(tenth["theta"], every["theta"][::10])
    collisions = pytest.importorskip("rbody.scenes.collisions")
    impacts = collisions.pi_collisions(0, speed=1.0)
    whole = backend.run(impacts, 1e-3, save_every=10)
    # 70 steps per rollout call (rod: 2 x 3 state numbers + 13 sensors a step): same numbers, bit for bit,
    # the solver's warm start carried across the calls
    monkeypatch.setattr(backend, "_CHUNK_BYTES", 8 * 19 * 70)
    chunked = backend.run(scene, 1e-3, save_every=10)
    np.testing.assert_array_equal(chunked["theta"], tenth["theta"])
    pieces = backend.run(impacts, 1e-3, save_every=10)
    for name in ("positions", "velocities", "collisions", "ball_collisions"):
        np.testing.assert_array_equal(pieces[name], whole[name])
    assert whole["collisions"][-1] == 3


# ----- a free body: the angular velocity in the body frame ----------------------------------------------

def test_free_rotation_keeps_energy_and_angular_momentum():
    """The free joint's qvel holds omega in the body frame; the keyframe converts the scene's world
    omega. Written wrongly, omega_body is off by O(1) at once. RK4 at dt = 1e-3 over 2 s: energy within
    6.8e-15 relative and L_world within 5.8e-15 of |L| (measured), omega_body within 5.1e-14 rad/s of
    the exact Jacobi solution; at dt = 2e-3 these are 16 times larger (1.2e-13, 4.9e-14, 9.2e-13)."""
    free_rotation = pytest.importorskip("rbody.scenes.free_rotation").free_rotation
    body = Inertia.box(3.0, (0.2, 0.5, 0.9)).rotated([0.8, 0.3, 0.4, -0.1]).translated([0.1, -0.2, 0.3])
    scene = free_rotation(body, omega0=[1.0, 2.0, 0.5], t_end=2.0)
    run = backend.run(scene, 1e-3)
    exact = scene.exact(run.t)
    assert np.max(np.abs(run["omega_body"][0] - exact["omega_body"][0])) < 1e-14
    energy0, momentum = exact["energy"][0], np.linalg.norm(exact["L_world"][0])
    assert np.max(np.abs(run["energy"] - energy0)) < 1e-13 * energy0
    assert np.max(np.abs(run["L_world"] - exact["L_world"])) < 1e-13 * momentum
    assert np.max(np.abs(run["omega_body"] - exact["omega_body"])) < 1e-12


# ----- impacts: contact onsets ------------------------------------------------------------------------

def test_pi_collisions_count_from_contact_onsets():
    """The heavy ball 100 times the light one, at 0.1 m/s (10^-digits, so the light ball moves at
    about 1 m/s): 31 impacts, 16 between the balls. Euler with the undamped contact spring K = 1/dt^2
    returns each velocity reversed: the energy after the last impact is the initial one to 4.8e-13
    (measured) and the final velocities are the exact ones to 1e-10."""
    collisions = pytest.importorskip("rbody.scenes.collisions")
    scene = collisions.pi_collisions(1, speed=0.1)
    run = backend.run(scene, 1e-3)
    assert run.meta["integrator"] == "Euler"
    assert run["collisions"][-1] == scene.expected_collisions == 31
    assert run["ball_collisions"][-1] == 16
    assert np.all(np.diff(run["collisions"]) >= 0)
    exact = scene.exact(run.t[-1:])
    np.testing.assert_allclose(run["velocities"][-1], exact["velocities"][-1], rtol=0, atol=1e-10)
    assert abs(run["energy"][-1] / exact["energy"][-1] - 1) < 1e-12


def test_inelastic_impact_gives_the_restitution():
    """Head-on, masses 1 and 3 kg at +-1 m/s, e = 0.5: the 30-step spring-damper returns a relative
    velocity 0.482..0.501 of the approach over five contact phases (measured; an O(1/30) discretisation
    of the contact), and momentum exactly (the contact force is internal)."""
    collisions = pytest.importorskip("rbody.scenes.collisions")
    scene = collisions.line_collisions([1.0, 3.0], [1.0, 2.0], [1.0, -1.0], walls=(-100.0,), restitution=0.5,
                                       t_end=1.0)
    run = backend.run(scene, 1e-3)
    velocity = run["velocities"][-1]
    assert abs((velocity[1] - velocity[0]) / 2.0 - 0.5) < 0.02
    assert abs(velocity @ [1.0, 3.0] - (-2.0)) < 1e-12
    assert run["collisions"][-1] == 1 and run["ball_collisions"][-1] == 1


@pytest.mark.slow
def test_pi_collisions_two_digits():
    collisions = pytest.importorskip("rbody.scenes.collisions")
    scene = collisions.pi_collisions(2, speed=0.01)
    run = backend.run(scene, 1e-3, save_every=100)
    assert run["collisions"][-1] == scene.expected_collisions == 314
    assert run["ball_collisions"][-1] == 157


# ----- rolling: a frictional contact --------------------------------------------------------------------

def test_disc_rolls_without_slipping():
    """A disc on a 0.3 rad slope, mu = 1 (rolls): x = g sin(alpha) t^2 / 3. MuJoCo's contact is soft:
    the disc sinks a little and rolls on a radius shorter by that, so slip grows as -delta phi'.
    Measured at dt = 1e-3 over 1 s with the defaults (solref (2 dt, 1), solimp 0.99, elliptic cone,
    impratio 100): distance within 3.9e-7 m, slip 1.2e-6 m/s; with MuJoCo's own contact defaults
    (0.02 s, 0.9-0.95) 4.2e-4 m and 1.3e-3 m/s, which is why they are not used."""
    scene = rolling("disc", radius=0.1, incline=0.3, friction=1.0, t_end=1.0)
    run = backend.run(scene, 1e-3)
    exact = scene.exact(run.t)
    assert np.max(np.abs(run["distance"] - exact["distance"])) < 1e-6
    assert np.max(np.abs(run["slip"])) < 3e-6
    soft = backend.run(scene, 1e-3, solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001))
    assert np.max(np.abs(soft["slip"])) > 100 * np.max(np.abs(run["slip"]))


# ----- forces set from the scene ----------------------------------------------------------------------

def test_pair_force_is_evaluated_at_every_rk4_stage():
    """The two-body pair force is a MuJoCo passive force computed at each stage, so RK4 keeps its
    fourth order: r1 within 9.7e-11 m at dt = 2e-3 and 6.0e-12 m at dt = 1e-3 over 2 s (measured;
    a force held over the step would make it first order, errors ~1e-1 m). Gravity is off."""
    two_body = pytest.importorskip("rbody.scenes.two_body").two_body
    scene = two_body(1.0, 2.0, separation=(1.0, 0.0, 0.0), relative_velocity=(0.0, 0.0, 1.5), t_end=2.0)
    errors = []
    for dt in (2e-3, 1e-3):
        run = backend.run(scene, dt)
        errors.append(np.max(np.abs(run["r1"] - scene.exact(run.t)["r1"])))
    assert 3.8 < math.log2(errors[0] / errors[1]) < 4.2
    model, _xml = backend.build(scene, 1e-3)
    np.testing.assert_array_equal(model.opt.gravity, [0.0, 0.0, 0.0])
    assert mujoco.get_mjcb_passive() is None  # the callback is removed after the run


# ----- what MuJoCo does not run -------------------------------------------------------------------------

def test_check_refuses_batches_and_scenes_without_bodies():
    with pytest.raises(NotImplementedError, match="item"):
        backend.check(swinging_rod(1.0, theta0=[0.1, 0.2], t_end=1.0))
    particles = pytest.importorskip("rbody.scenes.particles")
    scene = particles.particles(3, seed=0, t_end=1.0)
    with pytest.raises(NotImplementedError, match="bodies and joints"):
        backend.check(scene)


def test_unstable_run_raises_instead_of_resetting():
    """MuJoCo resets a diverging state and goes on; the backend stops with SimulationError. A contact
    spring 1e12 times stiffer than K = 1/dt^2 makes qacc huge at the first impact."""
    collisions = pytest.importorskip("rbody.scenes.collisions")
    scene = collisions.pi_collisions(0, speed=1.0)
    with pytest.raises(SimulationError, match="unstable"):
        backend.run(scene, 1e-2, solref=(-1e16, 0.0))


# ----- roll joints: the rolling tree, a slide and a hinge tied by a joint equality ---------------------------

@dataclass(frozen=True, kw_only=True)
class RollingTree(Scene):
    """The rolling scene's reduced tree (one roll joint "roll"), observed from the joint's history (tests only)."""

    rolling: Any

    def _layout(self) -> Layout:
        return self.rolling.rolling_tree()

    def observe(self, t, bodies, joints):
        angle, rate = joints["roll"]
        radius = float(self.rolling.radius)
        return {"distance": radius * angle, "speed": radius * rate, "spin": rate,
                "com": bodies["body"].com}


def test_roll_joint_history_is_the_hinge_and_the_slip_is_reported():
    """Measured (mujoco 4.0, RK4, solid sphere a = 0.1 m on 0.5 rad, 1 s): the soft equality starts from rest
    with a transient, the spin 1.45e-4 then 1.76e-4 rad/s short after the first two steps at dt = 1e-3 (1.76e-5
    at 1e-4: first order in dt), gone to 4e-13 rad/s by t = 1 s; slide and a hinge then differ by at most
    1.35e-7 m (dt^2) and 2.47e-5 m/s (dt), the backend's meta["roll_slip"]."""
    radius, incline, dt = 0.1, 0.5, 1e-3
    scene = rolling("solid_sphere", radius=radius, incline=incline, t_end=1.0)
    tree = RollingTree(name="rolling_tree", t_end=1.0, rolling=scene)
    model, _xml = backend.build(tree, dt)
    assert not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)  # the equality is solved
    assert model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # nothing touches
    run = backend.run(tree, dt)
    exact = scene.exact(run.t)
    scale = exact["distance"][-1]
    # the soft equality's error (tests/rbody/test_mjcf.py: 5.7e-8 of the distance for the sphere at this dt)
    np.testing.assert_allclose(run["distance"], exact["distance"], rtol=0, atol=1e-7 * scale)
    spin_error = np.abs(run["spin"] - exact["spin"])
    assert np.max(spin_error) <= 0.25 * dt and spin_error[-1] <= 1e-10 * exact["spin"][-1], spin_error.max()
    down = np.array([math.cos(incline), 0.0, -math.sin(incline)])
    start = run["com"][0]
    np.testing.assert_allclose(run["com"] - start, run["distance"][:, None] * down, rtol=0, atol=1e-6 * scale)
    slip = run.meta["roll_slip"]["roll"]
    assert 0 < slip["max_position"] <= 0.2 * dt**2 and 0 < slip["max_rate"] <= 0.03 * dt, slip
