"""The general multibody engine (rbody.Multibody, Scene.from_layout) against MuJoCo's own computed
quantities, the closed forms of the chapter's scenes, and the hand-written kernels of the families."""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Multibody, Scene
from rbody.errors import MethodNotApplicable, SimulationError
from rbody.motion import quat_normalize, quat_to_matrix
from rbody.scene import BodyStates, TreeScene

sys.path.insert(0, str(Path(__file__).parent))
from trees import random_inertia, random_tree  # noqa: E402

ALL_KINDS = ("hinge", "slide", "ball", "free", "weld", "multi")
_OFF = mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT


def mujoco_model(scene: TreeScene, dt: float = 0.002, integrator: str = "RK4"):
    """MuJoCo's model of the scene through rbody.to_mjcf (which this also tests), constraints and contacts
    off, at the scene's initial state."""
    model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene, dt=dt, integrator=integrator))
    model.opt.disableflags |= _OFF
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    return model, data


def relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(np.max(np.abs(b)), 1e-300))


def mujoco_dynamics(mj, data, q, v) -> dict[str, np.ndarray]:
    """MuJoCo's dynamics at (q, v): mass matrix (mj_fullM), bias (qfrc_bias), passive (qfrc_passive) and
    forward (qacc, constraints off), each a copy."""
    data.qpos[:], data.qvel[:] = q, v
    mujoco.mj_forward(mj, data)
    full = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, full)
    return {"mass_matrix": full, "bias": data.qfrc_bias.copy(), "passive": data.qfrc_passive.copy(),
            "forward": data.qacc.copy()}


def random_state(rng, model: Multibody):
    """A random (q, v) of the tree: coordinates moved from qpos0, quaternions random unit ones."""
    q = model.qpos0 + rng.uniform(-0.5, 0.5, model.nq)
    for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
        if kind in ("ball", "free"):
            at = address + (3 if kind == "free" else 0)
            q[at:at + 4] = quat_normalize(rng.normal(size=4))
    return q, rng.uniform(-2, 2, model.nv)


# ----- against MuJoCo's computed quantities ------------------------------------------------------------

@pytest.mark.parametrize("seed", range(12))
def test_dynamics_equal_mujoco_on_random_trees(seed):
    rng = np.random.default_rng(seed)
    scene = Scene.from_layout(random_tree(rng, int(rng.integers(2, 13)), kinds=ALL_KINDS), t_end=1.0)
    model = scene.multibody
    mj, data = mujoco_model(scene)
    assert (mj.nq, mj.nv) == (model.nq, model.nv)
    np.testing.assert_allclose(data.qpos, model.qpos0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data.qvel, model.qvel0, rtol=0, atol=1e-14)
    for _ in range(3):
        q, v = random_state(rng, model)
        theirs = mujoco_dynamics(mj, data, q, v)
        assert relative(model.mass_matrix(q), theirs["mass_matrix"]) < 1e-10
        assert relative(model.bias_forces(q, v), theirs["bias"]) < 1e-10
        assert relative(model.passive_forces(q, v), theirs["passive"]) < 1e-10
        assert relative(model.forward_dynamics(q, v), theirs["forward"]) < 1e-10
        com, quat = model.body_poses(q)
        ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name) for name in model.body_names]
        np.testing.assert_allclose(com, data.xipos[ids], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.abs(np.sum(quat * data.xquat[ids], axis=1)), 1.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_inverse_dynamics_inverts_forward_dynamics(seed):
    rng = np.random.default_rng(100 + seed)
    model = Multibody(random_tree(rng, int(rng.integers(2, 13)), kinds=ALL_KINDS))
    states = [random_state(rng, model) for _ in range(4)]
    q, v = np.stack([s[0] for s in states]).reshape(2, 2, -1), np.stack([s[1] for s in states]).reshape(2, 2, -1)
    tau = rng.normal(size=(2, 2, model.nv))
    a = model.forward_dynamics(q, v, tau)
    assert a.shape == (2, 2, model.nv)
    np.testing.assert_allclose(model.inverse_dynamics(q, v, a), tau, rtol=0, atol=1e-10 * np.max(np.abs(tau)) * 10)
    # and against the mass matrix: M a = tau + passive - bias
    M = model.mass_matrix(q)
    rhs = tau + model.passive_forces(q, v) - model.bias_forces(q, v)
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", M, a), rhs, rtol=0, atol=1e-10 * np.max(np.abs(rhs)))


@pytest.mark.parametrize("seed", range(3))
def test_rk4_equals_mujoco_rk4_on_hinge_and_slide_trees(seed):
    rng = np.random.default_rng(200 + seed)
    scene = Scene.from_layout(random_tree(rng, 8, kinds=("hinge", "slide", "weld", "multi")), t_end=1.5)
    dt = 2e-3
    run = rbody.simulate(scene, dt=dt, method="rk4")
    mj, data = mujoco_model(scene, dt=dt)
    qpos = [data.qpos.copy()]
    for _ in range(run.t.size - 1):
        mujoco.mj_step(mj, data)
        qpos.append(data.qpos.copy())
    assert np.max(np.abs(run["qpos"] - np.array(qpos))) < 1e-11


def test_mujoco_backend_reports_the_same_observables():
    from validation.backends import mujoco as backend

    rng = np.random.default_rng(7)
    scene = Scene.from_layout(random_tree(rng, 5, kinds=("hinge", "ball", "free", "multi")), t_end=0.2)
    theirs = backend.run(scene, 1e-3, integrator="RK4")
    ours = rbody.simulate(scene, dt=1e-3, method="rk4")
    for name in scene.observables:
        np.testing.assert_allclose(theirs[name], ours[name], rtol=0, atol=1e-9, err_msg=name)


# ----- conservation and closed forms ----------------------------------------------------------------------

def momenta(scene: TreeScene, run) -> tuple[np.ndarray, np.ndarray]:
    """Total linear momentum (T, 3) and angular momentum about the origin (T, 3) from the body states."""
    linear = 0.0
    angular = 0.0
    for body in scene.tree.bodies:
        mass = body.inertia.mass
        com, velocity = run[f"{body.name}.com"], run[f"{body.name}.velocity"]
        R = quat_to_matrix(run[f"{body.name}.quat"])
        tensor = R @ body.inertia.tensor @ np.swapaxes(R, -1, -2)
        spin = np.einsum("tab,tb->ta", tensor, run[f"{body.name}.omega"])
        linear = linear + mass * velocity
        angular = angular + mass * np.cross(com, velocity) + spin
    return linear, angular


def test_free_tree_without_gravity_keeps_momentum_and_angular_momentum():
    rng = np.random.default_rng(11)
    layout = random_tree(rng, 6, kinds=("hinge", "ball", "weld", "multi"), passive=False)
    root = layout.bodies[0]
    free = Joint("root", "free", root.name, qvel0=tuple(rng.uniform(-1, 1, 6)))
    joints = tuple(j for j in layout.joints if j.body != root.name) + (free,)
    bodies = tuple(b if b.parent != "world" or b is root else
                   Body(b.name, b.inertia, parent=root.name, pos=b.pos, quat=b.quat) for b in layout.bodies)
    scene = Scene.from_layout(Layout(bodies=bodies, joints=joints), t_end=2.0, gravity=0.0)
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    linear, angular = momenta(scene, run)
    assert np.max(np.abs(linear - linear[0])) < 1e-12 * max(1.0, np.max(np.abs(linear)))
    assert np.max(np.abs(angular - angular[0])) < 1e-11 * max(1.0, np.max(np.abs(angular)))
    assert abs(np.linalg.norm(angular[0])) > 0.1  # the check has something to keep


def test_free_rotation_matches_the_jacobi_elliptic_solution():
    inertia = Inertia(2.0, np.array([0.1, -0.05, 0.02]), np.diag([1.0, 2.0, 2.5]))
    scene = rbody.scenes.free_rotation(inertia, omega0=[0.3, 4.0, 0.5], t_end=3.0)
    tree = Scene.from_layout(scene.layout, t_end=3.0, gravity=0.0)
    errors = {}
    for dt in (4e-3, 2e-3):
        run = rbody.simulate(tree, dt=dt, method="rk4")
        states = BodyStates(com=run["body.com"], quat=run["body.quat"], velocity=run["body.velocity"],
                            omega=run["body.omega"])
        seen = scene.observe(run.t, {"body": states}, {})
        exact = scene.exact(run.t)
        drift = np.max(np.abs(run["body.com"] - run["body.com"][:1]))  # the centre of mass stays at rest
        errors[dt] = max(np.max(np.abs(seen["omega_body"] - exact["omega_body"])),
                         np.max(np.abs(seen["quaternion"] - exact["quaternion"])), drift)
        np.testing.assert_allclose(np.linalg.norm(run["body.quat"], axis=-1), 1.0, rtol=0, atol=1e-13)
    assert errors[2e-3] < 1e-8
    order = np.log2(errors[4e-3] / errors[2e-3])
    assert 3.6 < order < 4.6  # Runge-Kutta-Munthe-Kaas keeps rk4's order on the rotation


@pytest.mark.parametrize("method", ["gauss6", "euler"])
def test_rotation_keeps_each_methods_order(method):
    inertia = Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 2.5]))
    scene = rbody.scenes.free_rotation(inertia, omega0=[0.3, 4.0, 0.5], t_end=1.0)
    tree = Scene.from_layout(scene.layout, t_end=1.0, gravity=0.0)
    steps = {"gauss6": (2e-2, 1e-2), "euler": (1e-4, 5e-5)}[method]
    errors = []
    for dt in steps:
        run = rbody.simulate(tree, dt=dt, method=method, save_every=int(round(0.1 / dt)))
        exact = scene.exact(run.t)
        errors.append(np.max(np.abs(run["body.quat"] - exact["quaternion"])))
    expected = {"gauss6": 6, "euler": 1}[method]
    assert abs(np.log2(errors[0] / errors[1]) - expected) < 0.6


def test_swinging_rod_as_a_tree_matches_its_kernel_and_exact_solution():
    rod = rbody.scenes.swinging_rod(1.2, 0.7, theta0=1.0, omega0=0.5, t_end=2.0)
    tree = Scene.from_layout(rod.layout, t_end=2.0)
    assert "verlet" in tree.methods and "yoshida6" in tree.methods  # M constant, force from q only
    for method in ("rk4", "verlet", "gauss6"):
        ours, theirs = rbody.simulate(tree, dt=1e-3, method=method), rbody.simulate(rod, dt=1e-3, method=method)
        np.testing.assert_allclose(ours["qpos"][:, 0], theirs["theta"], rtol=0, atol=1e-12, err_msg=method)
        np.testing.assert_allclose(ours["energy"], theirs["energy"], rtol=0, atol=1e-12, err_msg=method)
    exact = rod.exact(ours.t)["theta"]
    assert np.max(np.abs(rbody.simulate(tree, dt=1e-3, method="rk4")["qpos"][:, 0] - exact)) < 1e-11


def test_pendulum_chain_as_a_tree_matches_chain_rhs():
    chain = rbody.scenes.pendulum_chain([1.0, 0.7, 1.3], masses=[1.0, 2.0, 0.5], theta0=[0.4, -0.3, 1.0],
                                        omega0=[0.2, 0.0, -0.5], t_end=2.0)
    tree = Scene.from_layout(chain.layout, t_end=2.0)
    assert "verlet" not in tree.methods
    with pytest.raises(MethodNotApplicable, match="shares its branch"):
        rbody.simulate(tree, dt=1e-3, method="verlet")
    ours, theirs = rbody.simulate(tree, dt=1e-3, method="rk4"), rbody.simulate(chain, dt=1e-3, method="rk4")
    np.testing.assert_allclose(np.cumsum(ours["qpos"], axis=-1), theirs["theta"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(ours["energy"], theirs["energy"], rtol=0, atol=1e-11)


def test_batch_runs_like_single_scenes():
    rng = np.random.default_rng(3)
    scene = Scene.from_layout(random_tree(rng, 4, kinds=("hinge", "ball", "free")), t_end=0.3)
    model = scene.multibody
    qpos0 = np.stack([random_state(rng, model)[0] for _ in range(3)])
    batch = dataclass_replace(scene, qpos0=qpos0)
    assert batch.batch_shape == (3,)
    run = rbody.simulate(batch, dt=1e-3, method="rk4")
    assert run["qpos"].shape == (301, 3, model.nq) and run[f"{model.body_names[0]}.com"].shape == (301, 3, 3)
    single = rbody.simulate(batch.item(1), dt=1e-3, method="rk4")
    np.testing.assert_array_equal(run["qpos"][:, 1], single["qpos"])


def dataclass_replace(scene, **changes):
    import dataclasses

    return dataclasses.replace(scene, **changes)


def test_tree_scene_contract_fields():
    rod = rbody.scenes.swinging_rod(1.0, theta0=0.3, t_end=1.0)
    tree = Scene.from_layout(rod.layout, t_end=1.0, name="rod")
    changed = dataclass_replace(tree, import_notes=("from a file",), timestep=0.01, integrator="RK4")
    np.testing.assert_array_equal(rbody.simulate(changed, dt=1e-3, method="rk4")["qpos"],
                                  rbody.simulate(tree, dt=1e-3, method="rk4")["qpos"])
    with pytest.raises(NotImplementedError, match="no closed-form"):
        tree.exact([0.0])


# ----- bad input ---------------------------------------------------------------------------------------

def _body(name, parent="world", inertia=None):
    return Body(name, inertia or Inertia(1.0, np.array([0.0, 0.0, -0.5]), np.eye(3) * 0.1), parent=parent)


@pytest.mark.parametrize("layout, match", [
    (Layout(bodies=(_body("a", "nowhere"),), joints=()), "parent='nowhere'"),
    (Layout(bodies=(_body("a"), _body("b", "c"), _body("c", "b")), joints=()), "cycle"),
    (Layout(bodies=(_body("a"),), joints=(Joint("j", "hinge", "ghost"),)), "body='ghost'"),
    (Layout(bodies=(_body("a"), _body("b", "a")), joints=(Joint("j", "free", "b"),)), "free joint"),
    (Layout(bodies=(_body("a"),), joints=(Joint("j", "free", "a"), Joint("k", "hinge", "a"))), "only joint"),
    (Layout(bodies=(_body("a"),), joints=(Joint("j", "ball", "a"), Joint("k", "hinge", "a"))), "last joint"),
    (Layout(bodies=(_body("a", inertia=Inertia(1.0, np.zeros(3), np.zeros((3, 3)))),),
            joints=(Joint("spin", "hinge", "a"),)), "body 'a' gives its joint 'spin'"),
    (Layout(bodies=(_body("a"),), joints=(Joint("j", "ball", "a", stiffness=1.0),)), "stiffness"),
    (Layout(bodies=(_body("a"),), joints=(Joint("j", "hinge", "a", qpos0=float("nan")),)), "qpos0"),
])
def test_bad_trees_are_refused_before_any_work(layout, match):
    with pytest.raises(ValueError, match=match):
        Scene.from_layout(layout, t_end=1.0)


def test_bad_states_are_refused():
    scene = Scene.from_layout(Layout(bodies=(_body("a"),), joints=(Joint("j", "hinge", "a"),)), t_end=1.0)
    with pytest.raises(ValueError, match="expected \\(..., 1\\)"):
        dataclass_replace(scene, qpos0=[0.0, 1.0])
    with pytest.raises(ValueError, match="NaN or inf"):
        dataclass_replace(scene, qvel0=[np.inf])
    with pytest.raises(ValueError, match="expected \\(..., 1\\)"):
        scene.multibody.forward_dynamics(np.zeros(2), np.zeros(1))
    with pytest.raises(ValueError, match="NaN"):
        scene.multibody.mass_matrix([np.nan])


def test_a_step_beyond_the_stability_limit_is_refused():
    rod = rbody.scenes.swinging_rod(0.01, theta0=0.3, t_end=1.0)  # w0 = sqrt(3 g / 2 L) = 38 rad/s
    tree = Scene.from_layout(rod.layout, t_end=1.0)
    with pytest.raises(SimulationError, match="stability limit"):
        rbody.simulate(tree, dt=0.1, method="rk4")


def test_a_tree_too_big_for_the_stack_workspace_gives_the_same_right_hand_side():
    """tree_rhs keeps its workspace on the stack up to STACK_FLOATS floats and on the heap beyond: both give
    forward_dynamics (the batch path, whose workspace is always on the heap)."""
    from rbody.engine import multibody as mb

    for links in (3, 190):
        rod = Inertia(1.0, np.array([0.0, 0.0, -0.05]), np.diag([1e-3, 1e-3, 1e-4]))
        bodies = (Body("b0", rod),) + tuple(Body(f"b{i}", rod, parent=f"b{i - 1}", pos=(0.0, 0.0, -0.1))
                                            for i in range(1, links))
        joints = tuple(Joint(f"j{i}", "hinge", f"b{i}", axis=(0.0, 1.0, 0.0), qpos0=0.1) for i in range(links))
        layout = Layout(bodies=bodies, joints=joints)
        model = Multibody(layout)
        size = mb.workspace_size(model._kernel_params)
        assert (size > mb.STACK_FLOATS) == (links == 190)
        rng = np.random.default_rng(links)
        q, v = rng.uniform(-1, 1, model.nv), rng.uniform(-1, 1, model.nv)
        y, out = np.concatenate([q, v]), np.full(2 * model.nv, np.nan)
        mb.tree_rhs(y, np.array(model.params), out)
        np.testing.assert_array_equal(out[:model.nv], v)
        np.testing.assert_allclose(out[model.nv:], model.forward_dynamics(q, v), rtol=0,
                                   atol=1e-12 * np.max(np.abs(out[model.nv:])))


def test_energy_counts_the_rotor_armature_stands_for():
    """A rod (m, length 2l, about its end I = 4/3 m l^2) on a hinge with armature A: (I + A) theta'' = -m g l sin
    theta, whose energy 1/2 (I + A) theta'^2 - m g l cos theta is the run's `energy` and stays constant."""
    m, l, armature, g = 1.5, 0.4, 0.3, 9.81
    rod = Body("rod", Inertia(m, (0.0, 0.0, -l), np.diag([m * l * l / 3, m * l * l / 3, 1e-6])))
    layout = Layout(bodies=(rod,), joints=(Joint("hinge", "hinge", "rod", axis=(0, 1, 0), armature=armature),))
    scene = Scene.from_layout(layout, t_end=2.0, qpos0=[1.2], qvel0=[0.5])
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    theta, omega = run["qpos"][:, 0], run["qvel"][:, 0]
    closed = 0.5 * (4 / 3 * m * l * l + armature) * omega ** 2 - m * g * l * np.cos(theta)
    assert np.max(np.abs(run["energy"] - closed)) < 1e-12 * m * g * l * 10
    assert np.ptp(run["energy"]) < 1e-9
