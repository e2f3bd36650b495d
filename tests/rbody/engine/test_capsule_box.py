"""Capsule-box contacts (rbody.engine.contacts.geometry): the exact segment-box distance against dense sampling and
closed forms, MuJoCo's capsule-box distance on random separated poses, and a capsule on a box in the rigid limit
(impact time, resting without sinking), from Python and from MJCF."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.engine.contacts.geometry import APART, collide_pair, segment_box_closest
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81
I3 = np.eye(3)


def rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def about_y(angle):
    return quat_to_matrix(np.array([np.cos(angle / 2), 0.0, np.sin(angle / 2), 0.0]))


def test_segment_box_closest_is_the_least_distance():
    """The least distance over the segment, never above a dense sampling of it, and the sampling never below it
    by more than its spacing allows."""
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(300):
        h = rng.uniform(0.1, 0.6, 3)
        c, u = rng.normal(size=3) * 0.8, rng.normal(size=3)
        u /= np.linalg.norm(u)
        half = rng.uniform(0.05, 0.8)
        closest, lo, hi, squared = segment_box_closest(c, u, half, h)
        t = np.linspace(-half, half, 20001)
        sampled = np.sum(np.maximum(np.abs(c + t[:, None] * u) - h, 0.0) ** 2, axis=1)
        assert -half <= lo <= closest <= hi <= half
        assert squared <= sampled.min() + 1e-14
        assert np.sqrt(sampled.min()) - np.sqrt(squared) <= half * 1e-4
        for at in (lo, closest, hi):  # the closest point gives it, and so does the span about it
            value = np.sum(np.maximum(np.abs(c + at * u) - h, 0.0) ** 2)
            assert value == pytest.approx(squared, rel=1e-12, abs=1e-300)
        checked += squared > 0
    assert checked > 100


def test_capsule_across_an_edge_closed_form():
    """A capsule whose axis passes over a box's edge (the edge along y at x = z = 1/2), tilted by theta from the
    top face and at height b above the edge where it crosses x = 1/2: the line of the axis is b cos(theta) from the
    edge, at the axis parameter b sin(theta); slot 2 holds that contact, slots 0 and 1 are APART. Moved back along
    its axis until its lower end is over the face, the closest point is that end (clamped)."""
    h, r, half, b, theta = np.array([0.5, 0.5, 0.5]), 0.05, 0.4, 0.2, 0.3
    R = about_y(theta) @ about_y(np.pi / 2)  # the capsule's axis (its z) turned onto (cos theta, 0, -sin theta)
    axis = R[:, 2]
    np.testing.assert_allclose(axis, [np.cos(theta), 0.0, -np.sin(theta)], rtol=0, atol=1e-15)
    centre = np.array([0.5, 0.0, 0.5 + b])
    dist, normal, point = collide_pair("capsule", centre, R, [r, half], "box", [0, 0, 0], I3, h)
    assert len(dist) == 3
    assert dist[2] == pytest.approx(b * np.cos(theta) - r, abs=1e-15)
    towards = np.array([-np.sin(theta), 0.0, -np.cos(theta)])  # from the axis down onto the edge
    np.testing.assert_allclose(normal[2], towards, rtol=0, atol=1e-15)
    on_axis = centre + b * np.sin(theta) * axis
    np.testing.assert_allclose(point[2], on_axis + (r + 0.5 * dist[2]) * towards, rtol=0, atol=1e-15)
    assert dist[0] > dist[2] and dist[1] > dist[2]  # the ends: farther
    back = centre - (half + 0.1) * axis  # its lower end at centre - 0.1 axis: over the face, b + 0.1 sin(theta) up
    dist, normal, point = collide_pair("capsule", back, R, [r, half], "box", [0, 0, 0], I3, h)
    assert dist[2] == pytest.approx(b + 0.1 * np.sin(theta) - r, abs=1e-15)
    np.testing.assert_allclose(normal[2], [0, 0, -1.0], rtol=0, atol=1e-15)
    assert point[2, 0] == pytest.approx(0.5 - 0.1 * np.cos(theta), abs=1e-15)
    assert dist[1] == APART and dist[0] > dist[2]  # that end is the closest point: only the other end is its own


def test_capsule_lying_on_a_face_rests_on_its_span():
    """Lying flat over the top face: the closest points span the whole segment; slot 2 is its middle, slots 0 and 1
    its ends, all at height b - r. Overhanging one side: the span runs from the box's edge to the end on the face.
    Tilted by 1e-3 rad: one closest point, the lower end (slot 2), and the upper end (slot 0) 4e-4 m above it."""
    dist, normal, point = collide_pair("capsule", [0.1, 0.0, 0.8], about_y(np.pi / 2), [0.1, 0.2], "box", [0, 0, 0],
                                       I3, [0.5, 0.5, 0.5])
    np.testing.assert_allclose(dist, 0.2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(normal, [[0, 0, -1.0]] * 3, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.sort(point[:, 0]), [-0.1, 0.1, 0.3], rtol=0, atol=1e-15)
    dist, normal, point = collide_pair("capsule", [0.4, 0.0, 0.8], about_y(np.pi / 2), [0.1, 0.3], "box", [0, 0, 0],
                                       I3, [0.5, 0.5, 0.5])
    np.testing.assert_allclose(dist, 0.2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.sort(point[:2, 0]), [0.1, 0.5], rtol=0, atol=1e-15)
    dist, normal, point = collide_pair("capsule", [0.1, 0.0, 0.8], about_y(np.pi / 2 + 1e-3), [0.1, 0.2], "box",
                                       [0, 0, 0], I3, [0.5, 0.5, 0.5])
    assert dist[1] == APART and dist[0] == pytest.approx(0.2 + 0.2 * np.sin(1e-3), abs=1e-15)
    assert dist[2] == pytest.approx(0.2 - 0.2 * np.sin(1e-3), abs=1e-15)


def test_against_mujoco_on_random_separated_poses():
    """MuJoCo's capsule-box distance (mj_collision, a margin wide enough to report every pose) equals the least of
    rbody's candidates to round-off, and so does its normal, wherever the two are apart."""
    mujoco = pytest.importorskip("mujoco")
    xml = ('<mujoco><worldbody><body name="A"><freejoint/><geom name="a" type="capsule" size="0.1 0.4" margin="100"/>'
           '</body><body name="B"><freejoint/><geom name="b" type="box" size="0.3 0.4 0.5" margin="100"/></body>'
           '</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    ga, gb = model.geom("a").id, model.geom("b").id
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(300):
        for j in range(model.njnt):
            adr = model.jnt_qposadr[j]
            data.qpos[adr:adr + 3] = rng.uniform(-0.8, 0.8, size=3)
            q = rng.normal(size=4)
            data.qpos[adr + 3:adr + 7] = q / np.linalg.norm(q)
        mujoco.mj_forward(model, data)
        dist, normal, _ = collide_pair("capsule", data.geom_xpos[ga], data.geom_xmat[ga].reshape(3, 3), (0.1, 0.4),
                                       "box", data.geom_xpos[gb], data.geom_xmat[gb].reshape(3, 3), (0.3, 0.4, 0.5))
        contacts = list(data.contact[:data.ncon])
        nearest = min(contacts, key=lambda c: c.dist)
        if nearest.dist <= 0:
            continue
        k = int(np.argmin(dist))
        assert dist[k] == pytest.approx(nearest.dist, abs=1e-12)
        sign = 1.0 if (nearest.geom1, nearest.geom2) == (ga, gb) else -1.0
        np.testing.assert_allclose(sign * normal[k], nearest.frame[:3], rtol=0, atol=1e-9)
        checked += 1
    assert checked > 150


def capsule_over_box(b, theta, r=0.05, half=0.3, shift=0.0, friction=1.0):
    """A free capsule (1 kg) tilted by theta, its axis crossing the edge x = z = 1/2 of a fixed unit box at height b
    above it (test_capsule_across_an_edge_closed_form's pose), moved by `shift` along x."""
    R = about_y(theta) @ about_y(np.pi / 2)
    w = np.cos((theta + np.pi / 2) / 2), 0.0, np.sin((theta + np.pi / 2) / 2), 0.0
    np.testing.assert_allclose(quat_to_matrix(np.array(w)), R, rtol=0, atol=1e-15)
    capsule = Body("rod", Inertia.solid_cylinder(1.0, r, 2 * half), shapes=(Shape("c", "capsule", (r, half)),),
                   pos=(0.5 + shift, 0.0, 0.5 + b - shift * np.tan(theta)), quat=w)
    return Layout(bodies=(capsule,), joints=(Joint("free", "free", "rod"),),
                  fixed=(Shape("block", "box", (0.5, 0.5, 0.5)),), contacts=(Contact("block", "c", friction=friction),))


def test_capsule_falls_onto_an_edge_in_the_step_of_the_closed_form():
    """Falling straight down, the axis's distance from the edge is (b - g t^2 / 2) cos(theta): it touches at
    t = sqrt(2 (b - r / cos(theta)) / g). The time-stepping stops it in the step that holds that time, and no
    point of it passes into the box (the contacts' distances >= 0 to round-off) as it tips off the edge."""
    b, theta, r, dt = 0.2, 0.3, 0.05, 1e-3
    run = rbody.simulate(Scene.from_layout(capsule_over_box(b, theta, r, shift=-0.1, friction=0.5), t_end=0.5), dt=dt)
    touch = np.sqrt(2 * (b - r / np.cos(theta)) / G)
    held = run["contact_normal_force"].sum(axis=1) > 0
    first = run.t[np.argmax(held)]
    assert touch <= first <= touch + dt
    np.testing.assert_allclose(run["rod.velocity"][run.t < touch - dt, 2], -G * run.t[run.t < touch - dt],
                               rtol=0, atol=1e-12)
    dist = run["contact_distance"]
    assert np.min(dist[np.isfinite(dist)]) >= -1e-13
    assert np.all(np.isfinite(dist[:, 2]))  # the closest point: always a candidate


@pytest.mark.parametrize("friction", [1.0, 2.0])
def test_capsule_tipping_onto_a_face_with_high_friction(friction):
    """The step where the tipping capsule's end lands on the face while its edge contact sticks: the two contacts'
    tangent rows are nearly dependent, no impulses hold both, and the end slides (cone.slide_polish); nothing
    passes into the box."""
    run = rbody.simulate(Scene.from_layout(capsule_over_box(0.2, 0.3, 0.05, shift=-0.1, friction=friction),
                                           t_end=0.5), dt=1e-3)
    dist = run["contact_distance"]
    assert np.min(dist[np.isfinite(dist)]) >= -1e-13
    assert run["rod.com"][-1, 2] == pytest.approx(0.55, abs=1e-13)  # lying on the face at the end


def test_event_driven_scheme_refuses_capsule_box():
    scene = Scene.from_layout(capsule_over_box(0.2, 0.3), t_end=0.1)
    assert "rk4" not in scene.methods and "moreau" in scene.methods
    with pytest.raises(rbody.MethodNotApplicable, match="the contact 'block'/'c' does not have"):
        rbody.simulate(scene, dt=1e-3, method="rk4")


@pytest.mark.parametrize("method", ["moreau", "mujoco_euler"])
def test_capsule_lying_on_a_box_stays_put(method):
    """A capsule laid flat on a box's top face rests on the span of its closest points (its ends and middle) for
    1 s: no sinking, no drift beyond round-off, the contacts carrying its weight."""
    r, half = 0.05, 0.3
    w = np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0
    capsule = Body("rod", Inertia.solid_cylinder(1.0, r, 2 * half), shapes=(Shape("c", "capsule", (r, half)),),
                   pos=(0.1, 0.0, 0.5 + r), quat=w)
    layout = Layout(bodies=(capsule,), joints=(Joint("free", "free", "rod"),),
                    fixed=(Shape("block", "box", (0.5, 0.5, 0.5)),), contacts=(Contact("block", "c", friction=0.5),))
    run = rbody.simulate(Scene.from_layout(layout, t_end=1.0), dt=2e-3, method=method)
    com = run["rod.com"]
    assert np.abs(com - com[0]).max() <= 1e-13
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-9)  # the weight, over the span
    assert np.all(np.isfinite(run["contact_distance"][-1]))  # its ends and its middle


CAPSULE_ON_BOX_XML = """
<mujoco model="capsule on a box">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="block" type="box" size="0.5 0.5 0.5" pos="0 0 0.5"/>
    <body name="rod" pos="0.1 0 1.05" euler="0 90 0">
      <freejoint/>
      <geom name="c" type="capsule" size="0.05 0.3" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_capsule_on_box_from_mjcf_runs_and_rests(tmp_path):
    """The pair that was refused loads; rbody holds the capsule on the box to round-off where MuJoCo's soft contact
    lets it sink (its divergence from the rigid limit)."""
    path = tmp_path / "capsule_on_box.xml"
    path.write_text(CAPSULE_ON_BOX_XML)
    scene = rbody.from_mjcf(path)
    run = rbody.simulate(scene, dt=scene.timestep, method=scene.file_method, t_end=1.0)
    z = run["rod.com"][:, 2]
    assert np.abs(z - 1.05).max() <= 1e-13
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    for _ in range(500):
        mujoco.mj_step(model, data)
    assert 1.05 - data.qpos[2] > 1e-6  # MuJoCo's contact sinks (measured: 2.1e-4 m in 1 s)


def test_slide_polish_finds_the_sliding_solution_the_stick_states_miss():
    """That landing step's problem (6 rows: the edge contact's normal and tangents, the end's; mu = 2), as the
    time-stepping posed it, from where Gauss-Seidel settled: both contacts inside their cones, slipping -+5.7e-5 m/s.
    Holding both sticking has no solution (the tangent rows are dependent to 2e-15), so stick_polish and
    cone_polish stay at the residual; slide_polish makes the end slide against its slip and solves it exactly."""
    from rbody.engine.constraints.cone import NORMAL, TANGENT, TANGENT2, cone_polish, cone_residual, slide_polish, \
        stick_polish

    W = np.array([[3.9387739233812993, 0.48915193883467306, 0.0, -0.17770832309607823, 0.4905338585811731, 0.0],
                  [0.48915193883467306, 1.0814181782960768, 0.0, -0.1967615280005547, 1.0815256165203968, 0.0],
                  [0.0, 0.0, 5.950449161299519, 0.0, 0.0, 1.8286378861841486],
                  [-0.17770832309607823, -0.1967615280005547, 0.0, 1.4719642594275848, -0.19628603189841715, 0.0],
                  [0.4905338585811731, 1.0815256165203968, 0.0, -0.19628603189841715, 1.0816337371926315, 0.0],
                  [0.0, 0.0, 1.8286378861841486, 0.0, 0.0, 3.4719908206470613]])
    b = np.array([-1.856372304041758, 0.003959063282221453, 0.0, -0.008470128160270318, 0.0031599313284780273, 0.0])
    start = np.array([0.500705175278706, -0.20838136742008317, 0.0, 0.03633591508259261, -0.015095427477989462, 0.0])
    role = np.array([NORMAL, TANGENT, TANGENT2] * 2)
    mu = np.array([0.0, 2.0, 0.0] * 2)
    lo, hi = np.array([0.0, -np.inf, -np.inf] * 2), np.full(6, np.inf)
    before = cone_residual(W, b, lo, hi, role, mu, start)
    assert before > 5e-5
    for polish in (stick_polish, cone_polish):
        assert polish(W, b, lo, hi, role, mu, start.copy(), 4) >= before * (1 - 1e-9)
    lam = start.copy()
    assert slide_polish(W, b, lo, hi, role, mu, lam, 4) <= 1e-13
    w = b + W @ lam
    assert lam[4] == pytest.approx(mu[4] * lam[3], rel=1e-12) and w[4] < 0  # the end slides against its slip
    assert abs(lam[1]) < mu[1] * lam[0] and abs(w[1]) <= 1e-13              # the edge contact sticks
    # the step's own schedule (cone_solve, which tries slide_polish after the interior finish) from that start
    from rbody.engine.constraints.stepping import cone_solve

    scheduled = start.copy()
    assert cone_solve(W, b, lo, hi, role, mu, scheduled, 1e-10, 2000) <= 1e-13
    w = b + W @ scheduled
    assert scheduled[4] == pytest.approx(mu[4] * scheduled[3], rel=1e-12) and w[4] < 0


def test_a_slot_that_is_not_a_contact_point_has_no_point_or_normal(tmp_path):
    """A capsule tilted 5 degrees above a box, its lower end 1 mm from the face: slot 0 (the axis's closest point,
    here that end) is APART, and its point and normal are NaN, not whatever the pair's work held before (they were
    left unwritten, and differed from run to run); the other slots' are the ends' points on the face."""
    path = tmp_path / "rod.xml"
    path.write_text("""<mujoco><option timestep="0.002"/><worldbody>
<geom name="table" type="box" size="0.5 0.5 0.05" pos="0 0 -0.05"/>
<body name="rod" pos="0 0 0.0297" euler="0 85 0"><freejoint/><geom name="rod" type="capsule" size="0.02 0.1"/></body>
</worldbody></mujoco>""")
    scene = rbody.from_mjcf(path, t_end=0.02)
    run = rbody.simulate(scene, dt=scene.timestep, method=scene.file_method)
    dist, point, normal = run["contact_distance"], run["contact_point"], run["contact_normal"]
    apart = dist == APART
    assert apart[:, 0].all() and not apart[:, 1:].any()
    assert np.isnan(point[apart]).all() and np.isnan(normal[apart]).all()
    assert np.isfinite(point[~apart]).all()
    down = np.broadcast_to([0.0, 0.0, -1.0], normal[~apart].shape)  # from geom a (the rod) towards b (the table)
    np.testing.assert_allclose(normal[~apart], down, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.abs(point[0, 1:, 0]), 0.1 * np.cos(np.radians(5)), rtol=1e-9)
