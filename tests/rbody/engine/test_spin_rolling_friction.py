"""Torsional (condim 4) and rolling (condim 6) friction in the rigid limit, against closed forms.

Each is its own Coulomb law sharing the normal force N (rbody.engine.constraints.cone): the torque about the
normal |T_s| <= mu_s N, against the spin; the torque about the tangents |T_r| <= mu_r N, against the rolling. A solid
ball (I = 2/5 m r^2, k = 2/5) then has closed forms:

- rolling on a plane: the rolling torque mu_r m g decelerates it without slip, v' = -mu_r g / (r (1 + k)), until it
  stops at t_s = v0 r (1 + k) / (mu_r g), where it stays;
- spinning about the normal: w' = -mu_s m g / I until t_s = I w0 / (mu_s m g);
- on an incline of angle alpha: it rests when r tan(alpha) <= mu_r (the friction force m g sin(alpha) holding it
  has a moment m g r sin(alpha) about the centre, which the rolling torque must carry), else it rolls down with
  a = g (sin(alpha) - mu_r cos(alpha) / r) / (1 + k).

The time-stepping scheme locates a stop within a step: the motion before it and the rest after it are exact.
"""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.errors import MethodNotApplicable
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81
K = 0.4  # a solid ball's I / (m r^2)


def ball(r=0.1, mu=1.0, torsion=0.0, rolling=0.0, condim=6, alpha=0.0, mass=1.0):
    """A solid ball resting on a plane tilted by alpha about y (down the slope: -x' of the plane's axes)."""
    q = (np.cos(alpha / 2), 0.0, np.sin(alpha / 2), 0.0)
    normal = quat_to_matrix(np.array(q))[:, 2]
    body = Body("ball", Inertia.solid_sphere(mass, r), shapes=(Shape("s", "sphere", (r,)),), pos=tuple(r * normal))
    return Layout(bodies=(body,), joints=(Joint("free", "free", "ball"),),
                  fixed=(Shape("floor", "plane", (0, 0), quat=q),),
                  contacts=(Contact("floor", "s", friction=mu, condim=condim, torsion=torsion, rolling=rolling),))


def test_rolling_friction_stops_a_rolling_ball_uniformly_without_slip():
    r, mu_r, v0, dt = 0.1, 0.01, 1.0, 1e-3
    run = rbody.simulate(Scene.from_layout(ball(r, rolling=mu_r), t_end=2.0, qvel0=[v0, 0, 0, 0, v0 / r, 0]), dt=dt)
    v, spin, z = run["ball.velocity"][:, 0], run["ball.omega"][:, 1], run["ball.com"][:, 2]
    decel = mu_r * G / (r * (1 + K))
    t_stop = v0 / decel
    rolling = run.t < t_stop - dt
    np.testing.assert_allclose(v[rolling], v0 - decel * run.t[rolling], rtol=0, atol=1e-12)
    assert np.abs(v - r * spin).max() <= 1e-12                      # it never slips
    assert np.abs(v[run.t > t_stop + dt]).max() <= 1e-12            # stopped in the step holding t_s, and stays
    assert np.abs(z - r).max() <= 1e-15
    torque = run["contact_rolling_torque"][:, 0]
    np.testing.assert_allclose(np.linalg.norm(torque[1:][rolling[1:]], axis=-1), mu_r * G, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(run["contact_friction_force"][1:][rolling[1:], 0], axis=-1),
                               decel, rtol=1e-12)                  # the force that decelerates the centre
    assert np.abs(run["contact_spin_torque"]).max() <= 1e-12        # no spin, no torsional torque
    total = run["energy"] + run["dissipated"]                       # the rolling torque's work is `dissipated`
    assert np.abs(total - total[0]).max() <= 1e-12 * total[0]


def test_without_rolling_friction_a_condim_6_ball_rolls_on_as_condim_3():
    r, v0 = 0.1, 1.0
    runs = [rbody.simulate(Scene.from_layout(ball(r, condim=condim), t_end=0.5, qvel0=[v0, 0, 0, 0, v0 / r, 0]),
                           dt=1e-3) for condim in (3, 6)]
    for run in runs:
        np.testing.assert_allclose(run["ball.velocity"][:, 0], v0, rtol=0, atol=1e-13)


def test_torsional_friction_spins_a_ball_down_uniformly():
    r, mu_s, w0, dt = 0.1, 0.02, 5.0, 1e-3
    run = rbody.simulate(Scene.from_layout(ball(r, torsion=mu_s, condim=4), t_end=1.0, qvel0=[0, 0, 0, 0, 0, w0]),
                         dt=dt)
    w = run["ball.omega"][:, 2]
    decel = mu_s * G / (K * r * r)
    t_stop = w0 / decel
    spinning = run.t < t_stop - dt
    np.testing.assert_allclose(w[spinning], w0 - decel * run.t[spinning], rtol=0, atol=1e-11)
    assert np.abs(w[run.t > t_stop + dt]).max() <= 1e-12
    assert np.abs(run["ball.velocity"]).max() <= 1e-12              # spinning in place
    np.testing.assert_allclose(np.abs(run["contact_spin_torque"][1:][spinning[1:], 0]), mu_s * G, rtol=1e-12)


@pytest.mark.parametrize("factor", [1 + 1e-6, 1 - 1e-6])
def test_ball_on_incline_rests_exactly_when_r_tan_alpha_within_rolling_friction(factor):
    r, alpha, dt = 0.1, 0.05, 1e-3
    mu_r = r * np.tan(alpha) * factor
    run = rbody.simulate(Scene.from_layout(ball(r, rolling=mu_r, alpha=alpha), t_end=2.0), dt=dt)
    slope = quat_to_matrix(np.array([np.cos(alpha / 2), 0, np.sin(alpha / 2), 0]))[:, 0]
    along = (run["ball.com"] - run["ball.com"][0]) @ slope          # displacement down the slope [m]
    if factor > 1:
        assert np.abs(along).max() == 0.0                           # held: not a bit of creep
    else:
        a = G * (np.sin(alpha) - mu_r * np.cos(alpha) / r) / (1 + K)
        n = np.arange(len(run.t))
        # the scheme's discrete motion under constant acceleration (symplectic Euler): x_n = a dt^2 n (n + 1) / 2
        # (a = 1e-6 g sin(alpha) / (1 + k): the net of two terms equal to 6 digits, to 6 digits; atol: the
        # round-off of the centre's coordinates, 0.1 m)
        np.testing.assert_allclose(along, a * dt * dt * n * (n + 1) / 2, rtol=1e-6, atol=1e-15)


def test_a_box_with_condim_6_rests_on_a_floor_without_drift():
    """Four corners of six rows each (24 rows of rank 6): held still, weight carried, for 20 s."""
    half = (0.2, 0.1, 0.05)
    box = Body("box", Inertia.box(2.0, 2 * np.array(half)), shapes=(Shape("b", "box", half),), pos=(0, 0, half[2]))
    layout = Layout(bodies=(box,), joints=(Joint("free", "free", "box"),), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", "b", friction=0.8, condim=6, torsion=0.01, rolling=0.001),))
    run = rbody.simulate(Scene.from_layout(layout, t_end=20.0), dt=2e-3)
    assert np.abs(run["box.com"] - run["box.com"][0]).max() <= 1e-13
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), 2.0 * G, rtol=1e-12)


def test_the_event_driven_scheme_refuses_torsional_and_rolling_friction():
    scene = Scene.from_layout(ball(rolling=0.01), t_end=0.1)
    with pytest.raises(MethodNotApplicable, match=r"torsional or rolling friction \(condim 4 or 6\)"):
        rbody.simulate(scene, dt=1e-3, method="rk4")


def test_exported_to_mjcf_and_read_back_with_its_torsional_and_rolling_friction(tmp_path):
    from rbody import from_mjcf
    from rbody.mjcf.export import to_mjcf

    contact = Contact("floor", "s", friction=0.9, condim=6, torsion=0.02, rolling=0.01)
    text = to_mjcf(Scene.from_layout(ball(mu=0.9, torsion=0.02, rolling=0.01), t_end=1.0), dt=2e-3)
    path = tmp_path / "ball.xml"
    path.write_text(text)
    (back,) = from_mjcf(path).tree.contacts
    assert (back.condim, back.friction, back.torsion, back.rolling) == (6, 0.9, 0.02, 0.01)
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.pair_dim[0] == contact.condim
    np.testing.assert_array_equal(model.pair_friction[0], [0.9, 0.9, 0.02, 0.01, 0.01])
