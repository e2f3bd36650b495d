"""Rolling and sliding down an incline, and the chapter's race, against their closed forms.

The chapter (rolling disc): (I/a^2 + M) x'' = M g sin(alpha), so x'' = 2/3 g sin(alpha) for the disc
(I = M a^2/2) and 1/2 g sin(alpha) for the hollow cylinder (I = M a^2); the solid cylinder wins the
race. The sliding case is Coulomb friction mu M g cos(alpha) up the slope at the contact point.
"""

from __future__ import annotations

import numpy as np
import pytest

import rbody
from rbody import Inertia
from rbody.errors import MethodNotApplicable
from rbody.motion import quat_from_axis_angle
from rbody.scene import BodyStates
from rbody.scenes import rolling, rolling_race
from rbody.scenes.rolling import arrival_times

G = 9.81
# The coefficient c in x'' = c g sin(alpha) when rolling: 1 / (1 + I / (M a^2)).
ROLLING_FRACTION = {"disc": 2 / 3, "hollow_cylinder": 1 / 2, "solid_sphere": 5 / 7, "spherical_shell": 3 / 5}
# k = I / (M a^2).
RATIO = {"disc": 1 / 2, "hollow_cylinder": 1.0, "solid_sphere": 2 / 5, "spherical_shell": 2 / 3}
INCLINES = np.array([0.1, 0.35, np.pi / 6, 0.7, 1.2])
EXACT_METHODS = ("verlet", "rk4", "yoshida6", "gauss6")  # constant acceleration: exact to round-off


def _close(got, want, rtol=1e-12, scale=None):
    """|got - want| <= rtol * scale, scale = max|want| by default (round-off relative to the size of the
    observable; give the scale of the quantities it is formed from where it is exactly zero)."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    scale = max(float(np.max(np.abs(want))), 1e-300) if scale is None else scale
    np.testing.assert_allclose(got, want, rtol=0, atol=rtol * scale)


# ----- rolling: the chapter's accelerations ----------------------------------------------------------

@pytest.mark.parametrize("body", list(ROLLING_FRACTION))
def test_rolling_acceleration_is_the_chapters(body):
    scene = rolling(body, radius=0.1, incline=INCLINES, friction=10.0)
    assert np.all(scene.rolls)
    np.testing.assert_allclose(scene.acceleration, ROLLING_FRACTION[body] * G * np.sin(INCLINES), rtol=1e-15)
    np.testing.assert_allclose(scene.angular_acceleration, scene.acceleration / 0.1, rtol=1e-15)


@pytest.mark.parametrize("body", list(ROLLING_FRACTION))
def test_rolling_run_matches_closed_form(body):
    radius, mass = 0.15, 2.5
    scene = rolling(body, radius=radius, mass=mass, incline=INCLINES, friction=10.0, t_end=1.0)
    run = rbody.simulate(scene, dt=1e-3, method="verlet")
    t = run.t[:, None]
    accel = ROLLING_FRACTION[body] * G * np.sin(INCLINES)
    _close(run["distance"], 0.5 * accel * t**2)
    _close(run["speed"], accel * t)
    _close(run["spin"], accel * t / radius)
    # no slip and no energy change, to round-off of the speeds and energies involved
    assert np.max(np.abs(run["slip"])) <= 1e-12 * np.max(accel)
    assert np.max(np.abs(run["energy"])) <= 1e-12 * mass * G * np.max(np.sin(INCLINES) * 0.5 * accel)
    exact = scene.exact(run.t)
    _close(exact["distance"], 0.5 * accel * t**2, rtol=1e-15)
    _close(exact["spin"], accel * t / radius, rtol=1e-15)
    assert np.all(exact["slip"] == 0) and np.all(exact["energy"] == 0)


def test_chapter_rolling_disc_energy():
    # E = 1/2 (I/a^2 + M) x'^2 - M g x sin(alpha) is conserved: with I = M a^2/2, E(t) = E(0) = 0.
    radius, mass, incline = 0.3, 4.0, 0.4
    scene = rolling("disc", radius=radius, mass=mass, incline=incline, t_end=2.0)
    for method in EXACT_METHODS:
        run = rbody.simulate(scene, dt=1e-3, method=method)
        x, v = run["distance"], run["speed"]
        chapter = 0.5 * (mass / 2 + mass) * v**2 - mass * G * x * np.sin(incline)
        scale = mass * G * np.sin(incline) * x[-1]
        assert np.max(np.abs(chapter)) <= 1e-12 * scale, method
        assert np.max(np.abs(run["energy"])) <= 1e-12 * scale, method


# ----- mu_min and the boundary ---------------------------------------------------------------------

@pytest.mark.parametrize("body", list(ROLLING_FRACTION))
def test_mu_min(body):
    scene = rolling(body, radius=0.1, incline=INCLINES)
    k = RATIO[body]
    np.testing.assert_allclose(scene.mu_min, np.tan(INCLINES) / (1 + 1 / k), rtol=1e-15)
    if body == "disc":
        np.testing.assert_allclose(scene.mu_min, np.tan(INCLINES) / 3, rtol=1e-15)


@pytest.mark.parametrize("body", list(ROLLING_FRACTION))
def test_boundary_rolls_and_just_below_slides(body):
    incline = 0.6
    mu_min = rolling(body, radius=0.1, incline=incline).mu_min
    at = rolling(body, radius=0.1, incline=incline, friction=mu_min)
    below = rolling(body, radius=0.1, incline=incline, friction=np.nextafter(mu_min, 0.0))
    assert at.rolls is True
    assert below.rolls is False
    assert at.acceleration == pytest.approx(ROLLING_FRACTION[body] * G * np.sin(incline), rel=1e-15)
    mu = np.nextafter(mu_min, 0.0)
    assert below.acceleration == pytest.approx(G * (np.sin(incline) - mu * np.cos(incline)), rel=1e-15)
    # the motion is continuous across the boundary: both formulas agree at mu_min
    assert below.acceleration == pytest.approx(at.acceleration, rel=1e-14)
    assert below.angular_acceleration == pytest.approx(at.angular_acceleration, rel=1e-14)


# ----- sliding -------------------------------------------------------------------------------------

@pytest.mark.parametrize("body", list(ROLLING_FRACTION))
def test_sliding_matches_closed_form(body):
    radius, mass, incline, mu = 0.2, 2.0, 0.5, 0.05
    k = RATIO[body]
    assert mu < np.tan(incline) * k / (1 + k)  # below mu_min: the body slides
    scene = rolling(body, radius=radius, mass=mass, incline=incline, friction=mu, t_end=1.5)
    assert scene.rolls is False
    run = rbody.simulate(scene, dt=1e-3, method="verlet")
    t = run.t
    x_dd = G * (np.sin(incline) - mu * np.cos(incline))
    moment = k * mass * radius**2
    phi_dd = mu * mass * G * np.cos(incline) * radius / moment
    x, phi = 0.5 * x_dd * t**2, 0.5 * phi_dd * t**2
    _close(run["distance"], x)
    _close(run["speed"], x_dd * t)
    _close(run["spin"], phi_dd * t)
    _close(run["slip"], (x_dd - radius * phi_dd) * t)
    # energy lost = friction force times the slipped distance x - a phi
    _close(run["energy"], -mu * mass * G * np.cos(incline) * (x - radius * phi))
    assert np.all(np.diff(run["energy"]) < 0)
    assert np.all(np.diff(run["slip"]) > 0)


def test_frictionless_slide_does_not_spin():
    scene = rolling("disc", radius=0.1, incline=0.3, friction=0.0)
    run = rbody.simulate(scene, dt=1e-2)
    assert np.all(run["spin"] == 0.0)
    _close(run["distance"], 0.5 * G * np.sin(0.3) * run.t**2)
    # no friction: no energy lost
    assert np.max(np.abs(run["energy"])) <= 1e-12 * G * np.sin(0.3) * run["distance"][-1]


def test_energy_exact_matches_its_definition_while_sliding():
    scene = rolling("solid_sphere", radius=0.1, mass=3.0, incline=1.0, friction=0.1, t_end=0.8)
    t = np.linspace(0, 0.8, 9)
    e = scene.exact(t)
    moment = 0.4 * 3.0 * 0.1**2
    definition = 0.5 * 3.0 * e["speed"] ** 2 + 0.5 * moment * e["spin"] ** 2 - 3.0 * G * np.sin(1.0) * e["distance"]
    _close(e["energy"], definition, rtol=1e-14)
    assert np.all(e["energy"][1:] < 0)


# ----- the methods ---------------------------------------------------------------------------------

@pytest.mark.parametrize("method", EXACT_METHODS + ("reference",))
def test_exact_methods_are_exact(method):
    scene = rolling("hollow_cylinder", radius=0.1, incline=np.array([0.3, 0.8]), friction=np.array([1.0, 0.1]))
    run = rbody.simulate(scene, dt=1e-3, method=method)
    exact = scene.exact(run.t)
    rtol = 1e-12 if method != "reference" else 1e-11
    for name in ("distance", "speed", "spin"):
        _close(run[name], exact[name], rtol=rtol)


def test_euler_has_an_order_one_offset():
    # Euler: x_n+1 = x_n + dt v_n, v_n = A n dt, so x_n = A t (t - dt)/2: an offset A t dt / 2.
    # Symplectic Euler updates v first: x_n = A t (t + dt)/2.
    scene = rolling("disc", radius=0.1, incline=0.4)
    accel = scene.acceleration
    errors = []
    for dt in (2e-3, 1e-3):
        euler = rbody.simulate(scene, dt=dt, method="euler")
        _close(euler["distance"], 0.5 * accel * euler.t * (euler.t - dt))
        symplectic = rbody.simulate(scene, dt=dt, method="symplectic_euler")
        _close(symplectic["distance"], 0.5 * accel * symplectic.t * (symplectic.t + dt))
        errors.append(abs(euler["distance"][-1] - scene.exact(euler.t)["distance"][-1]))
        assert errors[-1] == pytest.approx(0.5 * accel * euler.t[-1] * dt, rel=1e-9)
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=1e-9)  # first order


def test_splitting_is_not_a_rolling_method():
    with pytest.raises(MethodNotApplicable, match="rolling"):
        rbody.simulate(rolling("disc", radius=0.1, incline=0.3), dt=1e-2, method="splitting")


# ----- batches ---------------------------------------------------------------------------------------

def test_batch_equals_single_runs():
    scene = rolling("spherical_shell", radius=np.array([[0.1], [0.3]]), mass=np.array([1.0, 2.0, 5.0]),
                    incline=np.array([[0.2, 0.6, 1.1]]), friction=np.array([[1.0], [0.05]]), t_end=0.5)
    assert scene.batch_shape == (2, 3)
    batch = rbody.simulate(scene, dt=1e-2, method="verlet")
    rolls = np.asarray(scene.rolls)
    assert rolls.any() and not rolls.all()  # both cases in one batch
    for index in np.ndindex(scene.batch_shape):
        single = rbody.simulate(scene.item(index), dt=1e-2, method="verlet")
        for name in scene.observables:
            np.testing.assert_array_equal(batch[name][(slice(None),) + index], single[name], err_msg=name)


# ----- any Inertia -------------------------------------------------------------------------------------

def test_inertia_body_equals_named_disc():
    disc = Inertia.solid_cylinder(2.0, 0.1, 0.05, axis="y")
    scene = rolling(disc, radius=0.1, incline=0.5)
    assert scene.mass == 2.0
    assert scene.acceleration == pytest.approx(2 / 3 * G * np.sin(0.5), rel=1e-14)
    assert scene.mu_min == pytest.approx(np.tan(0.5) / 3, rel=1e-14)


def test_yoyo_inertia_rolls_on_its_axle():
    # A thin disc of radius sqrt(6) a rolling on an axle of radius a: I = M (6 a^2)/2 = 3 M a^2 (k = 3),
    # so x'' = g sin(alpha)/4 and mu_min = 3/4 tan(alpha).
    mass, axle = 0.5, 0.02
    yoyo = Inertia.disc(mass, np.sqrt(6) * axle, axis="y")
    scene = rolling(yoyo, radius=axle, incline=0.3, t_end=1.0)
    assert scene.acceleration == pytest.approx(G * np.sin(0.3) / 4, rel=1e-14)
    assert scene.mu_min == pytest.approx(0.75 * np.tan(0.3), rel=1e-14)
    run = rbody.simulate(scene, dt=1e-3)
    _close(run["distance"], 0.5 * G * np.sin(0.3) / 4 * run.t**2)


def test_inertia_with_offset_centre_rolls_about_its_centre_of_mass():
    body = Inertia.solid_sphere(1.5, 0.2).translated([0.3, -0.1, 0.2])
    scene = rolling(body, radius=0.2, incline=0.4)
    layout = scene.layout
    _down, normal = _frame(0.4)
    part = layout.bodies[0]
    np.testing.assert_allclose(np.array(part.pos) + body.com, 0.2 * normal, rtol=0, atol=1e-15)
    for joint in layout.joints:
        np.testing.assert_allclose(joint.anchor, body.com)
    np.testing.assert_allclose(part.shapes[0].pos, body.com)


# ----- layout ---------------------------------------------------------------------------------------------

def _frame(incline):
    return np.array([np.cos(incline), 0, -np.sin(incline)]), np.array([np.sin(incline), 0, np.cos(incline)])


def _rotate(quat, vector):
    from rbody.motion import quat_rotate
    return quat_rotate(np.asarray(quat), np.asarray(vector, float))


@pytest.mark.parametrize("body", list(ROLLING_FRACTION))
def test_layout_geometry(body):
    radius, incline = 0.1, 0.5
    scene = rolling(body, radius=radius, incline=incline, friction=0.7, t_end=1.2)
    layout = scene.layout
    down, normal = _frame(incline)
    (plane,) = layout.fixed
    assert plane.name == "incline" and plane.kind == "plane"
    np.testing.assert_allclose(_rotate(plane.quat, [0, 0, 1]), normal, rtol=0, atol=1e-15)
    np.testing.assert_allclose(_rotate(plane.quat, [1, 0, 0]), down, rtol=0, atol=1e-15)
    # the plane holds the top point (the origin) and covers the whole travel with room to spare
    assert abs(np.dot(plane.pos, normal)) < 1e-15
    travel = scene.exact([1.2])["distance"][0]
    centre_along = np.dot(plane.pos, down)
    assert centre_along - plane.size[0] < -radius and centre_along + plane.size[0] > travel + radius
    (part,) = layout.bodies
    assert part.name == "body"
    # centre of the body one radius above the surface at the top point
    np.testing.assert_allclose(np.array(part.pos) + part.inertia.com, radius * normal, rtol=0, atol=1e-15)
    assert part.inertia.moment("y") == pytest.approx(RATIO[body] * radius**2, rel=1e-14)
    (shape,) = part.shapes
    if body.endswith("sphere") or body.endswith("shell"):
        assert shape.kind == "sphere" and shape.size == (radius,)
    else:
        assert shape.kind == "cylinder" and shape.size == (radius, radius / 2)
        np.testing.assert_allclose(_rotate(shape.quat, [0, 0, 1]), [0, 1, 0], rtol=0, atol=1e-15)
    names = [j.name for j in layout.joints]
    assert names == ["x", "z", "phi"]
    x, z, phi = layout.joints
    assert (x.kind, z.kind, phi.kind) == ("slide", "slide", "hinge")
    np.testing.assert_allclose(x.axis, down, rtol=0, atol=1e-15)
    np.testing.assert_allclose(z.axis, normal, rtol=0, atol=1e-15)
    (contact,) = layout.contacts
    assert {contact.shape_a, contact.shape_b} == {shape.name, "incline"}
    assert contact.friction == 0.7 and contact.restitution == 0.0


def test_hinge_sign_makes_the_contact_point_rest_when_rolling_down():
    # v_contact = v d + w axis x (contact - centre), contact - centre = -a n: zero for v = a w > 0.
    radius, incline = 0.25, 0.3
    layout = rolling("disc", radius=radius, incline=incline).layout
    x, _z, phi = layout.joints
    down, normal = _frame(incline)
    speed = 1.7
    spin = speed / radius
    contact_velocity = speed * np.array(x.axis) + spin * np.cross(phi.axis, -radius * normal)
    np.testing.assert_allclose(contact_velocity, 0.0, rtol=0, atol=1e-15)
    # the rolling run has positive spin
    run = rbody.simulate(rolling("disc", radius=radius, incline=incline), dt=1e-2)
    assert np.all(run["spin"][1:] > 0)


def test_batched_scene_has_no_layout():
    with pytest.raises(ValueError, match="batch"):
        rolling("disc", radius=0.1, incline=np.array([0.1, 0.2])).layout  # noqa: B018


def _scales(exact, mass, incline):
    """Size of each observable's ingredients: slip from speeds, energy from the potential energy released."""
    sizes = {name: float(np.max(np.abs(exact[name]))) for name in ("distance", "speed", "spin")}
    sizes["slip"] = sizes["speed"]
    sizes["energy"] = mass * G * np.sin(incline) * sizes["distance"]
    return sizes


def _states_from_exact(radius, incline, exact, t, offset=np.zeros(3)):
    """World-frame states of a body moving as the closed form says (for observe())."""
    down, normal = _frame(incline)
    x, v, w = exact["distance"], exact["speed"], exact["spin"]
    phi = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    com = radius * normal + offset + x[:, None] * down
    return BodyStates(com=com, quat=quat_from_axis_angle([0, 1, 0], phi), velocity=v[:, None] * down,
                      omega=w[:, None] * np.array([0.0, 1.0, 0.0])), phi


@pytest.mark.parametrize("friction", [1.0, 0.03])
def test_observe_from_body_states_gives_the_observables(friction):
    scene = rolling("disc", radius=0.1, mass=2.0, incline=0.6, friction=friction, t_end=1.0)
    t = np.linspace(0, 1, 11)
    exact = scene.exact(t)
    states, phi = _states_from_exact(0.1, 0.6, exact, t)
    joints = {"x": (exact["distance"], exact["speed"]), "z": (0 * t, 0 * t), "phi": (phi, exact["spin"])}
    got = scene.observe(t, {"body": states}, joints)
    scales = _scales(exact, mass=2.0, incline=0.6)
    for name in scene.observables:
        _close(got[name], exact[name], rtol=1e-13, scale=scales[name])
    if friction < scene.mu_min:
        assert got["energy"][-1] < 0


def test_observe_counts_motion_along_the_normal():
    # a body lifted by h off the slope at rest has energy M g h cos(alpha)
    scene = rolling("solid_sphere", radius=0.1, mass=2.0, incline=0.6)
    _down, normal = _frame(0.6)
    h = 0.01
    states = BodyStates(com=(0.1 + h) * normal[None, :], quat=np.array([[1.0, 0, 0, 0]]),
                        velocity=np.zeros((1, 3)), omega=np.zeros((1, 3)))
    got = scene.observe(np.zeros(1), {"body": states}, {"x": (np.zeros(1),) * 2, "phi": (np.zeros(1),) * 2})
    assert got["energy"][0] == pytest.approx(2.0 * G * h * np.cos(0.6), rel=1e-12)


def test_describe_names_the_scene():
    text = rolling("spherical_shell", radius=0.1, incline=0.3, friction=0.2).describe()
    assert "spherical_shell" in text and "0.3" in text and "0.2" in text


# ----- the race --------------------------------------------------------------------------------------------

def test_chapter_race_solid_beats_hollow():
    length, incline = 2.0, 0.25
    race = rolling_race(radius=0.1, incline=incline, length=length)
    assert race.labels == ("disc", "hollow_cylinder")
    want = np.sqrt(2 * length / (np.array([2 / 3, 1 / 2]) * G * np.sin(incline)))
    np.testing.assert_allclose(race.arrival_time, want, rtol=1e-15)
    assert race.arrival_time[1] / race.arrival_time[0] == pytest.approx(np.sqrt(4 / 3), rel=1e-15)
    assert race.t_end > race.arrival_time.max()
    run = rbody.simulate(race, dt=1e-3, method="verlet")
    arrived = run["arrival_time"][-1]
    np.testing.assert_allclose(arrived, want, rtol=1e-12)
    assert arrived[0] < arrived[1]


@pytest.mark.parametrize("method", ["verlet", "rk4", "yoshida6"])
def test_race_order_and_arrival_times(method):
    bodies = ("hollow_cylinder", "solid_sphere", "spherical_shell", "disc")
    length, incline = 3.0, 0.4
    race = rolling_race(bodies, radius=0.05, incline=incline, length=length)
    want = np.sqrt(2 * length / (np.array([ROLLING_FRACTION[b] for b in bodies]) * G * np.sin(incline)))
    run = rbody.simulate(race, dt=1e-3, method=method)
    assert run["distance"].shape == (run.t.size, 4) and run["speed"].shape == (run.t.size, 4)
    got = arrival_times(run, length)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    np.testing.assert_array_equal(run["arrival_time"], np.broadcast_to(got, run["arrival_time"].shape))
    np.testing.assert_array_equal(race.arrival_times(run), got)
    # sphere beats disc beats shell beats hoop
    assert [bodies[i] for i in np.argsort(got)] == ["solid_sphere", "disc", "spherical_shell", "hollow_cylinder"]
    assert [bodies[i] for i in race.finishing_order] == ["solid_sphere", "disc", "spherical_shell", "hollow_cylinder"]
    accel = np.array([ROLLING_FRACTION[b] for b in bodies]) * G * np.sin(incline)
    _close(run["distance"], 0.5 * accel * run.t[:, None] ** 2)


def test_race_columns_equal_single_rolling_runs():
    bodies = ("solid_sphere", "hollow_cylinder")
    race = rolling_race(bodies, radius=0.1, incline=0.5, length=1.0, mass=2.0, friction=0.2)
    assert list(race.rolls) == [True, False]  # mu_min: 2/7 tan(0.5) = 0.156 for the sphere, 1/2 tan(0.5) = 0.273
    run = rbody.simulate(race, dt=1e-3)
    for i, body in enumerate(bodies):
        single = rbody.simulate(rolling(body, radius=0.1, mass=2.0, incline=0.5, friction=0.2, t_end=race.t_end),
                                dt=1e-3)
        for name in ("distance", "speed", "spin", "slip", "energy"):
            _close(run[name][:, i], single[name], rtol=1e-15)


def test_race_with_a_sliding_body_arrives_as_the_sliding_formula_says():
    race = rolling_race(("disc", "hollow_cylinder"), radius=0.1, incline=0.6, length=1.5, friction=0.2)
    # disc: mu_min = tan(0.6)/3 = 0.228 > 0.2 slides; hoop: tan(0.6)/2 = 0.342 slides too
    assert not race.rolls.any()
    want = np.sqrt(2 * 1.5 / (G * (np.sin(0.6) - 0.2 * np.cos(0.6))))
    run = rbody.simulate(race, dt=1e-3)
    np.testing.assert_allclose(run["arrival_time"][-1], [want, want], rtol=1e-12)


def test_arrival_is_nan_when_the_run_is_too_short():
    race = rolling_race(("disc", "hollow_cylinder"), radius=0.1, incline=0.3, length=1.0)
    t_between = 0.5 * (race.arrival_time[0] + race.arrival_time[1])
    run = rbody.simulate(race, dt=1e-3, t_end=t_between)
    got = arrival_times(run, 1.0)
    assert np.isfinite(got[0]) and np.isnan(got[1])


def test_race_layout_side_by_side():
    bodies = ("solid_sphere", "disc", "spherical_shell", "hollow_cylinder")
    radius, incline = 0.1, 0.3
    race = rolling_race(bodies, radius=radius, incline=incline, length=2.0, friction=0.8)
    layout = race.layout
    down, normal = _frame(incline)
    assert [b.name for b in layout.bodies] == [f"body_{i}" for i in range(4)]
    assert [j.name for j in layout.joints] == [f"{q}_{i}" for i in range(4) for q in ("x", "z", "phi")]
    for joint in layout.joints:
        expected = {"x": down, "z": normal, "phi": np.array([0.0, 1.0, 0.0])}[joint.name.split("_")[0]]
        np.testing.assert_allclose(joint.axis, expected, rtol=0, atol=1e-15)
    # extents across the slope (world y) do not overlap
    extents = []
    for part in layout.bodies:
        centre = np.array(part.pos) + part.inertia.com
        np.testing.assert_allclose(centre - centre[1] * np.array([0, 1, 0]), radius * normal, rtol=0, atol=1e-15)
        (shape,) = part.shapes
        half = shape.size[0] if shape.kind == "sphere" else shape.size[1]
        extents.append((centre[1] - half, centre[1] + half))
    extents.sort()
    assert all(a[1] < b[0] for a, b in zip(extents, extents[1:]))
    # every contact is between a body and the incline, and the incline is wide enough
    assert len(layout.contacts) == 4
    assert all("incline" in (c.shape_a, c.shape_b) and c.friction == 0.8 for c in layout.contacts)
    (plane,) = layout.fixed
    assert plane.size[1] > max(abs(e) for pair in extents for e in pair)
    travel = race.exact([race.t_end])["distance"].max()
    assert np.dot(plane.pos, down) + plane.size[0] > travel + radius


def test_race_observe_from_body_states():
    bodies = ("disc", "spherical_shell")
    race = rolling_race(bodies, radius=0.1, incline=0.5, length=1.0, friction=0.1)
    t = np.linspace(0, race.t_end, 2001)
    exact = race.exact(t)
    states, joints = {}, {}
    for i, body in enumerate(bodies):
        column = {name: exact[name][:, i] for name in ("distance", "speed", "spin")}
        states[f"body_{i}"], phi = _states_from_exact(0.1, 0.5, column, t, offset=np.array([0, i - 0.5, 0]))
        joints[f"x_{i}"] = (column["distance"], column["speed"])
        joints[f"phi_{i}"] = (phi, column["spin"])
    got = race.observe(t, states, joints)
    scales = _scales(exact, mass=1.0, incline=0.5)
    for name in ("distance", "speed", "spin", "slip", "energy"):
        _close(got[name], exact[name], rtol=1e-13, scale=scales[name])
    np.testing.assert_allclose(got["arrival_time"], exact["arrival_time"], rtol=1e-12)


# ----- bad input ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    (dict(radius=0.0, incline=0.3), "radius"),
    (dict(radius=-1.0, incline=0.3), "radius"),
    (dict(radius=np.nan, incline=0.3), "radius"),
    (dict(radius=0.1, mass=0.0, incline=0.3), "mass"),
    (dict(radius=0.1, mass=np.nan, incline=0.3), "mass"),
    (dict(radius=0.1, incline=0.0), "incline"),
    (dict(radius=0.1, incline=np.pi / 2), "incline"),
    (dict(radius=0.1, incline=-0.2), "incline"),
    (dict(radius=0.1, incline=np.nan), "incline"),
    (dict(radius=0.1, incline=0.3, friction=-0.1), "friction"),
    (dict(radius=0.1, incline=0.3, friction=np.nan), "friction"),
    (dict(radius=0.1, incline=0.3, t_end=0.0), "t_end"),
    (dict(radius=0.1, incline=0.3, gravity=np.nan), "gravity"),
    (dict(radius=np.array([0.1, 0.2]), incline=np.array([0.1, 0.2, 0.3])), "broadcast"),
])
def test_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        rolling("disc", **kwargs)


def test_unknown_body_lists_the_valid_ones():
    with pytest.raises(ValueError, match="cube.*'disc', 'hollow_cylinder', 'solid_sphere', 'spherical_shell'"):
        rolling("cube", radius=0.1, incline=0.3)
    with pytest.raises(ValueError, match="hollow_cylinder"):
        rolling(3.0, radius=0.1, incline=0.3)


def test_bad_inertia_bodies():
    with pytest.raises(ValueError, match="moment about its y axis"):
        rolling(Inertia.rod(1.0, 1.0, "y"), radius=0.1, incline=0.3)
    tilted = Inertia.solid_cylinder(1.0, 0.1, 0.5, axis=[1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="principal axis"):
        rolling(tilted, radius=0.1, incline=0.3)
    with pytest.raises(ValueError, match="mass"):
        rolling(Inertia.solid_sphere(2.0, 0.1), radius=0.1, mass=1.0, incline=0.3)


@pytest.mark.parametrize("kwargs, match", [
    (dict(bodies=()), "at least one body"),
    (dict(bodies=("disc", "cube")), r"bodies\[1\]"),
    (dict(length=0.0), "length"),
    (dict(length=np.nan), "length"),
    (dict(incline=2.0), "incline"),
    (dict(radius=np.array([0.1, 0.2])), "single value"),
    (dict(friction=-1.0), "friction"),
    (dict(t_end=-1.0), "t_end"),
    (dict(gravity=0.0), "gravity"),
])
def test_bad_race_input(kwargs, match):
    arguments = dict(radius=0.1, incline=0.3, length=1.0)
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=match):
        rolling_race(**arguments)
