"""The constraint layer against closed forms: a pendulum on its stop (e = 0, 1/2, 1), the dry-friction oscillator, a
pendulum with dry friction in its hinge, a parallelogram four-bar closed by a connect, two hinges coupled 1:1, and a
humanoid-like tree that starts outside its ranges. Each is also a hard case for MuJoCo
(tests/validation/test_constraints_mujoco.py measures MuJoCo's divergence from the same closed forms)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipk, ellipkinc

from rbody import Body, Equality, Inertia, Joint, Layout, Scene, from_mjcf, simulate

from .test_constraint_scheme import G, limited_pendulum, rod

# ----- a rod pendulum on its stop -----------------------------------------------------------------------------
# A uniform rod (mass m, length L) about its end: I = m L^2 / 3, torque -m g (L/2) sin(theta), w0^2 = 3 g / (2 L).
# Released from rest at theta0, it reaches theta at t = (K(k^2) - F(phi, k^2)) / w0, sin(theta/2) = k sin(phi),
# k = sin(theta0/2); a stop at -a (a < theta0) is hit at t1 with speed w1, 1/2 I w1^2 = m g (L/2) (cos a - cos theta0).
# With e = 1 the motion is reversed exactly: it returns to theta0 at 2 t1 and hits again at 3 t1, 5 t1, ...
# With e = 0 it stops there (losing all of 1/2 I w1^2) and, pulled back by gravity, swings between -a and a for ever.
# With e = 1/2 it leaves at w1 / 2 and rises to theta with m g (L/2) (cos a - cos theta) = 1/2 I (w1 / 2)^2.

THETA0, STOP = 1.0, 0.5
W0 = math.sqrt(3 * G / 2)
MGL = 1.0 * G * 0.5
IMPACT_TIME = (ellipk(math.sin(THETA0 / 2) ** 2)
               - ellipkinc(math.asin(math.sin(-STOP / 2) / math.sin(THETA0 / 2)), math.sin(THETA0 / 2) ** 2)) / W0
IMPACT_ENERGY = MGL * (math.cos(STOP) - math.cos(THETA0))  # 1/2 I w1^2 at the stop [J]


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_pendulum_hits_its_stop_at_the_closed_form_time_and_rebounds_by_newtons_law(e):
    run = simulate(limited_pendulum(THETA0, -STOP, 2.0, restitution=e, t_end=4.0), dt=1e-3)
    impacts = run.events["time"][run.events["what"] == "impact"]
    assert impacts[0] == pytest.approx(IMPACT_TIME, abs=1e-11)
    lost = run.events["energy_lost"][0]
    assert lost == pytest.approx((1 - e**2) * IMPACT_ENERGY, abs=1e-10)
    theta = run["qpos"][:, 0]
    assert theta.min() >= -STOP - 1e-15  # never past the stop beyond round-off
    energy = run["energy"] + run["dissipated"]
    assert np.ptp(energy) < 1e-11  # energy keeps its meaning: what it loses is the dissipated
    after = run.t > IMPACT_TIME + 0.05
    if e == 1.0:
        np.testing.assert_allclose(impacts[:3], IMPACT_TIME * np.array([1, 3, 5]), rtol=0, atol=1e-10)
        assert theta[after].max() == pytest.approx(THETA0, abs=1e-6)  # sampled near the turning point
    else:
        rise = math.acos(math.cos(STOP) - e**2 * IMPACT_ENERGY / MGL)  # the turning point after the impact
        top = rise if e > 0 else STOP
        assert theta[after].max() <= top + 1e-12 and theta[after].max() == pytest.approx(top, abs=1e-6)
    if e == 0.0:
        assert run.meta["impacts"] == 1  # later visits of the stop arrive at rest: no impact


def test_pendulum_held_on_its_stop_by_gravity_feels_the_stops_force():
    """The rod released at rest against a stop that gravity presses it onto (its lower stop at +0.3 rad, released at
    0.3): the stop holds it, with the force that balances the weight's moment, m g (L/2) sin(0.3), for ever."""
    run = simulate(limited_pendulum(0.3, 0.3, 2.0, t_end=1.0), dt=1e-2)
    assert np.all(run["active_limits"][:, 0]) and run.meta["events"] == 0
    np.testing.assert_allclose(run["qpos"][:, 0], 0.3, rtol=0, atol=1e-15)
    np.testing.assert_allclose(run["constraint_force"][:, 0], MGL * math.sin(0.3), rtol=1e-14)


# ----- the dry-friction oscillator ----------------------------------------------------------------------------
# m x'' = -k x - F sign(x'): each half swing lasts pi / w (w^2 = k / m) about the shifted equilibrium +-F/k, so the
# turning points are x_{n+1} = -(x_n - 2 (F/k) sign(x_n)): the amplitude falls by 2F/k per half swing, and the mass
# stops for ever at the first turning point where |x| <= F/k (there the spring's force k |x| <= F).

def friction_oscillator(x0: float, m=2.0, k=50.0, F=3.0, t_end=6.0):
    block = Inertia(m, (0, 0, 0), np.eye(3) * 0.01)
    joint = Joint("x", "slide", "block", axis=(1, 0, 0), qpos0=x0, stiffness=k, frictionloss=F)
    return Scene.from_layout(Layout(bodies=(Body("block", block),), joints=(joint,)), t_end=t_end)


def turning_points(x0: float, reach: float) -> list[float]:
    points = [x0]
    while abs(points[-1]) > reach:
        points.append(-(points[-1] - 2 * reach * math.copysign(1.0, points[-1])))
    return points


@pytest.mark.parametrize("x0", [1.0, -0.37, 5.5 * 0.06])
def test_dry_friction_oscillator_loses_2F_over_k_per_half_swing_and_stops_exactly(x0):
    m, k, F = 2.0, 50.0, 3.0
    reach = F / k
    points = turning_points(x0, reach)
    half = math.pi / math.sqrt(k / m)
    run = simulate(friction_oscillator(x0), dt=1e-3)
    assert len(points) - 1 <= 8 and run.t[-1] > (len(points) - 1) * half + 0.5
    what, times = run.events["what"], run.events["time"]
    assert list(what) == ["slip"] * (len(points) - 2) + ["stick"]  # a reversal at each turning point, then it sticks
    np.testing.assert_allclose(times, half * np.arange(1, len(points)), rtol=0, atol=1e-10)
    x = run["qpos"][:, 0]
    stopped = run.t >= times[-1]
    assert np.all(x[stopped] == x[stopped][0])  # no creep: the same bits for ever after
    assert x[stopped][0] == pytest.approx(points[-1], abs=1e-11)
    assert np.all(run["sticking"][stopped, 0]) and not np.any(run["sticking"][run.t < times[-1] - 1e-9, 0])
    np.testing.assert_allclose(run["constraint_force"][stopped, 0], k * points[-1], rtol=1e-9)  # holds the spring
    assert np.ptp(run["energy"] + run["dissipated"]) < 1e-10
    assert run["dissipated"][-1] == pytest.approx(0.5 * k * (x0**2 - points[-1] ** 2), abs=1e-10)


def test_dry_friction_oscillator_within_its_reach_never_moves():
    run = simulate(friction_oscillator(0.059), dt=1e-2)  # k x = 2.95 N < F = 3 N
    assert run.meta["events"] == 0 and np.all(run["qpos"] == 0.059) and np.all(run["sticking"])


# ----- a pendulum with dry friction in its hinge ---------------------------------------------------------------
# Energy between two turning points a and b (the rod at rest at both): the friction moment F does work F |a - b|, so
# m g l (cos b - cos a) = F |a - b| (l = L/2) exactly, at any amplitude; it stops at the first turning point where
# m g l |sin(theta)| <= F. For small angles this is the oscillator above with k = m g l: the amplitude falls by
# 2 F / (m g l) per half swing.

def friction_pendulum(theta0: float, friction: float, t_end: float):
    joint = Joint("h", "hinge", "rod", axis=(0, 1, 0), qpos0=theta0, frictionloss=friction)
    return Scene.from_layout(Layout(bodies=(Body("rod", rod()),), joints=(joint,)), t_end=t_end)


def pendulum_turning_points(theta0: float, friction: float) -> list[float]:
    """The turning points from the exact energy balance: from a, the rod moves by u toward the other side, with
    m g l (cos(a - s u) - cos a) = F u (s = sign a); a root in (0, 2|a|) found to round-off by Brent's method."""
    points = [theta0]
    while MGL * abs(math.sin(points[-1])) > friction:
        a = points[-1]
        s, span = math.copysign(1.0, a), 2 * abs(a)

        def balance(u):
            return MGL * (math.cos(a - s * u) - math.cos(a)) - friction * u
        points.append(a - s * brentq(balance, 1e-9 * span, span, xtol=1e-16, rtol=4 * np.finfo(float).eps))
    return points


def test_pendulum_with_dry_friction_stops_where_the_small_angle_closed_form_says():
    theta0, friction = 0.02, MGL * 0.0014  # F / (m g l) = 0.0014 rad: the amplitude falls by 0.0028 per half swing
    linear = turning_points(theta0, 0.0014)
    run = simulate(friction_pendulum(theta0, friction, t_end=8.0), dt=1e-3)
    assert run.events["what"][-1] == "stick" and len(run.events["time"]) == len(linear) - 1
    stop = run["qpos"][-1, 0]
    # the linear closed form holds to the pendulum's nonlinearity: cos b - cos a = (a^2 - b^2)/2 (1 - (a^2 + b^2)/12
    # + ...) shifts each turning point by less than a^3 / 12, and the swings add their shifts
    assert stop == pytest.approx(linear[-1], abs=(len(linear) - 1) * theta0**3 / 12)
    assert abs(stop - linear[-1]) > 1e-8  # and the nonlinearity is there to see
    assert stop == pytest.approx(pendulum_turning_points(theta0, friction)[-1], abs=1e-11)


def test_pendulum_with_dry_friction_stops_where_the_exact_energy_balance_says_at_large_angles():
    theta0, friction = 2.5, 0.3 * MGL
    points = pendulum_turning_points(theta0, friction)
    run = simulate(friction_pendulum(theta0, friction, t_end=10.0), dt=1e-3)
    what = list(run.events["what"])
    assert what[-1] == "stick" and len(what) == len(points) - 1
    assert run["qpos"][-1, 0] == pytest.approx(points[-1], abs=1e-10)
    assert MGL * abs(math.sin(points[-1])) <= friction < MGL * abs(math.sin(points[-2]))


# ----- a parallelogram four-bar closed by a connect -----------------------------------------------------------
# Crank and rocker: rods of mass m and length L hinged at the world, d apart; the coupler (mass mc, length d)
# hinged at the crank's tip and connected to the rocker's. The coupler translates, so the crank is a pendulum with
# inertia (2m/3 + mc) L^2 and moment (m + mc) g L sin(theta): period 4 K(sin^2(theta0/2)) / w0,
# w0^2 = (m + mc) g / ((2m/3 + mc) L).

def four_bar(theta0: float, m=1.0, mc=0.5, L=1.0, d=0.8, t_end=10.0, equalities=None):
    coupler = Inertia(mc, (d / 2, 0, 0), np.diag([1e-6 * mc * d**2, mc * d**2 / 12, mc * d**2 / 12]))
    bodies = (Body("crank", rod(m, L)), Body("coupler", coupler, parent="crank", pos=(0, 0, -L)),
              Body("rocker", rod(m, L), pos=(d, 0, 0)))
    joints = (Joint("a", "hinge", "crank", axis=(0, 1, 0), qpos0=theta0),
              Joint("b", "hinge", "coupler", axis=(0, 1, 0), qpos0=-theta0),
              Joint("c", "hinge", "rocker", axis=(0, 1, 0), qpos0=theta0))
    loop = (Equality("loop", "connect", body1="coupler", body2="rocker", anchor=(d, 0, 0)),)
    return Scene.from_layout(Layout(bodies=bodies, joints=joints, equalities=loop if equalities is None else equalities),
                             t_end=t_end)


def downward_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times where x falls through 0, by cubic interpolation of the samples around each."""
    found = []
    for i in np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0)):
        window = slice(max(i - 1, 0), i + 3)
        coefficients = np.polyfit(t[window] - t[i], x[window], 3)
        roots = np.roots(coefficients)
        step = t[i + 1] - t[i]
        real = [r.real for r in roots if abs(r.imag) < 1e-12 and -1e-9 <= r.real <= step + 1e-9]
        found.append(t[i] + min(real, key=lambda r: abs(r - step / 2)))
    return np.array(found)


def test_four_bar_crank_swings_with_the_elliptic_period_and_the_loop_stays_closed():
    m, mc, L, theta0 = 1.0, 0.5, 1.0, 0.6
    w0 = math.sqrt((m + mc) * G / ((2 * m / 3 + mc) * L))
    period = 4 * ellipk(math.sin(theta0 / 2) ** 2) / w0
    run = simulate(four_bar(theta0), dt=1e-3)
    crossings = downward_crossings(run.t, run["qpos"][:, 0])
    assert len(crossings) >= 5
    np.testing.assert_allclose(np.diff(crossings), period, rtol=0, atol=1e-9)
    assert np.abs(run["constraint_error"]).max() <= 1e-10  # the loop's closure error over 10 s
    assert np.ptp(run["energy"]) < 1e-9
    np.testing.assert_allclose(run["qpos"][:, 1], -run["qpos"][:, 0], rtol=0, atol=1e-12)  # the coupler translates


def test_four_bar_closed_by_a_weld_of_the_coupler_is_a_rigid_frame_that_does_not_move():
    """A weld instead of the connect closes the loop with three more rows than it needs (redundant): the frame
    is rigid (one configuration) and stays at rest; the run goes on."""
    weld = (Equality("rigid", "weld", body1="coupler", body2="rocker", anchor=(0, 0, -1.0)),)
    run = simulate(four_bar(0.3, equalities=weld, t_end=1.0), dt=1e-2)
    # completed at the reference pose (every angle 0), the weld puts the frame back there at t = 0, and it stays
    assert run.events["what"][0] == "start" and np.abs(run["constraint_error"][0]).max() > 0.1
    assert np.abs(run["qvel"]).max() < 1e-12 and np.abs(run["constraint_error"][1:]).max() <= 1e-13
    np.testing.assert_allclose(run["qpos"][1:], 0.0, rtol=0, atol=1e-13)


# ----- two hinges coupled 1:1 ----------------------------------------------------------------------------------

def test_two_hinges_coupled_one_to_one_swing_as_one_body_with_the_summed_inertia():
    """Rod A (1 kg, 1 m) hinged at the origin and rod B (0.5 kg, 0.6 m) hinged 0.4 m away, coupled by a joint
    equality q_B = q_A: the same motion as one hinge carrying a body of the summed moment I_A + I_B about its axis
    and the summed gravity moment (m_A l_A + m_B l_B) g, run without constraints, to 1e-10."""
    theta0 = 1.2
    a, b = rod(1.0, 1.0), rod(0.5, 0.6)
    coupled = Layout(bodies=(Body("a", a), Body("b", b, pos=(0.4, 0, 0))),
                     joints=(Joint("qa", "hinge", "a", axis=(0, 1, 0), qpos0=theta0),
                             Joint("qb", "hinge", "b", axis=(0, 1, 0), qpos0=theta0)),
                     equalities=(Equality("gear", "joint", joint1="qb", joint2="qa"),))
    moment = 1.0 / 3 + 0.5 * 0.36 / 3
    first = 1.0 * 0.5 + 0.5 * 0.3
    mass = 1.5
    com = first / mass
    about_com = moment - mass * com**2
    single = Layout(bodies=(Body("ab", Inertia(mass, (0, 0, -com), np.diag([about_com, about_com, 1e-6]))),),
                    joints=(Joint("q", "hinge", "ab", axis=(0, 1, 0), qpos0=theta0),))
    run = simulate(Scene.from_layout(coupled, t_end=3.0), dt=1e-3)
    one = simulate(Scene.from_layout(single, t_end=3.0), dt=1e-3, method="rk4")
    np.testing.assert_allclose(run["qpos"][:, 0], one["qpos"][:, 0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(run["qpos"][:, 1], run["qpos"][:, 0], rtol=0, atol=1e-14)
    w0 = math.sqrt(first * G / moment)
    crossings = downward_crossings(run.t, run["qpos"][:, 0])
    np.testing.assert_allclose(np.diff(crossings), 4 * ellipk(math.sin(theta0 / 2) ** 2) / w0, rtol=0, atol=1e-9)


# ----- a humanoid-like tree outside its ranges at its reference pose --------------------------------------------

from validation.hard.constraints import LIMBS as HUMANOID  # noqa: E402


def test_humanoid_starts_outside_its_ranges_and_the_limits_put_it_back_at_once():
    """Its reference pose (every angle 0) lies outside the knees', elbows' and ankles' ranges and the right shoulder
    is turned 60 degrees in a 45 degree cone: the run is not refused; its first event, at t = 0, puts every joint on
    its stop, and from then on no joint leaves its range (to round-off)."""
    scene = from_mjcf(HUMANOID, t_end=1.0)
    assert scene.limit_violation(np.zeros(1), scene.qpos0[None])  # outside at t = 0
    run = simulate(scene, dt=2e-3)
    assert run.events["what"][0] == "start" and run.events["time"][0] == 0.0
    for name in ("knee_r", "elbow_l", "ankle_r"):
        assert name in run.events["constraints"][0]
    np.testing.assert_array_equal(run["qpos"][0], scene.qpos0)  # the state as given, as MuJoCo starts it
    overshoot = -run["constraint_error"][1:].min()  # the largest excursion past any stop after t = 0
    assert overshoot <= 1e-13
    inside = [name for name, (low, high) in scene.limits.items() if "shoulder" not in name and "neck" not in name]
    for name in inside:
        column = scene.multibody.arrays.qposadr[scene.multibody.joint_names.index(name)]
        low, high = scene.limits[name]
        assert np.all(run["qpos"][1:, column] >= low - 1e-13) and np.all(run["qpos"][1:, column] <= high + 1e-13)
    assert run.meta["events"] >= 1 and np.all(np.isfinite(run["energy"]))


# ----- the time-stepping scheme on the same closed forms ---------------------------------------------------------

def test_moreau_time_stepping_converges_at_first_order_to_the_dry_friction_oscillator():
    """The oscillator's position at t = 1 s (in its second half swing, about the equilibrium -F/k): the error halves
    with dt (order 1: the free motion is symplectic Euler, the turning point falls inside a step)."""
    m, k, F, x0 = 2.0, 50.0, 3.0, 1.0
    w, reach = math.sqrt(k / m), F / k
    exact = -reach + (-(x0 - 2 * reach) + reach) * math.cos(w * (1.0 - math.pi / w))
    errors = [abs(simulate(friction_oscillator(x0, t_end=1.0), dt=dt, method="moreau")["qpos"][-1, 0] - exact)
              for dt in (2e-3, 1e-3, 5e-4)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 1.0) < 0.25) and errors[-1] < 1e-3


def test_moreau_time_stepping_holds_stops_and_loops_to_round_off():
    stop = simulate(limited_pendulum(THETA0, -STOP, 2.0, t_end=2.0), dt=1e-3, method="moreau")
    assert stop["qpos"][:, 0].min() >= -STOP - 1e-15 and -stop["constraint_error"].min() <= 1e-15
    loop = simulate(four_bar(0.6, t_end=2.0), dt=1e-3, method="moreau")
    assert np.abs(loop["constraint_error"]).max() <= 1e-10
    steps = simulate(friction_oscillator(1.0), dt=1e-4, method="moreau")
    assert steps["qpos"][-1, 0] == pytest.approx(turning_points(1.0, 3.0 / 50.0)[-1], abs=1e-4)
    assert np.all(steps["qpos"][-100:, 0] == steps["qpos"][-1, 0])  # stuck: no creep
