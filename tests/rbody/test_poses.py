"""Scene.body_poses: every family's bodies placed from its observables, against closed forms and against the
centres of mass the general engine reports for the same layout."""

import dataclasses

import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Scene, Shape, Trajectory, scenes
from rbody.motion import quat_to_matrix


def _run(scene, dt=1e-3, **kwargs):
    return rbody.simulate(scene, dt=dt, **kwargs)


def test_a_tree_places_its_bodies_where_the_engine_reports_their_centres_of_mass():
    upper = Body("upper", Inertia.rod(1.0, 0.8, "z").translated([0, 0, -0.4]))
    lower = Body("lower", Inertia.solid_sphere(0.5, 0.1).translated([0.05, 0.0, -0.5]), parent="upper",
                 pos=(0, 0, -0.8))
    layout = Layout(bodies=(upper, lower), joints=(Joint("shoulder", "ball", "upper", qpos0=(0.9, 0.3, 0.2, 0.1),
                                                         qvel0=(0.5, -1.0, 2.0)),
                                                   Joint("elbow", "hinge", "lower", axis=(0, 1, 0), qpos0=0.7)))
    arm = Scene.from_layout(layout, t_end=1.0)
    run = _run(arm, method="rk4")
    poses = arm.body_poses(run)
    for name in ("upper", "lower"):
        np.testing.assert_allclose(poses[name].com, run[f"{name}.com"], rtol=0, atol=1e-12)
        same = np.abs(np.sum(poses[name].quat * run[f"{name}.quat"], axis=1))
        np.testing.assert_allclose(same, 1.0, rtol=0, atol=1e-12)
    # the frame is not the centre of mass: pos + R c = com, with c = (0.05, 0, -0.5) for the lower body
    lower_pose = poses["lower"]
    offset = np.einsum("tab,b->ta", quat_to_matrix(lower_pose.quat), [0.05, 0.0, -0.5])
    np.testing.assert_allclose(lower_pose.pos + offset, lower_pose.com, rtol=0, atol=1e-12)
    assert np.min(np.linalg.norm(lower_pose.pos - lower_pose.com, axis=1)) > 0.4
    # a run that kept only qpos is placed from it by the layout's kinematics: the same poses
    from_qpos = arm.body_poses(Trajectory(run.t, {"qpos": run["qpos"]}))
    for name in ("upper", "lower"):
        np.testing.assert_allclose(from_qpos[name].com, run[f"{name}.com"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(from_qpos[name].pos, poses[name].pos, rtol=0, atol=1e-12)


@pytest.mark.crosssim
def test_a_tree_run_by_mujoco_is_placed_where_mujoco_reports_it():
    from validation.backends import get

    upper = Body("upper", Inertia.rod(1.0, 0.8, "z").translated([0, 0, -0.4]),
                 shapes=(Shape("u", "capsule", (0.02, 0.4), pos=(0, 0, -0.4)),))
    lower = Body("lower", Inertia.solid_sphere(0.5, 0.1), parent="upper", pos=(0, 0, -0.8),
                 shapes=(Shape("l", "sphere", (0.1,)),))
    layout = Layout(bodies=(upper, lower), joints=(Joint("a", "hinge", "upper", axis=(0, 1, 0), qpos0=1.0),
                                                   Joint("b", "hinge", "lower", axis=(0, 1, 0), qpos0=-0.5)))
    arm = Scene.from_layout(layout, t_end=1.0)
    run = get("mujoco").run(arm, 1e-3, None)
    poses = arm.body_poses(run)
    for name in ("upper", "lower"):
        np.testing.assert_allclose(poses[name].com, run[f"{name}.com"], rtol=0, atol=1e-9)


def test_the_rod_is_placed_by_its_angle():
    rod = scenes.swinging_rod(2.0, theta0=2.5, t_end=3.0)
    run = _run(rod, method="rk4")
    com = rod.body_poses(run)["body"].com
    theta = run["theta"]
    expected = np.stack([-np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=1)  # L/2 = 1 m from the pivot
    np.testing.assert_allclose(com, expected, rtol=0, atol=1e-12)


def test_the_chain_is_placed_as_the_engine_places_its_layout():
    chain = scenes.pendulum_chain(3, theta0=[0.6, 0.3, -0.2], t_end=1.0)
    run = _run(chain, method="rk4")
    tree = Scene.from_layout(chain.layout, t_end=1.0)
    reference = _run(tree, method="rk4")
    poses = chain.body_poses(run)
    for i in range(3):
        # two runs of one model by one method: equal to round-off of the coordinates
        np.testing.assert_allclose(poses[f"link_{i}"].com, reference[f"link_{i}.com"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("body", ["disc", "solid_sphere"])
def test_a_rolling_body_is_placed_on_the_incline_and_turned_by_the_distance(body):
    scene = scenes.rolling(body, radius=0.1, incline=0.5, t_end=1.0)
    run = _run(scene, method="rk4")
    pose = scene.body_poses(run)["body"]
    down, normal = np.array([np.cos(0.5), 0, -np.sin(0.5)]), np.array([np.sin(0.5), 0, np.cos(0.5)])
    exact = scene.exact(run.t)["distance"]
    np.testing.assert_allclose(pose.com, 0.1 * normal + exact[:, None] * down, rtol=0, atol=1e-12)
    # turned about +y by distance / radius (rolling: no slip)
    rotation = quat_to_matrix(pose.quat)
    angle = np.arctan2(rotation[:, 0, 2], rotation[:, 0, 0])
    np.testing.assert_allclose(np.unwrap(angle), exact / 0.1, rtol=0, atol=1e-9)
    # against the general engine on the scene's rolling tree (a roll joint), which reports body.com itself
    tree = Scene.from_layout(scene.rolling_tree(), t_end=1.0)
    reference = _run(tree, method="rk4")
    np.testing.assert_allclose(pose.com, reference["body.com"], rtol=0, atol=1e-9)
    same = np.abs(np.sum(pose.quat * reference["body.quat"], axis=1))
    np.testing.assert_allclose(same, 1.0, rtol=0, atol=1e-9)


def test_a_sliding_body_turns_by_its_spin_alone():
    scene = scenes.rolling("disc", radius=0.1, incline=0.5, friction=0.05, t_end=1.0)
    run = _run(scene, method="rk4")
    pose = scene.body_poses(run)["body"]
    rotation = quat_to_matrix(pose.quat)
    angle = np.unwrap(np.arctan2(rotation[:, 0, 2], rotation[:, 0, 0]))
    spin_angle = 0.5 * scene.angular_acceleration * run.t**2  # phi'' t^2 / 2, far less than distance / radius
    np.testing.assert_allclose(angle, spin_angle, rtol=0, atol=1e-9)
    assert angle[-1] < 0.5 * run["distance"][-1] / 0.1


def test_the_race_places_each_body_as_the_engine_places_its_rolling_tree():
    race = scenes.rolling_race(("disc", "hollow_cylinder", "solid_sphere"), radius=0.1, incline=0.3, length=0.5)
    run = _run(race, method="rk4")
    reference = _run(Scene.from_layout(race.rolling_tree(), t_end=race.t_end), method="rk4")
    poses = race.body_poses(run)
    assert list(poses) == ["body_0", "body_1", "body_2"]
    for name, pose in poses.items():
        np.testing.assert_allclose(pose.com, reference[f"{name}.com"], rtol=0, atol=1e-9)


def test_event_driven_and_other_families_place_bodies_where_their_observables_say():
    cradle = scenes.line_collisions((1.0, 1.0, 1.0), (0.0, 0.5, 0.7), (1.0, 0.0, 0.0), radii=0.1, walls=(),
                                    t_end=1.0)
    run = _run(cradle)
    poses = cradle.body_poses(run)
    for i in range(3):
        np.testing.assert_allclose(poses[f"ball_{i}"].com[:, 0], run["positions"][:, i], rtol=0, atol=1e-15)
        np.testing.assert_allclose(poses[f"ball_{i}"].com[:, 1:], 0.0, rtol=0, atol=1e-15)

    stacked = scenes.stacked_balls(1.0, 0.05, drop_height=1.0, gap=0.02)
    run = _run(stacked)
    poses = stacked.body_poses(run)
    np.testing.assert_allclose(poses["large"].com[:, 2], run["large_height"] + 0.1, rtol=0, atol=1e-14)
    np.testing.assert_allclose(poses["small"].com[:, 2], run["small_height"] + 0.02, rtol=0, atol=1e-14)

    scattering = scenes.scattering(0.1, radius=0.1)
    run = _run(scattering)
    poses = scattering.body_poses(run)
    np.testing.assert_allclose(poses["disc_1"].com[:, [0, 2]], run["position_1"], rtol=0, atol=1e-14)
    np.testing.assert_allclose(poses["disc_2"].com[:, [0, 2]], run["position_2"], rtol=0, atol=1e-14)

    orbit = scenes.two_body(1.0, 2.0, separation=(1.0, 0.0, 0.0), relative_velocity=(0.0, 0.0, 1.5), t_end=2.0)
    run = _run(orbit, method="rk4")
    poses = orbit.body_poses(run)
    np.testing.assert_allclose(poses["body1"].com, run["r1"], rtol=0, atol=1e-14)
    np.testing.assert_allclose(poses["body2"].com, run["r2"], rtol=0, atol=1e-14)

    rocket = scenes.rocket(100.0, burn_rate=10.0, exhaust_speed=50.0, dry_mass=40.0, drag=2.0, t_end=8.0)
    run = _run(rocket, method="rk4")
    np.testing.assert_allclose(rocket.body_poses(run)["rocket"].com[:, 0], run["distance"], rtol=0, atol=1e-12)

    avalanche = scenes.avalanche(0.5, t_end=1.0)
    run = _run(avalanche, method="rk4")
    down = np.array([np.cos(0.5), 0.0, -np.sin(0.5)])
    com = avalanche.body_poses(run)["slab"].com
    np.testing.assert_allclose(com, run["distance"][:, None] * down, rtol=0, atol=1e-12)


def test_a_free_rotation_turns_about_its_resting_centre_of_mass():
    body = Inertia(2.0, np.array([0.1, -0.2, 0.3]), np.diag([1.0, 2.0, 3.0]))
    scene = scenes.free_rotation(body, omega0=(0.05, 2.0, 0.05), t_end=4.0)
    run = _run(scene, method="rk4")
    pose = scene.body_poses(run)["body"]
    np.testing.assert_allclose(pose.com, np.broadcast_to([0.1, -0.2, 0.3], pose.com.shape), rtol=0, atol=1e-12)
    same = np.abs(np.sum(pose.quat * run["quaternion"], axis=1))
    np.testing.assert_allclose(same, 1.0, rtol=0, atol=1e-12)


def test_runs_of_another_scene_or_of_a_batch_are_refused():
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
    race = scenes.rolling_race(("disc", "hollow_cylinder"), radius=0.1, incline=0.3, length=0.5)
    race_run = _run(race, method="rk4")
    with pytest.raises(ValueError, match="run of scene 'rolling_race'"):
        rod.body_poses(race_run)
    bigger = scenes.rolling_race(("disc", "hollow_cylinder", "solid_sphere"), radius=0.1, incline=0.3, length=0.5)
    with pytest.raises(ValueError, match=r"shape \(\d+, 2\), expected \(\d+, 3\)"):
        bigger.body_poses(race_run)
    anonymous = Trajectory(race_run.t, {"theta": race_run["distance"]})  # no meta: the shape tells
    with pytest.raises(ValueError, match="is the trajectory a run of another scene"):
        rod.body_poses(anonymous)
    with pytest.raises(ValueError, match="has no observable 'theta'"):
        rod.body_poses(Trajectory(race_run.t, {"distance": race_run["distance"][:, 0]}))
    rods = scenes.swinging_rod(1.0, theta0=np.array([0.5, 1.0]), t_end=1.0)
    with pytest.raises(ValueError, match="is a batch"):
        rods.body_poses(_run(rods))
    particles = scenes.particles(3, seed=1, t_end=0.1)
    with pytest.raises(ValueError, match="no bodies to place"):
        particles.body_poses(_run(particles, method="rk4"))
    blown = Trajectory(race_run.t, {**{n: race_run[n] for n in race_run.observables},
                                    "distance": np.where(race_run.t[:, None] > 0.2, np.nan, race_run["distance"])})
    with pytest.raises(ValueError, match="not finite from t = 0.2"):
        race.body_poses(blown)


def test_a_family_without_its_inverse_of_observe_says_so():
    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Still(Scene):
        def _layout(self):
            return Layout(bodies=(Body("b", Inertia.solid_sphere(1.0, 0.1)),), joints=(Joint("x", "slide", "b"),))

    scene = Still(name="still", t_end=1.0)
    with pytest.raises(NotImplementedError, match="does not place its bodies"):
        scene.body_poses(Trajectory(np.zeros(1), {}))
