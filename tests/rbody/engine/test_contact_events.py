"""Event-driven contacts (method "rk4"): the rows' acceleration terms against finite differences, and the closed
forms of issue 22 to the event scheme's precision (impact times, bounce heights, the slide-to-roll time, the block
on an incline at the boundary of its cone)."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.engine.constraints import dynamics as dyn
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81


def random_quat(rng):
    q = rng.normal(size=4)
    return tuple(q / np.linalg.norm(q))


def two_bodies(kind_a, size_a, kind_b, size_b, pos_b, rng, plane_on_body=False):
    """Geom a on a free body 'A' (or a fixed plane), geom b on a free body 'B', each turned at random."""
    bodies, joints, fixed = [], [], []
    if kind_a == "plane" and not plane_on_body:
        fixed.append(Shape("a", "plane", (0, 0), quat=random_quat(rng)))
    else:
        bodies.append(Body("A", Inertia.solid_sphere(1.3, 0.2), shapes=(Shape("a", kind_a, size_a,
                                                                                quat=random_quat(rng)),),
                           pos=(0.0, 0.0, 0.0), quat=random_quat(rng)))
        joints.append(Joint("fa", "free", "A"))
    bodies.append(Body("B", Inertia.box(0.7, (0.3, 0.2, 0.1)), shapes=(Shape("b", kind_b, size_b,
                                                                            pos=(0.01, -0.02, 0.03),
                                                                            quat=random_quat(rng)),),
                       pos=pos_b, quat=random_quat(rng)))
    joints.append(Joint("fb", "free", "B"))
    return Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=tuple(fixed),
                  contacts=(Contact("a", "b", friction=0.5),))


def rows_at(model, y):
    p = np.asarray(model.params)[0]
    rows = model.constraints.rows
    nv = int(dyn.sizes(p)[1])
    M, f, J, jdot, g = np.empty((nv, nv)), np.empty(nv), np.empty((rows, nv)), np.empty(rows), np.empty(rows)
    dyn.state_rows(p, y, M, f, J, jdot, g)
    return p, J, jdot, g


PAIRS = [
    ("plane", (0, 0), "sphere", (0.1,), False),
    ("plane", (0, 0), "capsule", (0.05, 0.2), False),
    ("plane", (0, 0), "box", (0.1, 0.15, 0.05), False),
    ("plane", (0, 0), "sphere", (0.1,), True),
    ("sphere", (0.2,), "sphere", (0.1,), False),
    ("sphere", (0.2,), "capsule", (0.05, 0.3), False),
    ("capsule", (0.1, 0.4), "capsule", (0.05, 0.3), False),
    ("sphere", (0.2,), "box", (0.1, 0.15, 0.05), False),
    ("box", (0.2, 0.1, 0.15), "box", (0.1, 0.15, 0.05), False),
]


@pytest.mark.parametrize("kind_a, size_a, kind_b, size_b, plane_on_body", PAIRS)
def test_normal_rows_jdot_is_the_gaps_second_derivative(kind_a, size_a, kind_b, size_b, plane_on_body):
    """J' v of every candidate's normal row equals d/dt (J(q(t)) v) along q(t) = q (+) t v (qacc = 0), by a
    central difference (error ~1e-9 of the terms; a missing curvature term is of order one)."""
    rng = np.random.default_rng(7)
    worst = 0.0
    for trial in range(6):
        layout = two_bodies(kind_a, size_a, kind_b, size_b, tuple(rng.normal(scale=0.3, size=3)), rng,
                            plane_on_body)
        model = Scene.from_layout(layout, t_end=1.0).native_model
        y = np.array(np.asarray(model.y0)[0], dtype=float)
        p = np.asarray(model.params)[0]
        nq, nv, _n = (int(x) for x in dyn.sizes(p))
        y[nq:nq + nv] = rng.normal(size=nv)
        v = y[nq:nq + nv].copy()
        _p, J, jdot, g = rows_at(model, y)
        eps = 1e-5
        ends = []
        for sign in (1.0, -1.0):
            z = y.copy()
            dyn.displace(p, z, sign * eps * v)
            ends.append(rows_at(model, z)[1] @ v)
        fd = (ends[0] - ends[1]) / (2 * eps)
        normals = [unit.row0 for unit in model.constraints.units]
        scale = 1.0 + np.abs(fd[normals]).max()
        np.testing.assert_allclose(jdot[normals], fd[normals], rtol=0, atol=2e-7 * scale)
        worst = max(worst, np.abs(jdot[normals] - fd[normals]).max())
    assert worst > 0 or kind_a == "plane"


def ball_layout(r, height, friction, restitution=0.0):
    ball = Body("ball", Inertia.solid_sphere(1.0, r), shapes=(Shape("s", "sphere", (r,)),), pos=(0, 0, r + height))
    return Layout(bodies=(ball,), joints=(Joint("free", "free", "ball"),), fixed=(Shape("floor", "plane", (0, 0)),),
                  contacts=(Contact("floor", "s", friction=friction, restitution=restitution),))


def test_rolling_rows_hold_a_spinning_sphere_without_slip():
    """The tangent rows' J' v (the rolling point's term): a sphere rolling with spin about the normal too keeps
    its slip 0 and its height r (the material point's acceleration would leave a slip of omega x (omega x r))."""
    r = 0.1
    omega = np.array([1.5, -2.0, 4.0])
    v = np.cross(omega, [0, 0, r])  # no slip at the contact point
    scene = Scene.from_layout(ball_layout(r, 0.0, 0.5), t_end=1.0, qvel0=[*v, *omega])
    run = rbody.simulate(scene, dt=1e-2, method="rk4")
    z = run["ball.com"][:, 2]
    vel, w = run["ball.velocity"], run["ball.omega"]
    slip = vel + np.cross(w, [0, 0, -r])
    assert np.abs(z - r).max() <= 1e-14
    assert np.abs(slip).max() <= 1e-13
    assert np.abs(vel - vel[0]).max() <= 1e-13           # no force on a sphere rolling on a level plane
    assert len(run.events["time"]) == 0


def test_ball_bounces_at_the_exact_impact_times():
    """Restitution e: impact k at T0 (1 + 2e + ... + 2e^(k-1)), T0 = sqrt(2H/g); after impact k the energy is
    m g (r + e^(2k) H) (the bounce height e^(2k) H); found to the event scheme's precision. The impacts accumulate
    at 3 T0 (Zeno); an impact slower than 1e-6 of the first is plastic, and the ball rests."""
    r, H, e = 0.1, 1.0, 0.5
    run = rbody.simulate(Scene.from_layout(ball_layout(r, H, 0.5, e), t_end=1.4), dt=1e-3, method="rk4")
    assert run.meta["scheme"].startswith("event-driven")
    T0 = np.sqrt(2 * H / G)
    impacts = run.events["time"][run.events["what"] == "impact"]
    count = len(impacts)
    assert count >= 8
    closed = T0 * (1 + 2 * np.cumsum(np.r_[0.0, e ** np.arange(1, count)]))
    np.testing.assert_allclose(impacts, closed, rtol=0, atol=1e-10)
    # impact k's impulse (1 + e) m v_k, v_k = e^(k-1) sqrt(2 g H) (m = 1 kg), for the impacts Newton's law takes
    impulses = run.events["impulse"][run.events["what"] == "impact"][:4]
    np.testing.assert_allclose(impulses, (1 + e) * e ** np.arange(4) * np.sqrt(2 * G * H), rtol=1e-9)
    energy, t = run["energy"], run.t
    for k in range(4):
        between = (t > closed[k] + 1e-9) & (t < closed[k + 1] - 1e-9)
        np.testing.assert_allclose(energy[between], G * (r + e ** (2 * k + 2) * H), rtol=0, atol=1e-10)
    after = t > 3 * T0 + 1e-6
    assert after.any() and np.abs(run["ball.velocity"][after]).max() <= 1e-12 and run["contacts"][-1] == 1
    assert (run["ball.com"][:, 2] - r).min() >= -1e-15   # never below the floor
    total = run["energy"] + run["dissipated"]
    np.testing.assert_allclose(total, total[0], rtol=0, atol=1e-10)


def test_ball_dropped_plastic_rests_at_the_impact():
    r, H = 0.1, 1.0
    run = rbody.simulate(Scene.from_layout(ball_layout(r, H, 0.5, 0.0), t_end=1.0), dt=1e-3, method="rk4")
    T0 = np.sqrt(2 * H / G)
    assert run.events["what"][0] == "impact"
    assert abs(run.events["time"][0] - T0) <= 1e-12
    after = run.t > T0
    assert np.abs(run["ball.com"][after, 2] - r).max() <= 1e-15
    assert np.abs(run["ball.velocity"][after]).max() <= 1e-15
    np.testing.assert_allclose(run["contact_normal_force"][-1], [G], rtol=1e-12)


def test_sphere_thrown_sliding_rolls_from_t_star():
    """Thrown sliding without spin: slides with v0 - mu g t until t* = 2 v0 / (7 mu g), then rolls at 5/7 v0 for
    ever; the event is located at t* to 1e-10 s, the speeds are exact, the height is r."""
    r, mu, v0 = 0.1, 0.3, 2.0
    scene = Scene.from_layout(ball_layout(r, 0.0, mu), t_end=1.0, qvel0=[v0, 0, 0, 0, 0, 0])
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    t_star = 2 * v0 / (7 * mu * G)
    assert list(run.events["what"]) == ["stick"]
    assert abs(run.events["time"][0] - t_star) <= 1e-10
    v, spin, z, t = run["ball.velocity"][:, 0], run["ball.omega"][:, 1], run["ball.com"][:, 2], run.t
    np.testing.assert_allclose(v[t < t_star], v0 - mu * G * t[t < t_star], rtol=0, atol=1e-12)
    np.testing.assert_allclose(spin[t < t_star], 5 * mu * G * t[t < t_star] / (2 * r), rtol=0, atol=1e-10)
    np.testing.assert_allclose(v[t > t_star], 5 / 7 * v0, rtol=0, atol=1e-12)
    assert np.abs(v - r * spin)[t > t_star].max() <= 1e-12
    assert np.abs(z - r).max() <= 1e-15
    total = run["energy"] + run["dissipated"]
    np.testing.assert_allclose(total, total[0], rtol=0, atol=1e-12)


def incline(mu, alpha=0.3, half=(0.1, 0.1, 0.05)):
    q = (np.cos(alpha / 2), 0.0, np.sin(alpha / 2), 0.0)
    R = quat_to_matrix(np.array(q))
    box = Body("box", Inertia.box(1.0, 2 * np.array(half)), shapes=(Shape("b", "box", half),),
               pos=tuple(R[:, 2] * half[2]), quat=q)
    layout = Layout(bodies=(box,), joints=(Joint("free", "free", "box"),),
                    fixed=(Shape("ramp", "plane", (0, 0), quat=q),), contacts=(Contact("ramp", "b", friction=mu),))
    return layout, R


@pytest.mark.parametrize("factor", [1 + 1e-6, 2.0])
def test_block_on_incline_sticks_exactly(factor):
    alpha = 0.3
    layout, R = incline(np.tan(alpha) * factor, alpha)
    run = rbody.simulate(Scene.from_layout(layout, t_end=10.0), dt=1e-2, method="rk4")
    com = run["box.com"]
    assert np.abs(com - com[0]).max() <= 1e-16            # round-off (5e-18 m measured); a creeping block: 1.5e-4 m
    assert len(run.events["time"]) == 0
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G * np.cos(alpha), rtol=1e-12)


@pytest.mark.parametrize("factor", [1 - 1e-6, 0.3])
def test_block_on_incline_slides_exactly(factor):
    """x = g (sin(alpha) - mu cos(alpha)) t^2 / 2 to round-off (the event scheme integrates the sliding mode with
    RK4, exact on a quadratic), no lift-off, no turning; at mu = tan(alpha)(1 - 1e-6) it moves 5.8e-6 m in 2 s."""
    alpha = 0.3
    mu = np.tan(alpha) * factor
    layout, R = incline(mu, alpha)
    run = rbody.simulate(Scene.from_layout(layout, t_end=2.0), dt=1e-2, method="rk4")
    t = run.t
    x = (run["box.com"] - run["box.com"][0]) @ R[:, 0]
    a = G * (np.sin(alpha) - mu * np.cos(alpha))
    np.testing.assert_allclose(x, a * t ** 2 / 2, rtol=1e-9, atol=1e-15)
    assert np.abs((run["box.com"] - run["box.com"][0]) @ R[:, 2]).max() <= 1e-15
    assert np.abs(run["box.quat"] - run["box.quat"][0]).max() <= 1e-14
    assert run["contacts"][-1] == 4
    np.testing.assert_allclose(np.linalg.norm(run["contact_friction_force"][-1].sum(axis=0)),
                               mu * G * np.cos(alpha), rtol=1e-12)


@pytest.mark.parametrize("restitution", [0.5, pytest.param(0.0, marks=pytest.mark.slow)])
def test_a_tumbling_box_comes_to_rest_on_its_face(restitution):
    """A box dropped turned and spinning: impacts on single corners, corners sliding in different directions (a
    face that turns as it slides), releases and sticks, until it rests on its face. No corner below the floor
    beyond the projection's round-off, energy + dissipated kept to the RK4 error (measured 1.9e-9 J for e = 0.5,
    6e-7 J for e = 0, of 10.8 J)."""
    half = (0.2, 0.1, 0.05)
    box = Body("box", Inertia.box(2.0, 2 * np.array(half)), shapes=(Shape("b", "box", half),), pos=(0, 0, 0.55),
               quat=(np.cos(0.05), np.sin(0.05), 0, 0))
    layout = Layout(bodies=(box,), joints=(Joint("free", "free", "box"),), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", "b", friction=0.5, restitution=restitution),))
    run = rbody.simulate(Scene.from_layout(layout, t_end=2.0, qvel0=[0.5, 0, 0, 0, 0, 1.0]), dt=1e-3, method="rk4")
    what = set(run.events["what"])
    assert {"impact", "slip", "stick", "release"} <= what
    assert run["contact_distance"].min() >= -1e-13
    assert abs(run["box.com"][-1, 2] - half[2]) <= 1e-13                      # on its face
    assert np.abs(run["qvel"][-1]).max() <= 1e-12                             # at rest
    assert run["contacts"][-1] == 4
    total = run["energy"] + run["dissipated"]
    assert np.abs(total - total[0]).max() <= 1e-6 * total[0]
