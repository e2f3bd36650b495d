"""The roll joint of the general engine (a round body rolling without slipping on a line): against its exact
reduction to a slide followed by a hinge, the closed form of the chapter's rolling bodies on an incline, and
rk4's energy error and order on a wheel carrying a pendulum."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Multibody, Scene

sys.path.insert(0, str(Path(__file__).parent))
from test_multibody import mujoco_dynamics, mujoco_model, random_state, relative  # noqa: E402
from trees import random_inertia, random_tree  # noqa: E402


# ----- the exact reduction: roll = slide along l by x = a th, then hinge by th ------------------------------

def roll_tree(rng, bodies: int) -> tuple[Layout, Layout, float]:
    """A random tree with one roll joint (first joint of a random body, other joints of that body after it,
    bodies below it), the same tree with the roll replaced by a slide along l then a hinge, and the radius."""
    layout = random_tree(rng, bodies, kinds=("hinge", "slide", "ball", "weld", "multi"))
    roller = layout.bodies[int(rng.integers(0, bodies - 1))].name  # not the last: bodies hang below it mostly
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    normal = np.cross(axis, rng.normal(size=3))
    normal /= np.linalg.norm(normal)
    radius = float(rng.uniform(0.2, 0.8))
    passive = dict(damping=float(rng.uniform(0, 0.5)), stiffness=float(rng.uniform(0, 2)),
                   springref=float(rng.uniform(-0.5, 0.5)), armature=float(rng.uniform(0, 0.1)))
    ref, anchor = float(rng.uniform(-0.5, 0.5)), tuple(rng.uniform(-0.3, 0.3, 3))
    roll = Joint("rolling", "roll", roller, axis=tuple(axis), anchor=anchor, radius=radius, normal=tuple(normal),
                 qpos0=0.3, qvel0=-0.4, ref=ref, **passive)
    line = np.cross(axis, normal)
    # the slide carries no passive force (the roll's spring, damper and armature act on the angle: the hinge's)
    slide = Joint("rolling_x", "slide", roller, axis=tuple(line), anchor=anchor, qpos0=radius * 0.3,
                  qvel0=radius * -0.4, ref=radius * ref)
    hinge = Joint("rolling_th", "hinge", roller, axis=tuple(axis), anchor=anchor, qpos0=0.3, qvel0=-0.4, ref=ref,
                  **passive)

    def first(extra):
        own = [j for j in layout.joints if j.body == roller]
        others = [j for j in layout.joints if j.body != roller]
        return dataclasses.replace(layout, joints=tuple(others + list(extra) + own))

    return first([roll]), first([slide, hinge]), radius


def reduction(model: Multibody, model2: Multibody, radius: float):
    """J (nv2, nv): the roll rate to (radius, 1) on the slide and hinge, identity elsewhere; and the map of
    (q, v) of the roll tree to the two-dof tree's."""
    qa = int(model.arrays.qposadr[model.joint_names.index("rolling")])
    da = int(model.arrays.dofadr[model.joint_names.index("rolling")])
    assert int(model2.arrays.qposadr[model2.joint_names.index("rolling_x")]) == qa
    J = np.zeros((model2.nv, model.nv))
    J[:da, :da] = np.eye(da)
    J[da, da], J[da + 1, da] = radius, 1.0
    J[da + 2:, da + 1:] = np.eye(model.nv - da - 1)

    def coordinates(q, v):
        return np.insert(q, qa, radius * q[qa]), J @ v

    return J, coordinates


@pytest.mark.parametrize("seed", range(8))
def test_roll_equals_slide_then_hinge_reduced_by_x_equals_a_theta(seed):
    rng = np.random.default_rng(500 + seed)
    layout, layout2, radius = roll_tree(rng, int(rng.integers(2, 9)))
    model, model2 = Multibody(layout), Multibody(layout2)
    assert (model2.nq, model2.nv) == (model.nq + 1, model.nv + 1)
    J, coordinates = reduction(model, model2, radius)
    q2, v2 = coordinates(model.qpos0, model.qvel0)
    np.testing.assert_allclose(model2.qpos0, q2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(model2.qvel0, v2, rtol=0, atol=1e-15)
    for _ in range(4):
        q, v = random_state(rng, model)
        q2, v2 = coordinates(q, v)
        M2, bias2, passive2 = model2.mass_matrix(q2), model2.bias_forces(q2, v2), model2.passive_forces(q2, v2)
        M = model.mass_matrix(q)
        assert relative(M, J.T @ M2 @ J) < 1e-12
        assert relative(model.bias_forces(q, v), J.T @ bias2) < 1e-12
        assert relative(model.passive_forces(q, v), J.T @ passive2) < 1e-12
        tau = rng.normal(size=model.nv)
        expected = np.linalg.solve(J.T @ M2 @ J, tau + J.T @ (passive2 - bias2))
        assert relative(model.forward_dynamics(q, v, tau), expected) < 1e-10
        np.testing.assert_allclose(model.inverse_dynamics(q, v, expected), tau, rtol=0,
                                   atol=1e-10 * max(1.0, np.max(np.abs(tau))))
        # the same bodies in the same places moving the same way
        ours, theirs = model.body_states(q, v), model2.body_states(q2, v2)
        for name in ours:
            np.testing.assert_allclose(ours[name], theirs[name], rtol=0, atol=1e-13, err_msg=name)
        np.testing.assert_allclose(model.kinetic_energy(q, v) + model.potential_energy(q),
                                   model2.kinetic_energy(q2, v2) + model2.potential_energy(q2), rtol=1e-13)


@pytest.mark.parametrize("seed", range(3))
def test_the_two_dof_reduction_itself_equals_mujoco(seed):
    """The slide-then-hinge tree the roll is reduced to: M2 and bias2 are MuJoCo's (mj_fullM, qfrc_bias)."""
    rng = np.random.default_rng(500 + seed)
    _, layout2, _ = roll_tree(rng, int(rng.integers(2, 9)))
    scene = Scene.from_layout(layout2, t_end=1.0)
    model = scene.multibody
    mj, data = mujoco_model(scene)
    for _ in range(3):
        q, v = random_state(rng, model)
        theirs = mujoco_dynamics(mj, data, q, v)
        assert relative(model.mass_matrix(q), theirs["mass_matrix"]) < 1e-10
        assert relative(model.bias_forces(q, v), theirs["bias"]) < 1e-10
        assert relative(model.passive_forces(q, v), theirs["passive"]) < 1e-10


def test_the_contact_point_is_at_rest():
    """v_centre = a q' l, and the body point at anchor - a normal has zero velocity, in any pose, with a body
    hanging below the roller."""
    rng = np.random.default_rng(41)
    quat = rbody.motion.quat_normalize(rng.normal(size=4))
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    normal = np.cross(axis, [1.0, 0.0, 0.0])
    normal /= np.linalg.norm(normal)
    anchor, radius = np.array([0.1, -0.2, 0.05]), 0.35
    roller = Body("roller", random_inertia(rng), pos=(0.2, 0.1, -0.3), quat=tuple(quat))
    below = Body("below", random_inertia(rng), parent="roller", pos=(0.1, 0.3, -0.4))
    joints = (Joint("rolling", "roll", "roller", axis=tuple(axis), anchor=tuple(anchor), radius=radius,
                    normal=tuple(normal), ref=0.2),
              Joint("swing", "hinge", "below", axis=(1.0, 0.0, 0.0)))
    model = Multibody(Layout(bodies=(roller, below), joints=joints))
    R0 = rbody.motion.quat_to_matrix(quat)
    line, normal_world = R0 @ np.cross(axis, normal), R0 @ normal
    for _ in range(3):
        q, v = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
        states = model.body_states(q, v)
        com, quat_now, velocity, omega = (states[k][0] for k in ("com", "quat", "velocity", "omega"))
        R = rbody.motion.quat_to_matrix(quat_now)
        centre = com + R @ (anchor - roller.inertia.com)
        np.testing.assert_allclose(centre, np.array(roller.pos) + R0 @ anchor + radius * (q[0] - 0.2) * line,
                                   rtol=0, atol=1e-14)
        np.testing.assert_allclose(velocity + np.cross(omega, centre - com), radius * v[0] * line, rtol=0,
                                   atol=1e-13)
        contact = centre - radius * normal_world
        np.testing.assert_allclose(velocity + np.cross(omega, contact - com), 0.0, rtol=0, atol=1e-13)
        np.testing.assert_allclose(omega, v[0] * R0 @ axis, rtol=0, atol=1e-14)


# ----- the chapter's rolling bodies on an incline ---------------------------------------------------------

def incline(k: float, alpha: float, radius: float = 0.3, mass: float = 2.0, q0: float = 0.2, w0: float = -1.0):
    """A round body (I = k M a^2 about its axis +y) rolling on an incline of angle alpha, normal
    e = (sin alpha, 0, cos alpha), its centre at the frame origin."""
    tensor = np.diag([0.5 * k + 0.1, k, 0.5 * k + 0.1]) * mass * radius ** 2  # transverse moments: any valid
    body = Body("wheel", Inertia(mass, np.zeros(3), tensor), pos=(0.0, 0.0, radius))
    joint = Joint("roll", "roll", "wheel", axis=(0.0, 1.0, 0.0), radius=radius,
                  normal=(np.sin(alpha), 0.0, np.cos(alpha)), qpos0=q0, qvel0=w0)
    return Layout(bodies=(body,), joints=(joint,))


@pytest.mark.parametrize("name, k", [("disc", 0.5), ("sphere", 0.4), ("hollow cylinder", 1.0)])
def test_rolling_down_an_incline_has_the_chapters_acceleration(name, k):
    alpha, radius, g = 0.35, 0.3, 9.81
    layout = incline(k, alpha, radius)
    model = Multibody(layout, gravity=g)
    line = np.cross([0.0, 1.0, 0.0], [np.sin(alpha), 0.0, np.cos(alpha)])
    assert line[2] < 0 and abs(np.dot(line, [np.sin(alpha), 0.0, np.cos(alpha)])) < 1e-15  # down the slope
    expected = g * np.sin(alpha) / (radius * (1.0 + k))
    rng = np.random.default_rng(3)
    q, v = rng.uniform(-3, 3, (5, 1)), rng.uniform(-3, 3, (5, 1))
    np.testing.assert_allclose(model.forward_dynamics(q, v), expected, rtol=1e-14, err_msg=name)
    np.testing.assert_allclose(model.mass_matrix(q)[:, 0, 0], 2.0 * radius ** 2 * (1.0 + k), rtol=1e-14)
    # rk4 is exact on q = q0 + w0 t + q'' t^2 / 2; the centre moves along l by a (q - q0)
    scene = Scene.from_layout(layout, t_end=1.0, gravity=g)
    run = rbody.simulate(scene, dt=1e-2, method="rk4")
    t = run.t
    angle = 0.2 - 1.0 * t + 0.5 * expected * t ** 2
    np.testing.assert_allclose(run["qpos"][:, 0], angle, rtol=0, atol=1e-13)
    np.testing.assert_allclose(run["wheel.com"], np.array([0.0, 0.0, radius]) + radius * angle[:, None] * line,
                               rtol=0, atol=1e-13)
    np.testing.assert_allclose(run["wheel.omega"], (-1.0 + expected * t)[:, None] * [0.0, 1.0, 0.0], rtol=0,
                               atol=1e-13)
    np.testing.assert_allclose(run["energy"], run["energy"][0], rtol=0, atol=1e-12)


# ----- a wheel carrying a pendulum under rk4 --------------------------------------------------------------

def wheel_with_pendulum() -> Scene:
    """A wheel (radius 0.4 m) rolling on the floor, a pendulum hinged at its centre about the same axis."""
    wheel = Body("wheel", Inertia(3.0, np.zeros(3), np.diag([0.15, 0.24, 0.15])), pos=(0.0, 0.0, 0.4))
    bob = Body("bob", Inertia(1.0, np.array([0.0, 0.0, -0.6]), np.diag([0.02, 0.03, 0.01])), parent="wheel")
    joints = (Joint("roll", "roll", "wheel", axis=(0.0, 1.0, 0.0), radius=0.4, normal=(0.0, 0.0, 1.0),
                    qvel0=2.0),
              Joint("swing", "hinge", "bob", axis=(0.0, 1.0, 0.0), qpos0=1.2, qvel0=-1.0))
    return Scene.from_layout(Layout(bodies=(wheel, bob), joints=joints), t_end=2.0)


def test_rk4_on_a_wheel_with_a_pendulum_keeps_energy_to_its_error_and_has_order_4():
    scene = wheel_with_pendulum()
    reference = rbody.simulate(scene, dt=1e-2, method="reference")
    drift, error = {}, {}
    for dt in (1e-2, 5e-3):
        run = rbody.simulate(scene, dt=dt, method="rk4", save_every=int(round(1e-2 / dt)))
        assert run.t[-1] == pytest.approx(reference.t[-1], abs=1e-12)
        drift[dt] = np.max(np.abs(run["energy"] - run["energy"][0]))
        error[dt] = np.max(np.abs(run["qpos"][-1] - reference["qpos"][-1]))
    assert drift[5e-3] < 1e-6 and error[5e-3] < 1e-6
    assert 3.6 < np.log2(drift[1e-2] / drift[5e-3]) < 4.5
    assert 3.6 < np.log2(error[1e-2] / error[5e-3]) < 4.5
