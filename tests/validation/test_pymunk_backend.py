"""The pymunk backend against the exact solutions: the swinging rod, the sign of the angle mapping,
the rolling disc and the race, the double rod's normal mode, collisions on a line and the pi counts,
and what pymunk refuses.

pymunk is deterministic, so the measured figures quoted below repeat exactly on one build; the
bounds sit a little above them and say where they come from.
"""

import dataclasses

import numpy as np
import pytest

import rbody
from rbody import Inertia
from rbody.motion import quat_to_matrix
from rbody.scenes import rolling, swinging_rod
from rbody.scenes.pendulum import SwingingRod
from validation import run, supports
from validation.backends import pymunk as pm

pytestmark = pytest.mark.crosssim

DT = 1e-3


def _peaks(theta: np.ndarray) -> np.ndarray:
    """Local maxima of theta (T,), refined by the parabola through the three samples around each."""
    i = np.flatnonzero((theta[1:-1] > theta[:-2]) & (theta[1:-1] >= theta[2:])) + 1
    a, b, c = theta[i - 1], theta[i], theta[i + 1]
    return b - (a - c) ** 2 / (8 * (a - 2 * b + c))


def _down_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times where x crosses zero downward, linearly interpolated."""
    i = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))
    return t[i] + (t[i + 1] - t[i]) * x[i] / (x[i] - x[i + 1])


def _swing_loss_per_period(dt: float, periods: int = 4) -> tuple[float, np.ndarray, SwingingRod]:
    """Fraction of the swing energy M g d (1 - cos theta_max) lost per period, from the turning points."""
    scene = swinging_rod(1.0, theta0=1.0, t_end=1.0)
    scene = dataclasses.replace(scene, t_end=(periods + 0.1) * scene.period)
    trajectory = pm.run(scene, dt)
    peaks = _peaks(trajectory["theta"])
    assert len(peaks) == periods
    loss = 1 - (1 - np.cos(peaks[-1])) / (1 - np.cos(1.0))
    return loss / periods, trajectory, scene


# ----- the swinging rod -------------------------------------------------------------------------------

def test_swinging_rod_loses_energy_at_a_rate_proportional_to_dt():
    # Measured (theta0 = 1 rad, L = 1 m, 4 periods): 3.19e-3 of the swing energy per period at dt = 1e-3,
    # 6.31e-3 at dt = 2e-3 (ratio 1.98): pymunk's PivotJoint pendulum is damped at a rate ~ dt.
    loss, trajectory, scene = _swing_loss_per_period(DT)
    coarse, _trajectory, _scene = _swing_loss_per_period(2 * DT)
    assert 2.5e-3 < loss < 4e-3
    assert 1.9 < coarse / loss < 2.1, "the loss is first order in dt"
    # The angle is off by the lost amplitude: measured 8.76e-3 rad over 4 periods at dt = 1e-3.
    exact = scene.exact(trajectory.t)
    assert np.max(np.abs(trajectory["theta"] - exact["theta"])) < 1e-2


def test_swinging_rod_period_matches_the_exact_period():
    # The first full swing (between the first two downward zero crossings) at dt = 1e-3 is measured
    # 3.8e-5 longer than 4 K(k^2)/w0 (7.4e-5 at dt = 2e-3: a first-order phase error).
    scene = swinging_rod(1.0, theta0=1.0, t_end=1.0)
    scene = dataclasses.replace(scene, t_end=2.5 * scene.period)
    trajectory = pm.run(scene, DT)
    crossings = _down_crossings(trajectory.t, trajectory["theta"])
    period = crossings[1] - crossings[0]
    assert abs(period / scene.period - 1) < 1e-4
    exact_crossings = _down_crossings(trajectory.t, scene.exact(trajectory.t)["theta"])
    assert abs(crossings[0] - exact_crossings[0]) < 2 * DT


def test_swinging_rod_starts_from_the_scene_state_and_steps_position_first():
    # pymunk moves positions with the velocity before the step (the known O(dt) trap, not corrected),
    # then kicks the velocity with the force at the new position: theta_1 = theta_0 + omega_0 dt,
    # omega_1 = omega_0 - w0^2 sin(theta_1) dt. Measured: theta_1 to round-off, omega_1 to 4.7e-8 rad/s
    # (the pivot's iterative velocity solve).
    scene = swinging_rod(1.0, theta0=1.0, omega0=0.5, t_end=0.01)
    trajectory = pm.run(scene, DT)
    assert trajectory["theta"][0] == pytest.approx(1.0, abs=1e-15)
    assert trajectory["omega"][0] == pytest.approx(0.5, abs=1e-15)
    theta1 = 1.0 + 0.5 * DT
    assert trajectory["theta"][1] == pytest.approx(theta1, abs=1e-12)
    w0_squared = 9.81 * 0.5 / (1.0 / 3.0)
    assert trajectory["omega"][1] == pytest.approx(0.5 - w0_squared * np.sin(theta1) * DT, abs=1e-7)


def test_whirling_rod_angle_is_continuous_through_the_turns():
    # k^2 = 1.44 > 1: the rod goes over the top. The hinge angle is pymunk's unwrapped body angle, so it
    # keeps counting past -2 pi. Measured over 1 s: 0.100 rad behind the exact angle at dt = 1e-3 and
    # 0.200 at dt = 2e-3 (the energy lost ~ dt slows the whirl).
    scene = swinging_rod(1.0, theta0=0.5, omega0=-9.0, t_end=1.0)
    assert scene.modulus > 1
    trajectory = pm.run(scene, DT)
    theta, exact = trajectory["theta"], scene.exact(trajectory.t)["theta"]
    assert np.all(np.diff(theta) < 0) and theta[-1] < -2 * np.pi
    assert np.max(np.abs(theta - exact)) < 0.11
    assert np.max(np.abs(np.diff(theta))) < 10 * DT  # no jumps of 2 pi


# ----- the sign of the angle mapping ---------------------------------------------------------------------

def test_positive_angle_swings_back_through_zero_with_the_exact_sign(monkeypatch):
    theta0, d = 0.05, 0.5
    scene = swinging_rod(1.0, theta0=theta0, t_end=1.0)
    scene = dataclasses.replace(scene, t_end=scene.period)
    captured = {}
    observe_states = pm._observe_states

    def spy(*args):
        captured["bodies"], captured["joints"] = observe_states(*args)
        return captured["bodies"], captured["joints"]

    monkeypatch.setattr(pm, "_observe_states", spy)
    trajectory = pm.run(scene, DT)
    t, theta = trajectory.t, trajectory["theta"]
    exact = scene.exact(t)["theta"]
    # a right-handed turn by +theta about +y takes the hanging centre (0, 0, -d) to (-d sin, 0, -d cos)
    com = captured["bodies"]["body"].com
    assert com[0] == pytest.approx([-d * np.sin(theta0), 0.0, -d * np.cos(theta0)], abs=1e-15)
    # through zero at T/4 with theta' < 0, at -theta0 near T/2, back at +theta0 after one period
    for fraction in (1 / 8, 3 / 8, 5 / 8, 7 / 8):
        k = int(round(fraction * scene.period / DT))
        assert np.sign(theta[k]) == np.sign(exact[k]) != 0
    quarter = int(round(scene.period / 4 / DT))
    assert trajectory["omega"][quarter] < 0
    assert np.min(theta) == pytest.approx(-theta0, rel=1e-3)
    # the recorded orientation turns the reference offset of the centre of mass onto the recorded centre,
    # up to the PivotJoint's drift of the pivot (measured 1.2e-6 m here; 4.2e-4 m at theta0 = 1, ~ dt)
    rotation = quat_to_matrix(captured["bodies"]["body"].quat)
    assert np.allclose(rotation @ np.array([0.0, 0.0, -d]), com, atol=3e-6)
    assert np.allclose(quat_to_matrix(captured["bodies"]["body"].quat[0]),
                       [[np.cos(theta0), 0, np.sin(theta0)], [0, 1, 0], [-np.sin(theta0), 0, np.cos(theta0)]],
                       atol=1e-15)


@dataclasses.dataclass(frozen=True, kw_only=True)
class _RodOnMinusY(SwingingRod):
    """The swinging rod with its hinge axis written as -y: theta turns the rod the other way."""

    def _layout(self):
        layout = super()._layout()
        hinge = dataclasses.replace(layout.joints[0], axis=(0.0, -1.0, 0.0))
        return dataclasses.replace(layout, joints=(hinge,))


def test_hinge_axis_along_minus_y_turns_the_other_way(monkeypatch):
    scene = _RodOnMinusY(name="rod_minus_y", t_end=0.5, length=1.0, theta0=0.3)
    captured = {}
    observe_states = pm._observe_states
    monkeypatch.setattr(pm, "_observe_states",
                        lambda *args: captured.setdefault("out", observe_states(*args)))
    trajectory = pm.run(scene, DT)
    com = captured["out"][0]["body"].com
    assert com[0, 0] == pytest.approx(0.5 * np.sin(0.3), abs=1e-15)  # +theta about -y moves the centre to +x
    # the pendulum equation does not depend on the axis direction: theta follows the same exact curve
    assert np.max(np.abs(trajectory["theta"] - scene.exact(trajectory.t)["theta"])) < 2e-3


# ----- the rolling disc ------------------------------------------------------------------------------------

@pytest.mark.parametrize("friction", [1.0, 0.1])
def test_disc_on_an_incline_rolls_or_slides_with_the_exact_acceleration(friction):
    scene = rolling("disc", radius=0.1, incline=0.5, friction=friction, t_end=0.5)
    assert scene.rolls == (friction >= scene.mu_min)
    trajectory = pm.run(scene, DT)
    t = trajectory.t
    exact = scene.exact(t)
    if scene.rolls:
        assert scene.acceleration == pytest.approx(2 / 3 * 9.81 * np.sin(0.5), rel=1e-15)
    # Measured: speed, spin and slip exact to round-off (relative 1e-14); positions advance with the
    # velocity before each step, so the distance is a t (t - dt) / 2 (the O(dt) offset, not corrected).
    scale = scene.acceleration * t[-1]
    assert np.max(np.abs(trajectory["speed"] - exact["speed"])) < 1e-12 * scale
    assert np.max(np.abs(trajectory["slip"] - exact["slip"])) < 1e-12 * scale
    assert np.max(np.abs(trajectory["spin"] - exact["spin"])) < 1e-12 * scale / 0.1
    lagged = 0.5 * scene.acceleration * t * np.maximum(t - DT, 0.0)
    assert np.max(np.abs(trajectory["distance"] - lagged)) < 1e-12 * scale * t[-1]


def test_rolling_race_arrives_half_a_step_late():
    from rbody.scenes import rolling_race

    # side by side across the slope, the two bodies overlap in pymunk's plane: only the listed pairs
    # (each body with the incline) may collide, or the race would be wrecked
    scene = rolling_race(("disc", "hollow_cylinder"), radius=0.1, incline=0.4, length=1.0)
    trajectory = pm.run(scene, DT)
    # x = a t (t - dt) / 2 reaches L at t = sqrt(2 L / a) + dt/2 + O(dt^2)
    late = trajectory["arrival_time"][-1] - scene.arrival_time
    assert np.allclose(late, DT / 2, atol=1e-6)
    assert trajectory.meta["model"] == {"body_0": "free", "body_1": "free"}


# ----- what pymunk refuses, and bad settings -------------------------------------------------------------

def test_free_rotation_is_refused_as_three_dimensional():
    from rbody.scenes.free_rotation import free_rotation

    scene = free_rotation(Inertia.box(1.0, [1.0, 2.0, 3.0]), omega0=[0.1, 1.0, 0.1], t_end=1.0)
    with pytest.raises(NotImplementedError, match="2-D.*3-D rotation"):
        run(scene, "pymunk", dt=DT)
    ok, reason = supports(scene, "pymunk")
    assert not ok and "3-D rotation" in reason


def _two_body_orbit(periods: float = 1.0):
    from rbody.scenes import two_body

    scene = two_body(1.0, 2.0, separation=(1.0, 0.0, 0.0), relative_velocity=(0.0, 0.0, np.sqrt(3.9)), t_end=1.0)
    return dataclasses.replace(scene, t_end=periods * scene.period)


def test_pair_force_runs_as_symplectic_euler_first_order():
    # e = 0.3, one period (6.19 s): the orbit error halves with dt (first order); the energy error stays
    # bounded (symplectic Euler), 4.5e-4 of |E| at dt = 1e-3 over two periods (measured).
    scene = _two_body_orbit(1.0)
    errors = []
    for dt in (2e-3, 4e-3):
        trajectory = pm.run(scene, dt)
        exact = scene.exact(trajectory.t)
        errors.append(np.max(np.linalg.norm(trajectory["r1"] - exact["r1"], axis=1)))
        # equal and opposite forces: the centre of mass (at rest at the origin) does not move
        centre = (1.0 * trajectory["r1"] + 2.0 * trajectory["r2"]) / 3.0
        assert np.max(np.abs(centre)) < 1e-12
        energy = np.max(np.abs(trajectory["energy"] - exact["energy"])) / np.max(np.abs(exact["energy"]))
        assert energy < 2e-3 * dt / 1e-3
    assert 1.7 < errors[1] / errors[0] < 2.3, "first order in dt"
    assert errors[0] < 8e-3  # about 2.9e-3 m per ms of step (measured)
    assert "pair_force" in trajectory.meta["stepping"]


def test_varying_mass_and_slide_force_are_first_order():
    from rbody.scenes import avalanche, rocket

    scenes = (rocket(100.0, burn_rate=10.0, exhaust_speed=50.0, dry_mass=40.0, drag=2.0, t_end=8.0),
              avalanche(0.5, t_end=2.0))
    for scene in scenes:
        errors = []
        for dt in (2e-3, 4e-3):
            trajectory = pm.run(scene, dt)
            exact = scene.exact(trajectory.t)
            errors.append(np.max(np.abs(trajectory["distance"] - exact["distance"])))
            assert np.allclose(trajectory["mass"], scene.body_mass(trajectory.t, trajectory["distance"]))
        assert 1.7 < errors[1] / errors[0] < 2.3, f"{scene.name}: first order in dt, got {errors}"
        assert "body_mass" in trajectory.meta["stepping"]
    # The rocket burns to its dry mass and coasts: the coasting speed decays as exp(-beta t / dry).
    assert trajectory.t[-1] == pytest.approx(2.0)


def test_hooks_on_an_unsuitable_layout_are_refused():
    from rbody.scenes import stacked_balls

    scene = stacked_balls(1.0, 0.05, drop_height=1.0, gap=0.02)

    class Pushed(type(scene)):
        def slide_force(self, t, distance, speed):
            return np.zeros(np.size(t))

    pushed = Pushed(**{f.name: getattr(scene, f.name) for f in dataclasses.fields(scene)})
    with pytest.raises(NotImplementedError, match="one body on one slide"):
        pm.check(pushed)


def test_batched_scene_is_refused_one_at_a_time():
    scene = swinging_rod([1.0, 2.0], theta0=0.5, t_end=1.0)
    with pytest.raises(NotImplementedError, match=r"scene\.item\(i\)"):
        pm.check(scene)
    pm.check(scene.item(1))


@pytest.mark.parametrize("settings", [{"iterations": 0}, {"iterations": 2.5}, {"collision_slop": -1.0},
                                      {"save_every": None},
                                      {"save_every": 0}, {"dt": 0.0}, {"dt": float("nan")}])
def test_bad_settings_are_value_errors(settings):
    scene = swinging_rod(1.0, theta0=0.5, t_end=0.1)
    arguments = {"dt": DT, **settings}
    with pytest.raises(ValueError):
        pm.run(scene, arguments.pop("dt"), **arguments)


def test_settings_and_timing_are_recorded():
    scene = swinging_rod(1.0, theta0=0.5, t_end=0.1)
    trajectory = run(scene, "pymunk", dt=DT, iterations=7, collision_slop=1e-9, save_every=4)
    meta = trajectory.meta
    assert meta["backend"] == "pymunk" and meta["dt"] == DT
    assert meta["settings"] == {"iterations": 7, "collision_slop": 1e-9, "save_every": 4}
    assert meta["step_seconds"] > 0 and meta["pymunk"]
    assert np.allclose(np.diff(trajectory.t), 4 * DT)
    assert trajectory.t[-1] == pytest.approx(0.1)


# ----- the pendulum chain: nested hinges ---------------------------------------------------------------------

def test_double_rod_normal_mode_period_and_nested_hinge_geometry(monkeypatch):
    from rbody.scenes.chain import pendulum_chain

    probe = pendulum_chain(2, theta0=[0.0, 0.0], t_end=1.0)
    frequencies, shapes = probe.normal_modes()
    fast = shapes[:, 1] / np.max(np.abs(shapes[:, 1]))
    period = 2 * np.pi / frequencies[1]
    scene = pendulum_chain(2, theta0=1e-3 * fast, omega0=[0.0, 0.0], t_end=5.5 * period)
    captured = {}
    observe_states = pm._observe_states
    monkeypatch.setattr(pm, "_observe_states", lambda *args: captured.setdefault("out", observe_states(*args)))
    trajectory = pm.run(scene, DT)
    theta = trajectory["theta"]
    assert np.allclose(theta[0], 1e-3 * fast, rtol=0, atol=1e-16)  # absolute angles from the relative hinges
    crossings = _down_crossings(trajectory.t, theta[:, 0] * np.sign(fast[0]))
    measured = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    # the small-oscillation period of the fast mode, sqrt of K v = w^2 M0 v: measured 1.3e-6 off at dt = 1e-3
    assert abs(measured / period - 1) < 5e-6
    # each link's recorded centre of mass is where the chain's geometry puts it for the recorded angles,
    # up to the PivotJoints' drift (measured below 1e-8 m at this amplitude)
    bodies = captured["out"][0]
    com = np.stack([bodies[f"link_{i}"].com for i in range(2)], axis=1)
    assert np.allclose(com, scene.centres_of_mass(theta), atol=1e-7)


# ----- collisions on a line ------------------------------------------------------------------------------------

@pytest.mark.parametrize("digits, dt", [(1, 1e-3), (2, 1e-2)])
def test_pi_collisions_count_the_digits_of_pi(digits, dt):
    from rbody.scenes.collisions import pi_collisions

    # Heavy-ball speed 10^-digits keeps the light ball below 1 m/s: it moves at most dt x 1 m/s per step,
    # well inside its 0.05 m radius, so pymunk sees every contact. Measured: 31 and 314 impacts, the
    # exact counts (also 314 at dt = 1e-3), final velocities to 12 digits, energy to 6e-15.
    scene = pi_collisions(digits, speed=10.0**-digits)
    trajectory = pm.run(scene, dt, save_every=int(round(0.1 / dt)))
    assert trajectory.meta["line_mode"] and set(trajectory.meta["model"].values()) == {"line"}
    counts = scene.exact_counts
    assert trajectory["collisions"][-1] == scene.expected_collisions == int(np.floor(np.pi * 10**digits))
    assert trajectory["ball_collisions"][-1] == counts["ball"]
    exact = scene.exact(trajectory.t[-1:])
    assert trajectory["u"][-1] == pytest.approx(exact["u"][-1], rel=1e-11)
    assert trajectory["v"][-1] == pytest.approx(exact["v"][-1], rel=1e-11)
    assert trajectory["energy"][-1] == pytest.approx(trajectory["energy"][0], rel=1e-13)
    assert np.all(np.diff(trajectory["collisions"]) >= 0)


def _three_balls():
    """Three equal balls on a line, no walls: ball 0 hits ball 1 elastically, ball 1 hits ball 2 with
    e = 1/2. The middle ball is in two pairs of different restitution (set on pymunk's arbiter)."""
    from rbody.scenes.collisions import LineCollisions, line_collisions

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class ThreeBalls(LineCollisions):
        def _layout(self):
            layout = super()._layout()
            contacts = tuple(dataclasses.replace(c, restitution=0.5) if "ball_2" in (c.shape_a, c.shape_b) else c
                             for c in layout.contacts)
            return dataclasses.replace(layout, contacts=contacts)

    base = line_collisions([1.0, 1.0, 1.0], [0.0, 1.0, 2.0], [1.0, 0.0, 0.0], radii=0.05, walls=(), t_end=3.0)
    return ThreeBalls(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base) if f.init})


def test_each_pair_gets_its_own_restitution():
    scene = _three_balls()
    trajectory = pm.run(scene, DT)
    # equal masses: e = 1 passes the velocity on; e = 1/2 leaves (1 - e)/2 and gives (1 + e)/2
    assert np.allclose(trajectory["velocities"][-1], [0.0, 0.25, 0.75], rtol=0, atol=1e-12)
    assert trajectory["collisions"][-1] == 2 and trajectory["ball_collisions"][-1] == 2


def test_wall_from_a_rounded_quaternion_still_faces_along_the_line():
    # A plane turned by 90 deg about y has normal (1, 0, 2.2e-16) from the quaternion; circles on a
    # line amplify any sideways kick at each impact, so the backend rounds that to (1, 0, 0).
    from rbody.layout import Shape
    from rbody.scenes.collisions import PiCollisions, pi_collisions

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class PlaneWall(PiCollisions):
        def _layout(self):
            layout = super()._layout()
            half = np.sqrt(0.5)
            plane = Shape("wall_lo", "plane", (0.0, 0.0), pos=(0.0, 0.0, 0.0), quat=(half, 0.0, half, 0.0))
            return dataclasses.replace(layout, fixed=tuple(plane if s.name == "wall_lo" else s for s in layout.fixed))

    base = pi_collisions(1, speed=0.1)
    scene = PlaneWall(name="pi_plane", t_end=None, digits=1, speed=0.1)
    assert scene.t_end == base.t_end
    trajectory = pm.run(scene, DT, save_every=100)
    assert trajectory.meta["line_mode"]
    assert trajectory["collisions"][-1] == 31
    assert trajectory["energy"][-1] == pytest.approx(trajectory["energy"][0], rel=1e-13)


def test_balls_off_a_common_line_get_grooves():
    from rbody.scenes.collisions import LineCollisions, line_collisions

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Raised(LineCollisions):
        def _layout(self):
            layout = super()._layout()
            raised = dataclasses.replace(layout.bodies[1], pos=(1.0, 0.0, 0.01))
            return dataclasses.replace(layout, bodies=(layout.bodies[0], raised))

    base = line_collisions([1.0, 1.0], [0.0, 1.0], [1.0, 0.0], radii=0.05, walls=(), t_end=2.0)
    scene = Raised(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base) if f.init})
    assert not pm._plan(scene).line_mode
    trajectory = pm.run(scene, DT)
    assert trajectory.meta["model"] == {"ball_0": "groove", "ball_1": "groove"}
    # Frictionless, elastic, both balls held on their lines: the normal relative velocity reverses, and
    # with the velocities along x that reverses the x relative velocity; momentum along x is conserved
    # (the grooves push along z only): equal masses exchange velocities, as in the centred impact.
    assert np.allclose(trajectory["velocities"][-1], [0.0, 1.0], rtol=0, atol=1e-12)
    assert trajectory["collisions"][-1] == 1


@dataclasses.dataclass(frozen=True, kw_only=True)
class _RollingTree(rbody.Scene):
    """A rolling scene's reduced tree (one roll joint), as a scene (tests only)."""

    rolling: object

    def _layout(self):
        return self.rolling.rolling_tree()


def test_roll_joint_is_refused_and_the_rolling_scene_keeps_its_contacts():
    scene = rolling("disc", radius=0.1, incline=0.5, t_end=0.2)
    with pytest.raises(NotImplementedError, match="roll joint.*no joint that ties a body's rotation to its translation"):
        pm.check(_RollingTree(name="rolling_tree", t_end=0.2, rolling=scene))
    pm.check(scene)  # the scene itself: a body on the incline, held by a contact with friction
    assert {c.shape_b for c in scene.layout.contacts} == {"incline"}
