"""Box-cylinder and cylinder-cylinder contacts (rbody.engine.contacts.geometry): 19 and 17 candidates, every one an
exact distance of a point from the other geom (a rim's closest point found by sampling and bisection on the slope,
a box's corner, a box's edge's closest point, two sides' closest points); their least against MuJoCo's distance on
random separated poses, and closed forms in the rigid limit: a cylinder standing and a drum lying on a box, a drum
thrown sliding on a box's top (rolls at 2/3 v0 from t* = v0 / (3 mu g)), a box resting on a cylinder's cap, coins
stacked, a cylinder dropped tilted onto a box; a box's or a mesh's face lying along a cylinder's (or a capsule's)
side touches at the ends of their line: a cube rests on a log and rocks on it as rolling without slipping."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.engine.contacts.geometry import APART, BOX, CYLINDER, MESH, SLOTS, collide_pair
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81
I3 = np.eye(3)
LYING = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)  # a cylinder's axis along -y


def random_rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def test_slots():
    assert SLOTS[(CYLINDER, BOX)] == 19 and SLOTS[(CYLINDER, CYLINDER)] == 17 and SLOTS[(CYLINDER, MESH)] == 19


def test_closed_form_distances():
    """A cylinder (r 0.1, half 0.2) upright above a box's top face, lying above it, and tilted over its edge."""
    top = 0.3  # the box [-1, 1] x [-1, 1] x [-0.3, 0.3]
    box = ("box", np.zeros(3), I3, (1.0, 1.0, top))
    dist, normal, _ = collide_pair("cylinder", [0.2, 0.1, top + 0.2 + 0.05], I3, (0.1, 0.2), *box)
    assert dist.min() == pytest.approx(0.05, abs=1e-15)
    np.testing.assert_allclose(np.sort(dist)[:4], 0.05, rtol=0, atol=1e-15)  # the lower cap's four rim points
    np.testing.assert_allclose(normal[np.argmin(dist)], [0, 0, -1], rtol=0, atol=1e-15)
    dist, _, _ = collide_pair("cylinder", [0.0, 0.0, top + 0.1 + 0.02], quat_to_matrix(np.array(LYING)),
                              (0.1, 0.2), *box)
    np.testing.assert_allclose(np.sort(dist)[:2], 0.02, rtol=0, atol=1e-15)  # a rim point at each end
    # upright beside the box's edge x = 1, its side 0.03 from the edge's line: the edge's closest point
    dist, normal, _ = collide_pair("cylinder", [1.13, 0.0, top + 0.1], I3, (0.1, 0.2), *box)
    assert dist.min() == pytest.approx(0.03, abs=1e-15)
    np.testing.assert_allclose(normal[np.argmin(dist)], [-1, 0, 0], rtol=0, atol=1e-15)
    # two drums crossed, sides 0.04 apart; a coin above another's cap
    dist, normal, _ = collide_pair("cylinder", np.zeros(3), quat_to_matrix(np.array(LYING)), (0.1, 0.3),
                                   "cylinder", [0, 0, 0.25 + 0.04], quat_to_matrix(np.array([0.5, 0.5, 0.5, 0.5])),
                                   (0.15, 0.3))
    assert dist.min() == pytest.approx(0.04, abs=1e-15)
    np.testing.assert_allclose(normal[np.argmin(dist)], [0, 0, 1], rtol=0, atol=1e-15)
    dist, _, _ = collide_pair("cylinder", np.zeros(3), I3, (0.2, 0.05), "cylinder", [0.05, 0, 0.1 + 0.01], I3,
                              (0.1, 0.05))
    np.testing.assert_allclose(np.sort(dist)[:4], 0.01, rtol=0, atol=1e-15)


@pytest.mark.parametrize("kind_a,size_a,kind_b,size_b", [("cylinder", (0.1, 0.2), "box", (0.15, 0.1, 0.3)),
                                                         ("box", (0.1, 0.2, 0.05), "cylinder", (0.15, 0.1)),
                                                         ("cylinder", (0.1, 0.2), "cylinder", (0.15, 0.1))])
def test_least_distance_against_mujoco_on_random_separated_poses(kind_a, size_a, kind_b, size_b):
    """Every candidate's distance is that of a point of one surface from the other geom, so the least is never
    below the true distance; it must reach it (MuJoCo's mj_geomDistance, its convex solver, to its own
    tolerance)."""
    mujoco = pytest.importorskip("mujoco")
    text = " ".join
    xml = (f'<mujoco><worldbody><body mocap="true"><geom name="a" type="{kind_a}" size="{text(map(str, size_a))}"/>'
           f'</body><body mocap="true"><geom name="b" type="{kind_b}" size="{text(map(str, size_b))}"/></body>'
           '</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(11)
    checked, worst = 0, 0.0
    fromto = np.zeros(6)
    for _ in range(300):
        qa, qb = (rng.normal(size=4) for _ in range(2))
        data.mocap_quat[0], data.mocap_quat[1] = qa / np.linalg.norm(qa), qb / np.linalg.norm(qb)
        offset = rng.normal(size=3)
        data.mocap_pos[1] = offset * rng.uniform(0.3, 0.8) / np.linalg.norm(offset)
        mujoco.mj_forward(model, data)
        reference = mujoco.mj_geomDistance(model, data, 0, 1, 10.0, fromto)
        if reference <= 1e-6:
            continue
        dist, normal, _ = collide_pair(kind_a, data.geom_xpos[0], data.geom_xmat[0].reshape(3, 3), size_a,
                                       kind_b, data.geom_xpos[1], data.geom_xmat[1].reshape(3, 3), size_b)
        worst = max(worst, abs(dist.min() - reference))
        k = int(np.argmin(dist))
        direction = (fromto[3:] - fromto[:3]) / np.linalg.norm(fromto[3:] - fromto[:3])
        np.testing.assert_allclose(normal[k], direction, rtol=0, atol=1e-4)  # MuJoCo's witness points: to its tolerance
        checked += 1
    assert checked > 200
    assert worst <= 1e-9, worst


def on_box(shape, quat=(1.0, 0.0, 0.0, 0.0), height=None, friction=0.5, mass=1.0, inertia=None, qvel=None,
           t_end=1.0, dt=2e-3):
    """A body with one shape resting on the top face (z = 0) of a fixed box 2 x 2 x 0.6 m."""
    body = Body("body", inertia or Inertia.solid_sphere(mass, 0.1), shapes=(shape,), pos=(0.0, 0.0, height),
                quat=quat)
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "body"),),
                    fixed=(Shape("table", "box", (1.0, 1.0, 0.3), pos=(0.0, 0.0, -0.3)),),
                    contacts=(Contact("table", shape.name, friction=friction),))
    return rbody.simulate(Scene.from_layout(layout, t_end=t_end, qvel0=qvel), dt=dt)


def test_cylinder_standing_and_lying_on_a_box_stays_put():
    inertia = Inertia.solid_cylinder(1.0, 0.1, 0.4)
    for quat, height, touching in (((1.0, 0.0, 0.0, 0.0), 0.2, 4), (LYING, 0.1, 2)):
        run = on_box(Shape("c", "cylinder", (0.1, 0.2)), quat, height, inertia=inertia)
        assert np.abs(run["body.com"] - run["body.com"][0]).max() <= 1e-13
        assert run["contacts"][-1] >= touching
        np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-12)


def test_drum_thrown_sliding_on_a_box_rolls_at_two_thirds():
    r, mu, v0, dt = 0.1, 0.3, 1.0, 1e-3
    run = on_box(Shape("c", "cylinder", (r, 0.2)), LYING, r, friction=mu, inertia=Inertia.solid_cylinder(1.0, r, 0.4),
                 qvel=[v0, 0, 0, 0, 0, 0], t_end=0.5, dt=dt)
    v, spin, z = run["body.velocity"][:, 0], run["body.omega"][:, 1], run["body.com"][:, 2]
    t_star = v0 / (3 * mu * G)
    rolling = np.abs(v - r * spin) <= 1e-12
    start = run.t[np.argmax(rolling)]
    assert t_star <= start <= t_star + dt
    assert np.all(rolling[run.t >= start])
    np.testing.assert_allclose(v[run.t >= start], 2 / 3 * v0, rtol=0, atol=1e-12)
    assert np.abs(z - r).max() <= 1e-14


def test_box_resting_on_a_cylinders_cap_and_coins_stacked():
    half = (0.15, 0.1, 0.05)
    for name, shape in (("box", Shape("top", "box", half)), ("coin", Shape("top", "cylinder", (0.1, 0.05)))):
        inertia = Inertia.box(1.0, 2 * np.array(half)) if name == "box" else Inertia.solid_cylinder(1.0, 0.1, 0.1)
        body = Body("top", inertia, shapes=(shape,), pos=(0.03, -0.02, 0.2 + 0.05))
        layout = Layout(bodies=(body,), joints=(Joint("free", "free", "top"),),
                        fixed=(Shape("pillar", "cylinder", (0.2, 0.1), pos=(0.0, 0.0, 0.1)),),
                        contacts=(Contact("pillar", "top", friction=0.5),))
        run = rbody.simulate(Scene.from_layout(layout, t_end=1.0), dt=2e-3)
        assert np.abs(run["top.com"] - run["top.com"][0]).max() <= 1e-13, name
        np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-12)


A = 0.1  # a cube's half side [m], as a box and as a mesh
R_LOG = 0.3  # the lying cylinder (a log) under it: radius [m], half-length 0.5 m, its axis along y
CUBE = tuple((x, y, z) for x in (-A, A) for y in (-A, A) for z in (-A, A))
ROUND = 4 * np.finfo(float).eps * (R_LOG + 2 * A)  # round-off in positions of this size [m]
LYING_Y = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)  # a geom's z axis along -y
LOG = Shape("log", "cylinder", (R_LOG, 0.5), quat=LYING_Y)
# the pairs whose face lies along a round side: a cylinder's with a box and a mesh, a capsule's with a mesh (a
# capsule and a box rest on the span they lie along: test_capsule_box.py)
ALONG_SIDES = [("cylinder", "box"), ("cylinder", "mesh"), ("capsule", "mesh")]


def cube(kind):
    return Shape("cube", "box", (A, A, A)) if kind == "box" else Shape("cube", "mesh", vertices=CUBE)


def on_log(kind, mat, centre, round_kind="cylinder"):
    """collide_pair of the log (a cylinder or a capsule) and the cube (box or mesh) with axes mat at centre."""
    return collide_pair(round_kind, np.zeros(3), quat_to_matrix(np.array(LYING_Y)), (R_LOG, 0.5), kind,
                        np.asarray(centre, dtype=float), mat, (A, A, A), vertices_b=CUBE if kind == "mesh" else None)


@pytest.mark.parametrize("round_kind,kind", ALONG_SIDES)
@pytest.mark.parametrize("yaw", [0.0, 0.3, np.pi / 4, 1.2])
def test_a_face_along_a_cylinders_side_touches_at_the_ends_of_their_line(round_kind, kind, yaw):
    """A cube's face lying on a log's top line (the cube turned by yaw about the vertical) touches it along the
    line's chord across the face, |y| <= A / max(|cos yaw|, |sin yaw|): exactly two candidates touch, at its ends
    (at yaw = pi/4 two corners, held by the line's ends alone), with the side's normal +z."""
    mat = quat_to_matrix(np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]))
    dist, normal, point = on_log(kind, mat, (0.0, 0.0, R_LOG + A), round_kind)
    touching = np.flatnonzero(dist <= 1e-9)
    assert len(touching) == 2, dist
    chord = A / max(abs(np.cos(yaw)), abs(np.sin(yaw)))
    np.testing.assert_allclose(dist[touching], 0.0, rtol=0, atol=ROUND)
    np.testing.assert_allclose(np.sort(point[touching, 1]), [-chord, chord], rtol=0, atol=ROUND)
    np.testing.assert_allclose(point[touching][:, [0, 2]], [[0.0, R_LOG]] * 2, rtol=0, atol=ROUND)
    np.testing.assert_allclose(normal[touching], [[0.0, 0.0, 1.0]] * 2, rtol=0, atol=1e-15)


@pytest.mark.parametrize("round_kind,kind", ALONG_SIDES)
def test_a_face_tipped_along_a_cylinders_side_has_its_line_ends_exact_distances(round_kind, kind):
    """The cube tipped by 0.01 rad about x (the log's line runs along y): the face's points over the line,
    (0, +-A, -A) in the cube's frame, are the line's ends; their distances from the log, sqrt(x^2 + z^2) - R, are
    the candidates' to round-off, the lower end touching."""
    tip = 0.01
    mat = quat_to_matrix(np.array([np.cos(tip / 2), np.sin(tip / 2), 0.0, 0.0]))
    ends = np.array([[0.0, -A, -A], [0.0, A, -A]]) @ mat.T
    centre = np.array([0.0, 0.0, R_LOG - ends[:, 2].min()])  # the lower end on the log's top line
    dist, _, point = on_log(kind, mat, centre, round_kind)
    ends += centre
    expected = np.hypot(ends[:, 0], ends[:, 2]) - R_LOG
    assert abs(expected.min()) <= ROUND and expected.max() > 1e-3
    for end, gap in zip(ends, expected):
        slot = np.argmin(np.hypot(point[:, 0], point[:, 1] - end[1]) + np.where(dist == APART, np.inf, 0.0))
        np.testing.assert_allclose(dist[slot], gap, rtol=0, atol=ROUND)
    assert dist.min() >= -ROUND


@pytest.mark.parametrize("round_kind,kind", ALONG_SIDES + [("capsule", "box")])
@pytest.mark.parametrize("yaw", [0.0, 0.3])
def test_a_cube_rests_on_a_lying_cylinder(round_kind, kind, yaw):
    """A cube resting on a log's top line (a cylinder's or a capsule's), on the two ends of their line, stays put
    to round-off (one point of contact, as before, let it tip: 1.1e-5 m and 0.08 rad/s in 1 s, or the step failed
    to project); on a capsule, a box rests on its span's ends and middle."""
    body = Body("body", Inertia.box(1.0, (2 * A, 2 * A, 2 * A)), shapes=(cube(kind),), pos=(0.0, 0.0, R_LOG + A),
                quat=(np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "body"),),
                    fixed=(Shape("log", round_kind, (R_LOG, 0.5), quat=LYING_Y),),
                    contacts=(Contact("log", "cube", friction=0.5),))
    run = rbody.simulate(Scene.from_layout(layout, t_end=1.0), dt=2e-3)
    assert np.abs(run["body.com"] - run["body.com"][0]).max() <= 1e-15
    assert np.abs(run["body.omega"]).max() <= 1e-14
    assert run["contacts"][-1] == (3 if (round_kind, kind) == ("capsule", "box") else 2)
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-12)


def rocking(kind, theta0, dt, t_end=1.0):
    """A cube rocking on the log, tipped by theta0 about the log's axis and let go, placed where rolling without
    slipping puts it (rolling_cube_com)."""
    x0, z0 = rolling_cube_com(theta0)
    body = Body("body", Inertia.box(1.0, (2 * A, 2 * A, 2 * A)), shapes=(cube(kind),), pos=(x0, 0.0, z0),
                quat=(np.cos(theta0 / 2), 0.0, np.sin(theta0 / 2), 0.0))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "body"),), fixed=(LOG,),
                    contacts=(Contact("log", "cube", friction=1.0),))
    return rbody.simulate(Scene.from_layout(layout, t_end=t_end), dt=dt)


def rolling_cube_com(theta):
    """(x, z) [m] of the cube's centre rolling without slipping on the log's top, turned by theta [rad] about y:
    the contact at angle theta on the log, R theta along the face from its middle, A above it."""
    return ((R_LOG + A) * np.sin(theta) - R_LOG * theta * np.cos(theta),
            (R_LOG + A) * np.cos(theta) + R_LOG * theta * np.sin(theta))


def rolling_cube_angle(theta0, t):
    """The cube's angle theta(t) [rad] rocking on the log from rest at theta0: Lagrange's equation of the rolling
    (kinetic energy m (A^2 + rho^2 + R^2 theta^2) theta'^2 / 2, rho^2 = (2A)^2 / 6, potential m g z(theta)),
    integrated to 1e-12."""
    from scipy.integrate import solve_ivp

    rho2 = (2 * A) ** 2 / 6

    def rates(_t, y):
        theta, spin = y
        slope = -A * np.sin(theta) + R_LOG * theta * np.cos(theta)  # dz/dtheta
        return [spin, -(R_LOG ** 2 * theta * spin ** 2 + G * slope) / (A ** 2 + rho2 + R_LOG ** 2 * theta ** 2)]

    return solve_ivp(rates, (0.0, t[-1]), [theta0, 0.0], t_eval=t, rtol=1e-12, atol=1e-14, method="DOP853").y[0]


def test_a_cube_rocks_on_a_lying_cylinder_as_rolling_without_slipping():
    """A cube rocking on a log (stable: A < R; small oscillations at g (R - A) / (A^2 + rho^2)), tipped by 0.2 rad:
    its angle follows the rolling's exact motion to first order in the step (the time-stepping's order: halving dt
    halves the error), on the line's two ends all along, without overlap beyond round-off, and the mesh cube's run is
    the box's to round-off."""
    theta0, errors = 0.2, []
    for dt in (1e-3, 5e-4):
        run = rocking("box", theta0, dt)
        quat = run["body.quat"]
        theta = 2 * np.arctan2(quat[:, 2], quat[:, 0])
        errors.append(np.abs(theta - rolling_cube_angle(theta0, run.t)).max())
        assert np.all(run["contacts"][1:] == 2)
        distance = run["contact_distance"]
        assert distance[np.isfinite(distance)].min() >= -1e-12
        assert np.abs(run["body.com"][:, 1]).max() <= 1e-15  # no motion along the log
    assert 1.9 <= errors[0] / errors[1] <= 2.1, errors
    assert errors[0] <= 2e-3  # 0.7% of the amplitude at dt = 1 ms
    mesh = rocking("mesh", theta0, 5e-4)
    np.testing.assert_allclose(mesh["body.com"], run["body.com"], rtol=0, atol=1e-13)


@pytest.mark.parametrize("tilt", [0.3, 1.2])
def test_cylinder_dropped_tilted_onto_a_box_lands_and_rests(tilt):
    quat = (np.cos(tilt / 2), np.sin(tilt / 2) * 0.6, np.sin(tilt / 2) * 0.8, 0.0)
    run = on_box(Shape("c", "cylinder", (0.1, 0.2)), quat, 0.45, friction=0.8,
                 inertia=Inertia.solid_cylinder(1.0, 0.1, 0.4), t_end=2.0, dt=1e-3)
    distance = run["contact_distance"]
    assert distance[np.isfinite(distance)].min() >= -1e-13          # no overlap beyond round-off
    assert np.abs(run["body.velocity"][-1]).max() <= 1e-9            # at rest on the face
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-9)


def test_event_driven_scheme_refuses_them():
    run_scene = Scene.from_layout(
        Layout(bodies=(Body("b", Inertia.solid_cylinder(1.0, 0.1, 0.4), shapes=(Shape("c", "cylinder", (0.1, 0.2)),),
                            pos=(0, 0, 0.5)),), joints=(Joint("free", "free", "b"),),
               fixed=(Shape("table", "box", (1, 1, 0.3)),), contacts=(Contact("table", "c"),)), t_end=0.1)
    with pytest.raises(rbody.MethodNotApplicable, match="'table'/'c'"):
        rbody.simulate(run_scene, dt=1e-3, method="rk4")


CRATES_ON_LOGS_XML = """<mujoco><compiler angle="radian"/><option timestep="0.002"/>
  <asset>
    <mesh name="cube" vertex="-.1 -.1 -.1 .1 -.1 -.1 -.1 .1 -.1 .1 .1 -.1 -.1 -.1 .1 .1 -.1 .1 -.1 .1 .1 .1 .1 .1"/>
  </asset>
  <worldbody>
    <geom name="log" type="cylinder" size="0.3 0.5" quat="1 1 0 0"/>
    <geom name="log2" type="cylinder" size="0.3 0.5" pos="2 0 0" quat="1 1 0 0"/>
    <body name="mesh_crate" pos="0 0 0.4" euler="0 0 0.3">
      <freejoint/><geom type="mesh" mesh="cube" mass="1"/></body>
    <body name="box_crate" pos="2 0 0.4" euler="0 0 0.3">
      <freejoint/><geom type="box" size="0.1 0.1 0.1" mass="1"/></body>
  </worldbody>
</mujoco>"""


def test_crates_on_logs_from_mjcf_rest(tmp_path):
    """A user's file: a mesh crate and a box crate, turned 0.3 rad, each on a lying cylinder. rbody holds both on
    the ends of their lines: the box crate to round-off from its first state; the mesh crate after its first step,
    which lifts it by float32(0.1) - 0.1 (MuJoCo keeps a mesh's vertices in single precision: the file's crate
    overlaps the log by that). MuJoCo's soft contact lets them sink (measured: 2.1e-4 m in 1 s)."""
    path = tmp_path / "crates_on_logs.xml"
    path.write_text(CRATES_ON_LOGS_XML)
    scene = rbody.from_mjcf(path)
    run = rbody.simulate(scene, dt=scene.timestep, method=scene.file_method, t_end=1.0)
    box = run["box_crate.com"]
    assert np.abs(box - box[0]).max() <= 1e-15
    mesh = run["mesh_crate.com"]
    np.testing.assert_allclose(mesh[1, 2] - mesh[0, 2], float(np.float32(0.1)) - 0.1, rtol=0, atol=1e-15)
    assert np.abs(mesh[1:] - mesh[1]).max() <= 1e-15
    assert np.abs(run["mesh_crate.omega"]).max() <= 1e-14 and np.abs(run["box_crate.omega"]).max() <= 1e-14
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    for _ in range(500):
        mujoco.mj_step(model, data)
    assert 0.4 - data.qpos[2] > 1e-6 and 0.4 - data.qpos[9] > 1e-6  # MuJoCo's crates sink
