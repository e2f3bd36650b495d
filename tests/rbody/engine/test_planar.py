"""The planar fast path (rbody.engine.planar) against the 3-D engine (rbody.Multibody), MuJoCo's own computed
quantities and closed forms, on random planar trees; non-planar trees are refused with the reason."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Multibody, Scene
from rbody.engine import integrators
from rbody.engine import multibody as mb
from rbody.engine.planar import planar_accel, planar_model, planar_rhs, planar_structure
from rbody.motion import quat_normalize, quat_to_matrix

sys.path.insert(0, str(Path(__file__).parent))
from test_multibody import mujoco_dynamics, mujoco_model, relative  # noqa: E402
from trees import random_inertia, random_tree  # noqa: E402

NORMALS = {
    "y": np.array([0.0, 1.0, 0.0]),
    "x": np.array([1.0, 0.0, 0.0]),
    "horizontal": np.array([np.cos(0.7), np.sin(0.7), 0.0]),  # a tilted normal in the horizontal plane
    "inclined": quat_to_matrix(quat_normalize([1.0, 0.3, -0.2, 0.1])) @ np.array([0.0, 1.0, 0.0]),  # plane not vertical
}


def planar_tree(rng: np.random.Generator, bodies: int, normal: np.ndarray, roll: bool = True) -> Layout:
    """A random tree whose hinges all turn about +-normal and whose slides lie in its plane: bodies in random
    3-D orientations (so the joint axes in their frames are arbitrary), offsets and com off the plane, inertia
    tensors with products of inertia, welded bodies, one to three joints per body, branches, damping,
    stiffness, springref, armature and ref; roll joints (random radius, surface normal in the plane)."""
    out_bodies, out_joints, rotation = [], [], {"world": np.eye(3)}
    for i in range(bodies):
        parent = "world" if i == 0 or rng.random() < 0.25 else f"b{rng.integers(0, i)}"
        quat = quat_normalize(rng.normal(size=4))
        rotation[f"b{i}"] = rotation[parent] @ quat_to_matrix(quat)
        out_bodies.append(Body(f"b{i}", random_inertia(rng), parent=parent, pos=tuple(rng.uniform(-0.5, 0.5, 3)),
                               quat=tuple(quat)))
        count = int(rng.choice([0, 1, 1, 2, 3]))  # 0: welded to its parent
        for k in range(count):
            kind = str(rng.choice(["hinge", "hinge", "slide", "roll"] if roll else ["hinge", "hinge", "slide"]))
            extra = {}
            if kind in ("hinge", "roll"):
                world_axis = normal * rng.choice([-1.0, 1.0])
                if kind == "roll":
                    surface = rng.normal(size=3)
                    surface -= normal * (surface @ normal)
                    extra = dict(radius=float(rng.uniform(0.1, 0.5)),
                                 normal=tuple(rotation[f"b{i}"].T @ (surface / np.linalg.norm(surface))))
            else:
                direction = rng.normal(size=3)
                world_axis = direction - normal * (direction @ normal)
            out_joints.append(Joint(
                f"j{i}_{k}", kind, f"b{i}", axis=tuple(rotation[f"b{i}"].T @ world_axis),
                anchor=tuple(rng.uniform(-0.3, 0.3, 3)), qpos0=float(rng.uniform(-1, 1)),
                qvel0=float(rng.uniform(-1, 1)), damping=float(rng.uniform(0, 0.5)),
                armature=float(rng.uniform(0, 0.1)), stiffness=float(rng.uniform(0, 2)),
                springref=float(rng.uniform(-0.5, 0.5)), ref=float(rng.uniform(-0.5, 0.5)), **extra))
    if not out_joints:  # at least one degree of freedom
        out_joints.append(Joint("j0_0", "hinge", "b0", axis=tuple(rotation["b0"].T @ normal)))
    return Layout(bodies=tuple(out_bodies), joints=tuple(out_joints))


def random_states(rng, model: Multibody, count: int):
    q = model.qpos0 + rng.uniform(-1.0, 1.0, (count, model.nq))
    return q, rng.uniform(-2, 2, (count, model.nv)), rng.normal(size=(count, model.nv))


# ----- the same dynamics as the 3-D engine and MuJoCo ------------------------------------------------------

kinds: set = set()  # joint kinds the random trees below used


@pytest.mark.parametrize("normal", list(NORMALS))
@pytest.mark.parametrize("seed", range(5))
def test_planar_dynamics_equal_the_3d_engine(seed, normal):
    rng = np.random.default_rng(seed)
    model = Multibody(planar_tree(rng, int(rng.integers(1, 13)), NORMALS[normal]))
    planar, why = planar_structure(model)
    assert planar is not None, why
    kinds.update(model.arrays.joint_kinds)
    assert abs(abs(float(planar.normal @ NORMALS[normal])) - 1.0) < 1e-12
    q, v, tau = random_states(rng, model, 6)
    assert relative(planar.mass_matrix(q), model.mass_matrix(q)) < 1e-12
    assert relative(planar.bias_forces(q, v), model.bias_forces(q, v)) < 1e-12
    assert relative(planar.forward_dynamics(q, v, tau), model.forward_dynamics(q, v, tau)) < 1e-12
    assert relative(planar.forward_dynamics(q, v), model.forward_dynamics(q, v)) < 1e-12
    # the compiled kernels the integrators call: rhs = (qvel, qacc), accel = qacc at rest
    p = np.ascontiguousarray(planar.row)
    out, acc = np.empty(2 * model.nv), np.empty(model.nv)
    planar_rhs(np.concatenate([q[0], v[0]]), p, out)
    np.testing.assert_array_equal(out[:model.nv], v[0])
    assert relative(out[model.nv:], model.forward_dynamics(q[0], v[0])) < 1e-12
    planar_accel(np.ascontiguousarray(q[0]), p, acc)
    assert relative(acc, model.forward_dynamics(q[0], np.zeros(model.nv))) < 1e-12


def test_the_random_planar_trees_used_every_planar_joint_kind():
    if len(kinds) == 0:
        pytest.skip("run with test_planar_dynamics_equal_the_3d_engine")
    assert kinds == {"hinge", "slide", "roll"}


@pytest.mark.parametrize("normal", ["y", "horizontal"])
@pytest.mark.parametrize("seed", range(3))
def test_planar_dynamics_equal_mujoco(seed, normal):
    """MuJoCo's mj_fullM, qfrc_bias and qacc (constraints off). 1e-10 as the 3-D engine's own test: MuJoCo
    sums about each subtree's centre of mass, rbody about the world origin (round-off ~ |x| / tree size)."""
    rng = np.random.default_rng(50 + seed)
    # no roll joints: MJCF writes one as a slide and a hinge tied by an equality, a constraint switched off here
    scene = Scene.from_layout(planar_tree(rng, int(rng.integers(2, 13)), NORMALS[normal], roll=False), t_end=1.0)
    planar = planar_model(scene.multibody)
    mj, data = mujoco_model(scene)
    q, v, _ = random_states(rng, scene.multibody, 3)
    for qi, vi in zip(q, v):
        theirs = mujoco_dynamics(mj, data, qi, vi)
        assert relative(planar.mass_matrix(qi), theirs["mass_matrix"]) < 1e-10
        assert relative(planar.bias_forces(qi, vi), theirs["bias"]) < 1e-10
        assert relative(planar.forward_dynamics(qi, vi), theirs["forward"]) < 1e-10


@pytest.mark.parametrize("seed", range(3))
def test_simulate_through_the_planar_path_equals_the_3d_path(seed):
    rng = np.random.default_rng(100 + seed)
    normal = list(NORMALS.values())[seed]
    scene = Scene.from_layout(planar_tree(rng, 10, normal), t_end=1.0,
                              qpos0=None, qvel0=None)
    native = scene.native_model
    assert native.rhs is planar_rhs
    dt = 1e-3
    run = rbody.simulate(scene, dt=dt, method="rk4")
    model = scene.multibody
    steps = run.t.size - 1
    out = np.empty((steps + 1, 1, 2 * model.nv))
    integrators.run_rk4(mb.tree_rhs, native.y0, np.asarray(model.params)[None, :], dt, steps, 1, out)
    scale = max(1.0, float(np.max(np.abs(out))))
    assert np.max(np.abs(run["qpos"] - out[:, 0, :model.nv])) < 1e-11 * scale
    assert np.max(np.abs(run["qvel"] - out[:, 0, model.nv:])) < 1e-11 * scale
    assert np.all(np.isfinite(run["energy"]))


def test_batch_through_the_planar_path_runs_like_single_scenes():
    rng = np.random.default_rng(7)
    layout = planar_tree(rng, 4, NORMALS["y"])
    nv = Multibody(layout).nv
    qpos0 = rng.uniform(-1, 1, (3, nv))
    batch = rbody.simulate(Scene.from_layout(layout, t_end=0.3, qpos0=qpos0), dt=1e-3, method="rk4")
    for b in range(3):
        single = rbody.simulate(Scene.from_layout(layout, t_end=0.3, qpos0=qpos0[b]), dt=1e-3, method="rk4")
        np.testing.assert_array_equal(batch["qpos"][:, b], single["qpos"])


# ----- closed forms ----------------------------------------------------------------------------------------

def test_swinging_rod_acceleration_is_the_closed_form():
    """The chapter's swinging rod: theta'' = -(m g d / I_pivot) sin(theta), d = L/2, I_pivot = m L^2 / 3,
    here about a hinge along -x with the body turned off its reference pose by ref."""
    length, mass, g = 1.3, 0.8, 9.81
    rod = Inertia(mass, np.zeros(3), np.diag([mass * length ** 2 / 12] * 2 + [1e-4]))
    layout = Layout(bodies=(Body("rod", rod, pos=(0.0, 0.2, -length / 2)),),
                    joints=(Joint("pivot", "hinge", "rod", axis=(-1.0, 0.0, 0.0), anchor=(0.0, 0.0, length / 2),
                                  ref=0.0),))
    model = Multibody(layout, gravity=g)
    planar = planar_model(model)
    theta = np.linspace(-2.5, 2.5, 11)
    expected = -(mass * g * length / 2) / (mass * length ** 2 / 3) * np.sin(theta)
    got = planar.forward_dynamics(theta[:, None], np.full((11, 1), 0.7))[:, 0]
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)


def test_rod_and_chain_scenes_run_the_planar_kernels_and_match_their_hand_kernels():
    rod = rbody.scenes.swinging_rod(1.2, 0.7, theta0=1.0, omega0=0.5, t_end=1.0)
    tree = Scene.from_layout(rod.layout, t_end=1.0)
    assert tree.native_model.rhs is planar_rhs and tree.native_model.accel is planar_accel
    for method in ("rk4", "verlet"):
        ours = rbody.simulate(tree, dt=1e-3, method=method)
        theirs = rbody.simulate(rod, dt=1e-3, method=method)
        assert np.max(np.abs(ours["qpos"][:, 0] - theirs["theta"])) < 1e-12
    chain = rbody.scenes.pendulum_chain(5, theta0=np.linspace(0.2, 0.6, 5), t_end=1.0)
    tree = Scene.from_layout(chain.layout, t_end=1.0)
    assert tree.native_model.rhs is planar_rhs and tree.native_model.accel is None
    ours = rbody.simulate(tree, dt=1e-3, method="rk4")
    theirs = rbody.simulate(chain, dt=1e-3, method="rk4")
    # the tree's coordinates are relative angles, the chain's absolute ones
    assert np.max(np.abs(np.cumsum(ours["qpos"], axis=-1) - theirs["theta"])) < 1e-10


def test_a_point_mass_on_its_own_axis_gives_nan_like_the_3d_engine():
    """A hinge through a point mass moves no inertia: the 3-D engine refuses it at construction; the planar
    kernel, handed such a row (armature removed), gives NaN for that joint, never a number."""
    from rbody.engine import planar as pl

    point = Inertia(1.0, np.zeros(3), np.zeros((3, 3)))
    layout = Layout(bodies=(Body("p", point),), joints=(Joint("h", "hinge", "p", axis=(0.0, 1.0, 0.0)),))
    with pytest.raises(ValueError, match="singular"):
        Multibody(layout)
    held = Layout(bodies=layout.bodies, joints=(Joint("h", "hinge", "p", axis=(0.0, 1.0, 0.0), armature=0.1),))
    row = np.array(planar_model(Multibody(held)).row)
    out = np.empty(2)
    planar_rhs(np.array([0.3, 0.1]), row, out)
    assert np.isfinite(out).all()
    row[pl.HEADER + pl.N_ARMATURE] = 0.0
    planar_rhs(np.array([0.3, 0.1]), row, out)
    assert np.isnan(out[1])


# ----- planarity is decided from the structure -------------------------------------------------------------

def _hinge_pair(axis_b):
    inertia = Inertia(1.0, np.array([0.1, 0.0, -0.2]), np.diag([0.1, 0.2, 0.3]))
    return Layout(bodies=(Body("a", inertia), Body("b", inertia, parent="a", pos=(0.0, 0.0, -0.5))),
                  joints=(Joint("ja", "hinge", "a", axis=(0.0, 1.0, 0.0)), Joint("jb", "hinge", "b", axis=axis_b)))


@pytest.mark.parametrize("layout, reason", [
    (_hinge_pair((1.0, 0.0, 0.0)), "axes of joints 'ja' and 'jb' are not parallel"),
    (_hinge_pair((0.0, 1.0, 1e-9)), "not parallel"),
    (Layout(bodies=_hinge_pair((0, 1, 0)).bodies, joints=(Joint("ja", "hinge", "a", axis=(0.0, 1.0, 0.0)),
                                                          Joint("jb", "slide", "b", axis=(0.0, 1.0, 0.0)))),
     "slide 'jb'.*not perpendicular"),
    (Layout(bodies=_hinge_pair((0, 1, 0)).bodies, joints=(Joint("ja", "hinge", "a", axis=(0.0, 1.0, 0.0)),
                                                          Joint("jb", "ball", "b"))), "'jb' is a ball joint"),
    (Layout(bodies=_hinge_pair((0, 1, 0)).bodies[:1], joints=(Joint("ja", "free", "a"),)), "'ja' is a free joint"),
    (Layout(bodies=_hinge_pair((0, 1, 0)).bodies, joints=(Joint("ja", "slide", "a", axis=(1.0, 0.0, 0.0)),
                                                          Joint("jb", "slide", "b", axis=(0.0, 1.0, 0.0)),
                                                          Joint("jc", "slide", "b", axis=(0.0, 0.0, 1.0)))),
     "span all of space"),
])
def test_non_planar_trees_are_refused_with_the_reason(layout, reason):
    model = Multibody(layout)
    planar, why = planar_structure(model)
    assert planar is None
    assert planar_model(model) is None
    import re
    assert re.search(reason, why), why
    scene = Scene.from_layout(layout, t_end=0.1)
    assert scene.native_model.rhs is not planar_rhs  # the 3-D engine runs it


def test_random_non_planar_trees_run_the_3d_engine():
    rng = np.random.default_rng(3)
    for _ in range(5):
        layout = random_tree(rng, 6, kinds=("hinge", "slide", "multi", "weld"))
        model = Multibody(layout)
        if len(model.joint_names) >= 2:
            assert planar_model(model) is None
            assert Scene.from_layout(layout, t_end=0.1).native_model.rhs is mb.tree_rhs


def test_slides_in_one_plane_and_welds_are_planar():
    inertia = Inertia(1.0, np.array([0.1, 0.3, -0.2]), np.array([[0.3, 0.05, 0.01], [0.05, 0.2, 0.02],
                                                               [0.01, 0.02, 0.25]]))
    layout = Layout(bodies=(Body("a", inertia), Body("w", inertia, parent="a", pos=(0.2, 0.1, 0.0)),
                            Body("fixed", inertia, pos=(1.0, 1.0, 1.0))),
                    joints=(Joint("x", "slide", "a", axis=(1.0, 0.0, 0.0)),
                            Joint("z", "slide", "a", axis=(1.0, 0.0, 1.0))))
    model = Multibody(layout)
    planar, why = planar_structure(model)
    assert planar is not None, why
    np.testing.assert_allclose(np.abs(planar.normal), [0.0, 1.0, 0.0], rtol=0, atol=1e-15)
    q, v = np.array([0.3, -0.2]), np.array([0.5, 1.0])
    assert relative(planar.forward_dynamics(q, v), model.forward_dynamics(q, v)) < 1e-13
    assert relative(planar.mass_matrix(q), model.mass_matrix(q)) < 1e-13


# ----- the roll joint (a round body rolling without slipping on a line) -----------------------------------

def rolling_row(*, radius, mass, moment, com, line, gravity=(0.0, -9.81), child=None, sign=1.0):
    """A planar row by hand: node 0 a disc of `radius` rolling along the unit `line` (plane coordinates), its
    centre at the origin at q = 0, com (2) and moment about the com; child: (anchor (2), mass, com (2), moment)
    of a pendulum hinged to the disc."""
    from rbody.engine import planar as pl

    nodes = 1 if child is None else 2
    row = np.zeros(pl.HEADER + nodes * pl.NODE_SIZE)
    row[pl.P_NODES], row[pl.P_GX], row[pl.P_GY] = nodes, -gravity[0], -gravity[1]
    r = pl.HEADER
    row[r + pl.N_PARENT], row[r + pl.N_KIND], row[r + pl.N_SIGN] = -1, pl.PLANAR_ROLL, sign
    row[r + pl.N_RADIUS], row[r + pl.N_LINE:r + pl.N_LINE + 2] = radius, line
    row[r + pl.N_MASS], row[r + pl.N_COM:r + pl.N_COM + 2], row[r + pl.N_MOMENT] = mass, com, moment
    if child is not None:
        anchor, m2, c2, I2 = child
        r += pl.NODE_SIZE
        row[r + pl.N_PARENT], row[r + pl.N_KIND], row[r + pl.N_SIGN] = 0, pl.PLANAR_HINGE, 1.0
        row[r + pl.N_POINT:r + pl.N_POINT + 2] = anchor
        row[r + pl.N_MASS], row[r + pl.N_COM:r + pl.N_COM + 2], row[r + pl.N_MOMENT] = m2, c2, I2
    return row


def _rot(angle):
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_disc_rolls_down_an_incline_at_the_closed_form_rate(sign):
    """The chapter's rolling disc: q'' = g sin(alpha) / (a (1 + k)), k = I / (M a^2), q the angle turned,
    whatever q'. The line l = axis x normal runs uphill here (l = (-cos alpha, sin alpha) for axis +n and the
    normal (sin alpha, cos alpha)), so q'' is negative; with the axis along -n both flip."""
    alpha, a, M, k = 0.4, 0.3, 2.0, 0.5
    normal = np.array([np.sin(alpha), np.cos(alpha)])
    line = sign * np.array([-normal[1], normal[0]])  # (s n) x e in plane coordinates
    row = rolling_row(radius=a, mass=M, moment=k * M * a * a, com=(0.0, 0.0), line=line, sign=sign)
    out = np.empty(2)
    for q, qd in ((0.0, 0.0), (1.3, -2.0), (-4.0, 5.0)):
        planar_rhs(np.array([q, qd]), row, out)
        np.testing.assert_allclose(out[1], -sign * 9.81 * np.sin(alpha) / (a * (1 + k)), rtol=1e-14)


def _rolling_energy(y, *, radius, mass, moment, com, line, child):
    """T + V of the disc (and its pendulum) from the kinematics written out here, velocities by central
    differences along (q', ...): independent of the kernel's recursions."""
    line, com = np.asarray(line), np.asarray(com)
    anchor, m2, c2, I2 = child

    def points(q):
        centre = radius * q[0] * line
        disc_com = centre + _rot(q[0]) @ com
        joint = centre + _rot(q[0]) @ np.asarray(anchor)
        return disc_com, joint + _rot(q[0] + q[1]) @ (np.asarray(c2) - np.asarray(anchor))

    q, qd = y[:2], y[2:]
    h = 1e-6
    plus, minus = points(q + h * qd), points(q - h * qd)
    v1, v2 = ((p - m) / (2 * h) for p, m in zip(plus, minus))
    x1, x2 = points(q)
    kinetic = 0.5 * mass * v1 @ v1 + 0.5 * moment * qd[0] ** 2 + 0.5 * m2 * v2 @ v2 + 0.5 * I2 * (qd[0] + qd[1]) ** 2
    return kinetic + 9.81 * (mass * x1[1] + m2 * x2[1])


def test_an_eccentric_disc_with_a_pendulum_keeps_its_energy():
    """A disc whose com is off its centre rolling on level ground, a pendulum hinged to it: the velocity-product
    term of the roll joint (its subspace turns with its own angle) is what keeps T + V constant."""
    geometry = dict(radius=0.4, mass=1.5, moment=0.05, com=(0.15, 0.05), line=(-1.0, 0.0),
                    child=((0.1, -0.1), 0.7, (0.1, -0.6), 0.02))
    row = rolling_row(**geometry)
    y0 = np.array([[0.3, 0.8, 2.0, -1.0]])
    dt, steps = 1e-3, 3000
    out = np.empty((steps + 1, 1, 4))
    integrators.run_rk4(planar_rhs, y0, row[None, :], dt, steps, 1, out)
    energy = np.array([_rolling_energy(y, **geometry) for y in out[::100, 0]])
    assert np.ptp(out[:, 0, 2]) > 1.0  # it really moves
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * max(1.0, abs(energy[0]))
