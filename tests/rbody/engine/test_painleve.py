"""Painleve's rod: a rod sliding on its lower end with friction mu (rbody.engine.constraints.events, the event
scheme's tangential impact; the time-stepping's step).

A thin rod of mass m and length 2 L, inclined at theta, its lower end A (a capsule's end of radius r) on the floor,
moving in the x-z plane (slide x, slide z, hinge y: its three coordinates). With d = A - c = (dx, dz) and the
moment of inertia I about c, an impulse or force P = (Pt, Pn) at A changes A's velocity by W P,

    W = [[1/m + dz^2/I, -dx dz/I], [-dx dz/I, 1/m + dx^2/I]].

Sliding towards -x (its friction +mu lambda_n), A's normal acceleration per unit normal force is
W_nn + mu W_nt = 1/m + (dx^2 - mu dx dz)/I: negative for mu > mu_P = (I/m + dx^2)/(dx dz). Then with gravity pulling
A down (a_n = -g + omega^2 (-dz) < 0) no normal force is consistent (Painleve's paradox); the rigid-body answer is
an impulse at zero normal velocity, a tangential impact (Darboux-Keller; Genot and Brogliato 1999), which stops A
sliding: the stick impulse P = -W^-1 (v_t, 0) lies in the cone exactly where mu >= mu_P (Pt/Pn = mu_P for the rod).
With a_n > 0 (the rod turning fast) lift-off and contact are both consistent; rbody lifts off.
"""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.errors import SimulationError
from rbody.inertia import Inertia

G = 9.81
M, L, R, THETA = 1.0, 0.5, 1e-3, 0.8
I_C = M * (2 * L) ** 2 / 12
DX, DZ = -L * np.cos(THETA), -L * np.sin(THETA) - R   # A - c, A the lowest point of the lower end's sphere
W = np.array([[1 / M + DZ ** 2 / I_C, -DX * DZ / I_C], [-DX * DZ / I_C, 1 / M + DX ** 2 / I_C]])
MU_P = (I_C / M + DX ** 2) / (DX * DZ)                # 1.6336 for these sizes


def rod(mu: float) -> Layout:
    """The rod: body frame at its centre, axes of the world; the capsule's axis (cos theta, 0, sin theta)."""
    phi = np.pi / 2 - THETA
    quat = (np.cos(phi / 2), 0.0, np.sin(phi / 2), 0.0)
    body = Body("rod", Inertia.rod(M, 2 * L), shapes=(Shape("s", "capsule", (R, L), quat=quat),),
                pos=(0.0, 0.0, -DZ))
    joints = (Joint("x", "slide", "rod", axis=(1, 0, 0)), Joint("z", "slide", "rod", axis=(0, 0, 1)),
              Joint("a", "hinge", "rod", axis=(0, 1, 0)))
    return Layout(bodies=(body,), joints=joints, fixed=(Shape("floor", "plane", (0, 0)),),
                  contacts=(Contact("floor", "s", friction=mu),))


def end_velocity(qvel):
    """(vt, vn) of A for qvel (x', z', omega about y) at the starting pose: v_c + omega y x d."""
    return np.array([qvel[0] + qvel[2] * DZ, qvel[1] - qvel[2] * DX])


def after_impulse(qvel, P):
    """qvel after the impulse P = (Pt, Pn) at A: v_c + P/m, omega + (d x P)_y / I."""
    return np.array([qvel[0] + P[0] / M, qvel[1] + P[1] / M, qvel[2] + (DZ * P[0] - DX * P[1]) / I_C])


def test_the_rod_is_a_painleve_configuration_above_mu_p():
    """The closed form's premises, checked on rbody's own rows: A's velocity change per impulse is W, and the stick
    impulse's ratio Pt/Pn is mu_P (so inside the cone exactly when sliding has no consistent force)."""
    for P in ([1.0, 0.0], [0.0, 1.0]):
        q = after_impulse(np.zeros(3), np.array(P))
        np.testing.assert_allclose(end_velocity(q), W @ P, rtol=1e-14)
    stick = np.linalg.solve(W, -np.array([-1.0, 0.0]))
    assert stick[1] > 0 and stick[0] / stick[1] == pytest.approx(MU_P, rel=1e-14)
    assert 1 / M + (DX ** 2 - MU_P * DX * DZ) / I_C == pytest.approx(0.0, abs=1e-14)


def test_event_scheme_resolves_painleve_by_a_tangential_impact():
    """mu = 2 > mu_P, sliding towards -x at 1 m/s, no spin: no consistent force; the event scheme's tangential impact
    at t = 0 stops A (the energy it takes is the closed form's to round-off), then the rod turns on A without
    slipping (its end's sphere of radius r rolls: its centre E moves by r a as the rod turns by a), friction within
    the cone, energy kept: omega^2 = 2 (E+ - m g z_c) / I_P with E+ the energy after the impact and I_P = I + m |c -
    P|^2 about the contact point P, |c - P|^2 = L^2 + 2 r z_c - r^2."""
    u = -1.0
    run = rbody.simulate(Scene.from_layout(rod(2.0), t_end=0.05, qvel0=[u, 0, 0]), dt=1e-3, method="rk4")
    assert list(run.events["what"]) == ["tangential impact"]
    assert run.events["time"][0] == 0.0
    P = np.linalg.solve(W, -np.array([u, 0.0]))
    q_plus = after_impulse(np.array([u, 0.0, 0.0]), P)
    np.testing.assert_allclose(end_velocity(q_plus), 0.0, rtol=0, atol=1e-15)
    I_A = I_C + M * (DX ** 2 + DZ ** 2)
    kinetic_plus = 0.5 * I_A * q_plus[2] ** 2
    np.testing.assert_allclose(run.events["energy_lost"][0], 0.5 * M * u ** 2 - kinetic_plus, rtol=1e-12)
    np.testing.assert_allclose(run.events["impulse"][0], P[1], rtol=1e-12)  # its normal impulse Pn
    later = run.t > 0
    qpos, qvel = run["qpos"][later], run["qvel"][later]
    ex, ez = DX, DZ + R                                                    # E - c at the start
    x_e = qpos[:, 0] + ex * np.cos(qpos[:, 2]) + ez * np.sin(qpos[:, 2])  # turned about y by the hinge's angle a
    # rolls on the floor without slip: held at the velocity level, so the position follows by RK4 (1.3e-13 m
    # after the 50 steps here, growing by 2.6e-15 m a step)
    assert np.abs(x_e - ex - R * qpos[:, 2]).max() <= 5e-13
    z_c = -DZ + qpos[:, 1]
    I_P = I_C + M * (L ** 2 + 2 * R * z_c - R ** 2)
    np.testing.assert_allclose(qvel[:, 2] ** 2, 2 * (kinetic_plus - M * G * qpos[:, 1]) / I_P, rtol=1e-11)
    assert np.all(qvel[:, 2] < 0)                                          # rising, theta growing
    normal, friction = run["contact_normal_force"][later, 1], run["contact_friction_force"][later, 1]
    assert np.all(normal > 0) and np.all(np.linalg.norm(friction, axis=1) < 2.0 * normal)
    assert np.abs(run["contact_distance"][:, 1]).max() <= 1e-13
    total = run["energy"][later] + run["dissipated"][later]
    assert np.abs(total - total[0]).max() <= 1e-12


@pytest.mark.parametrize("h", [1e-3, 1e-6])
def test_time_stepping_takes_the_tangential_impact_in_a_step(h):
    """The Moreau step at the same start: A's velocity after it is 0 (the stick impulse, now against (u, -g h):
    in the cone), the rod's that of the closed form at that h to round-off, and within O(h) of the event scheme's
    tangential impact."""
    u = -1.0
    run = rbody.simulate(Scene.from_layout(rod(2.0), t_end=h, qvel0=[u, 0, 0]), dt=h, method="moreau")
    stepped = np.linalg.solve(W, -np.array([u, -G * h]))
    assert stepped[1] > 0 and stepped[0] <= 2.0 * stepped[1]
    np.testing.assert_allclose(run["qvel"][-1], after_impulse(np.array([u, -G * h, 0.0]), stepped), rtol=0, atol=1e-12)
    limit = after_impulse(np.array([u, 0.0, 0.0]), np.linalg.solve(W, -np.array([u, 0.0])))
    assert np.abs(run["qvel"][-1] - limit).max() <= 2 * G * h


def test_below_mu_p_the_rod_slides_with_its_closed_form_force():
    """mu = 1.5 < mu_P: sliding is consistent; no impact, A slides with lambda_n = g / (W_nn + mu W_nt) (its normal
    acceleration 0) and the friction mu lambda_n along +x."""
    mu, u = 1.5, -1.0
    run = rbody.simulate(Scene.from_layout(rod(mu), t_end=0.01, qvel0=[u, 0, 0]), dt=1e-3, method="rk4")
    assert "tangential impact" not in set(run.events["what"])
    lam = G / (W[1, 1] + mu * W[1, 0])
    np.testing.assert_allclose(run["contact_normal_force"][0, 1], lam, rtol=1e-12)
    np.testing.assert_allclose(run["contact_friction_force"][0, 1], [mu * lam, 0.0], rtol=1e-12, atol=1e-12)
    assert np.all(end_velocity(run["qvel"][-1].T)[0] < 0)                  # still sliding


def test_with_a_fast_turn_the_event_scheme_lifts_off_and_the_time_stepping_sticks():
    """mu = 2 > mu_P but the rod turning at omega = 8 rad/s: A's free normal acceleration -g - omega^2 dz > 0, so
    both lift-off and a contact force (lambda_n = -a_n / (W_nn + mu W_nt) > 0) are consistent (Painleve's
    indeterminate case). The event scheme takes the one without impulse or force: A leaves the floor and the rod
    flies (c's height -dz + v_z t - g t^2 / 2). The time-stepping's rows are those of the step's start, where A is
    touching and approaching at -g h (the turn's centripetal term is second order in h): it takes the other
    admissible answer, the tangential impact, at every h, and A's velocity after the step is 0."""
    omega, u = 8.0, -1.0
    assert -G - omega ** 2 * DZ > 0
    qvel0 = [u - omega * DZ, omega * DX, omega]
    np.testing.assert_allclose(end_velocity(np.array(qvel0)), [u, 0.0], rtol=0, atol=1e-15)
    run = rbody.simulate(Scene.from_layout(rod(2.0), t_end=0.02, qvel0=qvel0), dt=1e-3, method="rk4")
    assert len(run.events["what"]) == 0
    assert run["contact_distance"][1:, 1].min() > 0
    np.testing.assert_allclose(run["qpos"][:, 1], omega * DX * run.t - G * run.t ** 2 / 2, rtol=0, atol=1e-14)
    for h in (1e-3, 1e-6):
        stepped = rbody.simulate(Scene.from_layout(rod(2.0), t_end=h, qvel0=qvel0), dt=h, method="moreau")
        np.testing.assert_allclose(end_velocity(stepped["qvel"][-1]), 0.0, rtol=0, atol=1e-12)
        assert stepped["contact_normal_force"][-1, 1] * h > 0.1                 # an impulse, not a force


def test_painleve_error_names_the_contacts(monkeypatch):
    """The refusal where no impulse resolves it either (the problem still jammed after the tangential impact; forced
    here by a select_mode that always finds the contact jammed): a SimulationError naming the time, the contact and
    the residual, never a silent penetration."""
    from rbody.engine.constraints import events
    original = events.EventRun.select_mode

    def always_jammed(self, y, t, resting, *args):
        original(self, y, t, resting, *args)
        raise events.Jammed((1,), 9.81)

    monkeypatch.setattr(events.EventRun, "select_mode", always_jammed)
    scene = Scene.from_layout(rod(2.0), t_end=0.01, qvel0=[-1.0, 0, 0])
    with pytest.raises(SimulationError, match=r"at t=0 s constraints 'floor/s\[1\]'; Painleve configuration.*"
                                              r"residual 9\.81"):
        rbody.simulate(scene, dt=1e-3, method="rk4")
