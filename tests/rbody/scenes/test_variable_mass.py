"""The chapter's variable-mass problems (section 5.3) against their closed forms.

Rocket (5.10)-(5.11): m v' + u m' = -beta v with m = m0 - alpha t. Free rocket: v = v0 + u log(m0/m),
x = v0 t + (u m0/alpha) [(1 - alpha t/m0) log(1 - alpha t/m0) + alpha t/m0]. Linear drag from rest:
v = (alpha u/beta)(1 - (m/m0)^(beta/alpha)), asked at m = m0/2. Avalanche: d(m v)/dt = m g sin(theta),
m = rho h x: x = g t^2 sin(theta)/6, v = sqrt(2/3 x g sin(theta)).
"""

from __future__ import annotations

import numpy as np
import pytest

import rbody
from rbody.errors import MethodNotApplicable
from rbody.motion import quat_to_matrix
from rbody.scenes import avalanche, rocket

G = 9.81
M0, ALPHA, U, DRY = 2.0, 0.1, 10.0, 0.7   # burn-out at t_b = 13 s


def _rocket(**changes):
    args = dict(burn_rate=ALPHA, exhaust_speed=U, dry_mass=DRY, t_end=20.0)
    args.update(changes)
    return rocket(args.pop("m0", M0), **args)


def _derivative(f, t, h):
    """Central difference (f(t + h) - f(t - h)) / 2h, error h^2 f'''/6."""
    return (f(t + h) - f(t - h)) / (2 * h)


# ----- rocket: the chapter's closed forms ----------------------------------------------------------------

@pytest.mark.parametrize("v0", [0.0, 3.0, -2.0])
def test_free_rocket_is_the_chapters_solution(v0):
    scene = _rocket(v0=v0)
    t = np.linspace(0.0, 13.0, 27)
    exact = scene.exact(t)
    m = M0 - ALPHA * t
    np.testing.assert_allclose(exact["mass"], m, rtol=1e-15)
    np.testing.assert_allclose(exact["speed"], v0 + U * np.log(M0 / m), rtol=0, atol=1e-13 * U)
    fraction = ALPHA * t / M0
    chapter_x = v0 * t + U * M0 / ALPHA * ((1 - fraction) * np.log(1 - fraction) + fraction)
    np.testing.assert_allclose(exact["distance"], chapter_x, rtol=0, atol=1e-13 * U * 13.0)


@pytest.mark.parametrize("beta", [0.05, 0.3, 2.0])
def test_rocket_with_drag_answers_the_half_mass_question(beta):
    """From rest, after burning half its mass: v = (alpha u/beta)(1 - 2^(-beta/alpha))."""
    scene = _rocket(drag=beta, dry_mass=0.4 * M0)
    answer = ALPHA * U / beta * (1 - 0.5 ** (beta / ALPHA))
    np.testing.assert_allclose(scene.speed_at_mass(M0 / 2), answer, rtol=1e-14)
    half_time = M0 / (2 * ALPHA)
    np.testing.assert_allclose(scene.exact([half_time])["speed"], answer, rtol=1e-14)
    # the chapter's v(m) at every mass, from rest
    mass = np.linspace(M0, 0.4 * M0, 9)
    np.testing.assert_allclose(scene.speed_at_mass(mass), ALPHA * U / beta * (1 - (mass / M0) ** (beta / ALPHA)),
                               rtol=0, atol=1e-14 * ALPHA * U / beta)
    assert scene.limiting_speed == pytest.approx(ALPHA * U / beta, rel=1e-15)


def test_rocket_faster_than_the_limit_slows_down_towards_it():
    """The chapter after (5.11): beta v > alpha u decelerates towards alpha u/beta, never below it."""
    beta = 0.5
    limit = ALPHA * U / beta
    scene = _rocket(drag=beta, v0=3 * limit)
    speed = scene.exact(np.linspace(0, 13.0, 50))["speed"]
    assert np.all(np.diff(speed) < 0) and np.all(speed > limit)


@pytest.mark.parametrize("beta, v0", [(0.0, 0.0), (0.3, 0.0), (0.3, 5.0), (2.0, 40.0)])
def test_rocket_closed_form_solves_the_rocket_equation(beta, v0):
    """x' = v, m v' = alpha u - beta v while burning, dry_mass v' = -beta v after burn-out (central
    differences, h = 1e-4: error ~ h^2 |v'''| ~ 1e-8), and x, v continuous at burn-out."""
    scene = _rocket(drag=beta, v0=v0)
    h = 1e-4
    distance = lambda t: scene.exact(t)["distance"]  # noqa: E731
    speed = lambda t: scene.exact(t)["speed"]  # noqa: E731
    for t in (np.linspace(0.5, 12.5, 7), np.linspace(13.5, 19.5, 5)):
        v, m = speed(t), scene.exact(t)["mass"]
        np.testing.assert_allclose(_derivative(distance, t, h), v, rtol=0, atol=1e-7)
        burning = t < 13.0
        force = np.where(burning, ALPHA * U, 0.0) - beta * v
        np.testing.assert_allclose(m * _derivative(speed, t, h), force, rtol=0, atol=1e-7)
    before, after = scene.exact([13.0 - 1e-9]), scene.exact([13.0 + 1e-9])
    assert after["speed"] == pytest.approx(before["speed"], abs=1e-8)
    assert after["distance"] == pytest.approx(before["distance"], abs=1e-7)


def test_rocket_coasts_after_burnout():
    t_b = (M0 - DRY) / ALPHA
    free = _rocket()
    assert free.burnout_time == pytest.approx(13.0, rel=1e-15)
    coast = free.exact([t_b, 16.0, 20.0])
    v_b = U * np.log(M0 / DRY)
    np.testing.assert_allclose(coast["speed"], v_b, rtol=1e-14)        # constant without drag
    np.testing.assert_allclose(coast["mass"], DRY, rtol=0)
    np.testing.assert_allclose(np.diff(coast["distance"]), v_b * np.array([3.0, 4.0]), rtol=1e-12)
    beta = 0.4
    dragged = _rocket(drag=beta).exact([t_b, 20.0])["speed"]
    assert dragged[1] == pytest.approx(dragged[0] * np.exp(-beta * (20.0 - t_b) / DRY), rel=1e-13)


def test_small_drag_has_no_cancellation():
    """beta -> 0 must reach the free rocket smoothly: the difference is O(beta), not round-off / beta."""
    t = np.linspace(0, 20, 41)
    free = _rocket(v0=1.0).exact(t)
    for beta in (1e-6, 1e-9, 1e-12):
        slight = _rocket(v0=1.0, drag=beta).exact(t)
        for name in ("distance", "speed"):
            scale = np.max(np.abs(free[name]))
            assert np.max(np.abs(slight[name] - free[name])) <= 1e3 * beta * scale + 1e-13 * scale


# ----- rocket: native runs ------------------------------------------------------------------------------

def _max_error(scene, dt, method, name="distance"):
    run = rbody.simulate(scene, dt=dt, method=method)
    return float(np.max(np.abs(run[name] - scene.exact(run.t)[name])))


@pytest.mark.parametrize("method, order", [("euler", 1), ("rk4", 4)])
def test_rocket_method_order_while_burning(method, order):
    scene = _rocket(drag=0.3, v0=1.0, t_end=12.0)       # before burn-out: a smooth right-hand side
    dt = 0.2 if method == "rk4" else 0.002
    ratio = _max_error(scene, dt, method) / _max_error(scene, dt / 2, method)
    assert 2**order * 0.8 < ratio < 2**order * 1.25


def test_rocket_gauss6_while_burning_is_at_round_off():
    scene = _rocket(drag=0.3, t_end=12.0)
    assert _max_error(scene, 0.05, "gauss6") < 1e-11


@pytest.mark.parametrize("dry", [DRY, 0.70003])  # t_b = 13 on the grid of every dt below, and off it
@pytest.mark.parametrize("method, order", [("euler", 1), ("rk4", 4), ("gauss6", 6)])
def test_rocket_keeps_each_methods_order_across_burnout(method, order, dry):
    """simulate cuts the step that straddles burn-out at t_b (NativeModel.break_time), so no stage spans
    the jump alpha u/dry of v': over the whole 20 s, burn and coast, each method keeps its order (rk4 and
    gauss6 at round-off at dt = 1e-3; before the cut, a step across the jump made every method first order)."""
    scene = _rocket(drag=0.3, dry_mass=dry)
    if order == 1:
        coarse, fine = (_max_error(scene, dt, method, "speed") for dt in (2e-3, 1e-3))
        assert 1.8 < coarse / fine < 2.2
    else:
        for name in ("speed", "distance"):
            assert _max_error(scene, 1e-3, method, name) < 1e-11


def test_rocket_batch_with_different_burnouts_runs_element_by_element_decision():
    """A batch whose elements burn out at different times has no shared break: rhs decides the side from
    the burn clock, and each element still matches its single run."""
    batch = rocket(M0, burn_rate=ALPHA, exhaust_speed=U, dry_mass=[0.7, 0.9], drag=0.3, t_end=20.0)
    run = rbody.simulate(batch, dt=1e-2, method="rk4")
    for k, dry in enumerate((0.7, 0.9)):
        single = rocket(M0, burn_rate=ALPHA, exhaust_speed=U, dry_mass=dry, drag=0.3, t_end=20.0)
        exact = single.exact(run.t)["speed"]
        assert np.max(np.abs(run["speed"][:, k] - exact)) <= ALPHA * U / dry * 1e-2 + 1e-9


def test_rocket_mass_is_exact_for_every_method():
    """The burn clock s' = -alpha is integrated exactly: one rounding of m0 per step at most."""
    scene = _rocket(drag=0.3)
    for method in ("euler", "rk4", "gauss6"):
        run = rbody.simulate(scene, dt=0.01, method=method)
        steps = run.t.size - 1
        np.testing.assert_allclose(run["mass"], np.maximum(M0 - ALPHA * run.t, DRY), rtol=0,
                                   atol=steps * np.finfo(float).eps * M0)


def test_rocket_batch_matches_its_items():
    scene = _rocket(m0=np.array([2.0, 3.0]), drag=np.array([[0.0], [0.2], [1.0]]), t_end=12.0)
    assert scene.batch_shape == (3, 2)
    run = rbody.simulate(scene, dt=0.01, method="rk4")
    assert run["distance"].shape == (run.t.size, 3, 2)
    exact = scene.exact(run.t)
    np.testing.assert_allclose(run["distance"], exact["distance"], rtol=0, atol=1e-8)
    one = rbody.simulate(scene.item((1, 0)), dt=0.01, method="rk4")
    np.testing.assert_array_equal(one["speed"], run["speed"][:, 1, 0])


def test_rocket_has_no_symplectic_method():
    with pytest.raises(MethodNotApplicable, match="velocity"):
        rbody.simulate(_rocket(), dt=0.01, method="verlet")
    assert rbody.simulate(_rocket(t_end=0.1), dt=0.01).meta["method"] == "rk4"


# ----- rocket: bad input ---------------------------------------------------------------------------------

@pytest.mark.parametrize("changes, words", [
    (dict(dry_mass=0.0), "burns itself away entirely at t = m0/burn_rate = 20"),
    (dict(dry_mass=-1.0), "must be > 0"),
    (dict(dry_mass=2.0), "must be < m0"),
    (dict(dry_mass=np.array([0.5, 2.5])), "must be < m0"),
    (dict(m0=-1.0), "m0"),
    (dict(burn_rate=0.0), "burn_rate"),
    (dict(burn_rate=np.nan), "finite"),
    (dict(exhaust_speed=-3.0), "exhaust_speed"),
    (dict(drag=-0.1), "drag"),
    (dict(v0=np.inf), "v0"),
    (dict(t_end=0.0), "t_end"),
])
def test_rocket_bad_input(changes, words):
    with pytest.raises(ValueError, match=words):
        _rocket(**changes)


def test_rocket_speed_at_mass_outside_the_burn():
    with pytest.raises(ValueError, match="between them"):
        _rocket().speed_at_mass(0.5 * DRY)


# ----- rocket: what other simulators build ------------------------------------------------------------------

def test_rocket_layout_and_mass_interface():
    scene = _rocket(drag=0.3, v0=2.0)
    layout = scene.layout
    (body,), (joint,) = layout.bodies, layout.joints
    assert body.inertia.mass == M0 and joint.kind == "slide" and joint.axis == (1.0, 0.0, 0.0)
    assert joint.qvel0 == 2.0 and joint.qpos0 == 0.0
    # m(t) v' = slide_force on the exact solution (gravity is perpendicular to the slide)
    t = np.array([1.0, 6.0, 12.5, 14.0, 19.0])
    exact = scene.exact(t)
    acceleration = _derivative(lambda s: scene.exact(s)["speed"], t, 1e-4)
    force = scene.slide_force(t, exact["distance"], exact["speed"])
    np.testing.assert_allclose(scene.body_mass(t) * acceleration, force, rtol=0, atol=1e-7)
    observed = scene.observe(t, {}, {"slide": (exact["distance"], exact["speed"])})
    for name in scene.observables:
        np.testing.assert_allclose(observed[name], exact[name], rtol=1e-15)


# ----- avalanche ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("slope", [0.1, 0.5, np.pi / 4, np.pi / 2])
def test_avalanche_is_the_chapters_parabola(slope):
    scene = avalanche(slope, t_end=5.0)
    s = G * np.sin(slope)
    t0 = np.sqrt(6 * 1e-3 / s)
    assert scene.start_time == pytest.approx(t0, rel=1e-15)
    t = np.linspace(0, 5, 11)
    exact = scene.exact(t)
    np.testing.assert_allclose(exact["distance"], s * (t + t0) ** 2 / 6, rtol=1e-14)
    np.testing.assert_allclose(exact["speed"], np.sqrt(2 / 3 * exact["distance"] * s), rtol=1e-14)
    np.testing.assert_allclose(exact["mass"], 300.0 * 0.5 * 1.0 * exact["distance"], rtol=1e-14)
    assert exact["distance"][0] == pytest.approx(1e-3, rel=1e-14)
    assert scene.acceleration == pytest.approx(s / 3, rel=1e-15)  # a third of a free slide


def test_avalanche_closed_form_solves_d_mv_dt_equals_m_g_sin():
    slope, rho, h, w = 0.4, 250.0, 0.3, 2.0
    scene = avalanche(slope, snow_density=rho, snow_height=h, width=w, x0=0.01, t_end=5.0)
    t = np.linspace(0.2, 4.8, 9)
    momentum = lambda s: scene.exact(s)["mass"] * scene.exact(s)["speed"]  # noqa: E731
    mass = scene.exact(t)["mass"]
    k = 1e-3  # five-point stencil, exact for the cubic m v ~ (t + t0)^3 up to round-off
    rate = (momentum(t - 2 * k) - 8 * momentum(t - k) + 8 * momentum(t + k) - momentum(t + 2 * k)) / (12 * k)
    np.testing.assert_allclose(rate, mass * G * np.sin(slope), rtol=1e-10)
    np.testing.assert_allclose(mass, rho * h * w * scene.exact(t)["distance"], rtol=1e-15)


@pytest.mark.parametrize("method, order, dt", [("euler", 1, 2e-3), ("rk4", 4, 2e-2)])
def test_avalanche_method_order(method, order, dt):
    scene = avalanche(0.5, x0=0.05, t_end=3.0)
    ratio = _max_error(scene, dt, method) / _max_error(scene, dt / 2, method)
    assert 2**order * 0.8 < ratio < 2**order * 1.25


def test_avalanche_native_starts_on_the_parabola_and_gauss6_is_at_round_off():
    scene = avalanche(np.array([0.3, 0.9]), t_end=3.0)
    run = rbody.simulate(scene, dt=0.01, method="gauss6")
    exact = scene.exact(run.t)
    np.testing.assert_allclose(run["distance"][0], 1e-3, rtol=0)
    np.testing.assert_allclose(run["speed"][0], np.sqrt(2 / 3 * 1e-3 * G * np.sin([0.3, 0.9])), rtol=1e-15)
    for name in scene.observables:
        np.testing.assert_allclose(run[name], exact[name], rtol=1e-11)


@pytest.mark.parametrize("changes, words", [
    (dict(slope=0.0), "slope"), (dict(slope=2.0), "slope"), (dict(slope=np.nan), "finite"),
    (dict(snow_density=-1.0), "snow_density"), (dict(snow_height=0.0), "snow_height"),
    (dict(width=-2.0), "width"), (dict(x0=0.0), "x0"), (dict(gravity=0.0), "gravity"),
])
def test_avalanche_bad_input(changes, words):
    args = dict(slope=0.5, t_end=1.0)
    args.update(changes)
    with pytest.raises(ValueError, match=words):
        avalanche(args.pop("slope"), **args)


def test_avalanche_layout_slides_down_the_slope():
    slope = 0.6
    scene = avalanche(slope, x0=0.02, t_end=2.0)
    (body,), (joint,) = scene.layout.bodies, scene.layout.joints
    axis_world = quat_to_matrix(np.array(body.quat)) @ np.array(joint.axis)
    np.testing.assert_allclose(axis_world, [np.cos(slope), 0.0, -np.sin(slope)], rtol=0, atol=1e-15)
    assert joint.qpos0 == 0.02 and joint.qvel0 == pytest.approx(scene.start_speed, rel=1e-15)
    assert body.inertia.mass == pytest.approx(300.0 * 0.5 * 1.0 * 0.02, rel=1e-15)
    # m v' = m g sin(theta) + slide_force on the exact solution: gravity along the slide plus the snow
    t = np.linspace(0.1, 1.9, 5)
    exact = scene.exact(t)
    mass = scene.body_mass(t, exact["distance"])
    acceleration = _derivative(lambda s: scene.exact(s)["speed"], t, 1e-4)
    force = mass * G * np.sin(slope) + scene.slide_force(t, exact["distance"], exact["speed"])
    np.testing.assert_allclose(mass * acceleration, force, rtol=1e-9)
