"""Contacts in the rigid limit (rbody.engine.constraints with rbody.engine.contacts) against closed forms.

Contacts run by the constraint layer's time-stepping scheme (Moreau-Jean, order 1; method "moreau"), so each case
asserts what that scheme makes exact (speeds after an impulsive transition, no penetration, no drift, sticking
classified to the last bit, the discrete motion under constant force) and bounds by one step what it locates only
within a step (the time rolling starts, impact times and bounce heights)."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81


def ball_layout(r, height, friction, restitution=0.0):
    ball = Body("ball", Inertia.solid_sphere(1.0, r), shapes=(Shape("s", "sphere", (r,)),), pos=(0, 0, r + height))
    return Layout(bodies=(ball,), joints=(Joint("free", "free", "ball"),), fixed=(Shape("floor", "plane", (0, 0)),),
                  contacts=(Contact("floor", "s", friction=friction, restitution=restitution),))


def test_sphere_thrown_sliding_rolls_at_five_sevenths():
    r, mu, v0, dt = 0.1, 0.3, 2.0, 1e-3
    run = rbody.simulate(Scene.from_layout(ball_layout(r, 0.0, mu), t_end=1.0, qvel0=[v0, 0, 0, 0, 0, 0]), dt=dt)
    assert run.meta["scheme"].startswith("time-stepping")
    v, spin, z = run["ball.velocity"][:, 0], run["ball.omega"][:, 1], run["ball.com"][:, 2]
    t_star = 2 * v0 / (7 * mu * G)
    rolling = np.abs(v - r * spin) <= 1e-12
    start = run.t[np.argmax(rolling)]
    assert t_star <= start <= t_star + dt                      # rolling begins in the step that holds t*
    assert np.all(rolling[run.t >= start])                     # and never slips again
    sliding = run.t < t_star - dt
    np.testing.assert_allclose(v[sliding], v0 - mu * G * run.t[sliding], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[run.t >= start], 5 / 7 * v0, rtol=0, atol=1e-12)
    assert np.abs(z - r).max() <= 1e-15                        # the height stays r
    assert not run.data.is_computed("contacts")                # counted from the kept impulses when asked for
    assert run["contacts"][-1] == 1
    np.testing.assert_allclose(run["contact_normal_force"][-1], [G], rtol=1e-12)
    # what friction took while sliding is `dissipated`: energy + dissipated is constant
    total = run["energy"] + run["dissipated"]
    assert np.abs(total - total[0]).max() <= 1e-12 * total[0]


def incline(mu, alpha=0.3, half=(0.1, 0.1, 0.05)):
    """A box resting on a plane turned by alpha about y, its axes along the plane."""
    q = (np.cos(alpha / 2), 0.0, np.sin(alpha / 2), 0.0)
    R = quat_to_matrix(np.array(q))
    box = Body("box", Inertia.box(1.0, 2 * np.array(half)), shapes=(Shape("b", "box", half),),
               pos=tuple(R[:, 2] * half[2]), quat=q)
    layout = Layout(bodies=(box,), joints=(Joint("free", "free", "box"),),
                    fixed=(Shape("ramp", "plane", (0, 0), quat=q),), contacts=(Contact("ramp", "b", friction=mu),))
    return layout, R


@pytest.mark.parametrize("factor", [1 + 1e-6, 1.0, 2.0])
def test_block_on_incline_sticks_when_tan_alpha_within_mu(factor):
    alpha = 0.3
    layout, R = incline(np.tan(alpha) * factor, alpha)
    run = rbody.simulate(Scene.from_layout(layout, t_end=100.0), dt=1e-2)
    com = run["box.com"]
    # no creep in 100 s: what moves is round-off (velocities of 1e-18 m/s left by each step's solve; 1.3e-14 m
    # measured at mu = tan(alpha) (1 + 1e-6)), where a creeping block would move mu g cos(alpha) 1e-6 t^2 / 2 = 0.015 m
    assert np.abs(com - com[0]).max() <= 1e-13
    assert run["contacts"][-1] == 4
    # the cone holds the weight: friction m g sin(alpha) and normal m g cos(alpha) over the four corners
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G * np.cos(alpha), rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(run["contact_friction_force"][-1].sum(axis=0)), G * np.sin(alpha),
                               rtol=1e-12)


@pytest.mark.parametrize("factor", [1 - 1e-6, 0.3])
def test_block_on_incline_slides_otherwise(factor):
    alpha, dt = 0.3, 1e-3
    mu = np.tan(alpha) * factor
    layout, R = incline(mu, alpha)
    run = rbody.simulate(Scene.from_layout(layout, t_end=2.0), dt=dt)
    t = run.t
    x = (run["box.com"] - run["box.com"][0]) @ R[:, 0]         # down the slope (the plane's x axis dips)
    a = G * (np.sin(alpha) - mu * np.cos(alpha))
    assert a > 0 and x[-1] > 0
    # the scheme's own closed form (symplectic Euler under a constant force): x_k = a t_k (t_k + dt) / 2, exact
    np.testing.assert_allclose(x, a * t * (t + dt) / 2, rtol=0, atol=1e-12 * G)
    # the continuous one, x = a t^2 / 2, to within one step's travel a t dt / 2 (order 1)
    assert np.all(np.abs(x - a * t ** 2 / 2) <= a * t * dt / 2 + 1e-12 * G)
    height = (run["box.com"] - run["box.com"][0]) @ R[:, 2]
    assert np.abs(height).max() <= 1e-14                       # no sinking, no lift-off


def test_ball_dropped_plastic_rests_at_once():
    r, H, dt = 0.1, 1.0, 1e-3
    run = rbody.simulate(Scene.from_layout(ball_layout(r, H, 0.5, 0.0), t_end=2.0), dt=dt)
    z = run["ball.com"][:, 2] - r
    T0 = np.sqrt(2 * H / G)
    assert z.min() >= 0.0
    after = run.t >= T0 + dt
    assert np.all(z[after] == 0.0)                             # on the floor from the step of the impact on
    assert np.abs(run["ball.velocity"][after]).max() <= 1e-17  # at rest to round-off (1.7e-18 m/s measured)


def test_ball_bounces_with_restitution_order_one():
    """Impacts are located within the step (the time-stepping scheme; the event-driven one for contacts is still to
    come): impact k within 2k steps of T0 (1 + 2e + ... + 2e^(k-1)), bounce k within 2 sqrt(2gH) dt of e^(2k) H,
    both errors shrinking with dt (measured at dt = 1e-3: 4.2e-3 s and 1.7e-3 m; at 2.5e-4: 1.2e-3 s, 9e-4 m)."""
    r, H, e = 0.1, 1.0, 0.5
    T0 = np.sqrt(2 * H / G)
    closed = T0 * np.array([1, 1 + 2 * e, 1 + 2 * e + 2 * e ** 2])
    worst = []
    for dt in (1e-3, 2.5e-4):
        run = rbody.simulate(Scene.from_layout(ball_layout(r, H, 0.5, e), t_end=1.5), dt=dt)
        z, vz, t = run["ball.com"][:, 2] - r, run["ball.velocity"][:, 2], run.t
        impacts = t[1:][(vz[1:] > 0) & (vz[:-1] <= 0)][:3]
        assert np.all(np.abs(impacts - closed) <= 2 * np.arange(1, 4) * dt)
        peaks = np.array([z[(t > t0) & (t < t1)].max() for t0, t1 in zip(closed, closed[1:])])
        assert np.all(np.abs(peaks - e ** (2 * np.arange(1, 3)) * H) <= 2 * np.sqrt(2 * G * H) * dt)
        assert z.min() >= 0.0                                   # never below the floor
        worst.append(np.abs(impacts - closed).max())
    assert worst[1] < worst[0] / 2                              # order 1: a quarter of the step, a quarter the error


def test_box_resting_100_s():
    half = (0.2, 0.1, 0.05)
    box = Body("box", Inertia.box(2.0, 2 * np.array(half)), shapes=(Shape("b", "box", half),), pos=(0.3, -0.2, 0.05))
    layout = Layout(bodies=(box,), joints=(Joint("free", "free", "box"),), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", "b", friction=0.8),))
    run = rbody.simulate(Scene.from_layout(layout, t_end=100.0), dt=1e-2)
    qpos = run["qpos"]
    assert np.abs(qpos - qpos[0]).max() <= 1e-15
    assert run["contact_distance"].min() >= -1e-15
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), 2.0 * G, rtol=1e-12)


def stack_layout() -> Layout:
    """Five boxes, each narrower than the one below (half sizes 0.3 - 0.04 k, 0.25 - 0.04 k, 0.05 m, masses 1 + k kg),
    stacked from the floor, offset 0.01 k, -0.005 k m sideways; friction 0.5 at every interface."""
    bodies, joints, contacts = [], [], [Contact("floor", "b0", friction=0.5)]
    z = 0.0
    for k in range(5):
        half = (0.3 - 0.04 * k, 0.25 - 0.04 * k, 0.05)
        z += half[2]
        bodies.append(Body(f"box{k}", Inertia.box(1.0 + k, 2 * np.array(half)), shapes=(Shape(f"b{k}", "box", half),),
                           pos=(0.01 * k, -0.005 * k, z)))
        z += half[2]
        joints.append(Joint(f"free{k}", "free", f"box{k}"))
        if k:
            contacts.append(Contact(f"b{k - 1}", f"b{k}", friction=0.5))
    return Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=(Shape("floor", "plane", (0, 0)),),
                  contacts=tuple(contacts))


@pytest.mark.parametrize("t_end, dt", [(5.0, 1e-2), (5.0, 0.1), pytest.param(100.0, 1e-2, marks=pytest.mark.slow)])
def test_stack_of_five_boxes_resting(t_end, dt):
    """Five boxes, each narrower than the one below, on a floor: 20 corner contacts holding (100 s: 66 s of run
    on a shared 2-core machine, hence slow; 5 s in the default suite), at the contact sweep's steps (0.1 s its
    coarsest)."""
    run = rbody.simulate(Scene.from_layout(stack_layout(), t_end=t_end), dt=dt)
    qpos = run["qpos"]
    # no drift, no sinking: round-off only (1.6e-14 measured over 100 s, mostly in the quaternions)
    assert np.abs(qpos - qpos[0]).max() <= 1e-13
    # no overlap beyond the layer's projection tolerance (rbody.engine.constraints.dynamics.PROJECTION_TOLERANCE,
    # 1e-13 m): round-off of coordinates near 0.5 m
    assert run["contact_distance"].min() >= -1e-13
    assert run["contacts"][-1] == 20                            # four corners under each box
    force = run["contact_normal_force"][-1]
    names = run.meta["contacts"]
    for k in range(5):  # each interface carries the weight of the boxes above it
        under = sum(force[i] for i, name in enumerate(names) if name.split("/")[1].startswith(f"b{k}["))
        np.testing.assert_allclose(under, G * sum(1.0 + j for j in range(k, 5)), rtol=1e-10)
