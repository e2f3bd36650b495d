"""The peers of issue 25: Pinocchio (the same dynamics through the reference implementation, the same rk4) and
Bullet (PyBullet DIRECT, semi-implicit Euler, rigid LCP contact), each against the chapter's closed forms and
rbody, and `python -m validation compare robot.urdf` with every engine. URDFs written here."""

from __future__ import annotations

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import rbody  # noqa: E402
from rbody import scenes  # noqa: E402
from validation.backends import ENGINES, get, supports  # noqa: E402
from validation.backends import pinocchio as pin_backend  # noqa: E402

ARM = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"><inertial><mass value="2"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="upper"><inertial><origin xyz="0 0 -0.2" rpy="0.1 0.2 0"/><mass value="1"/>
    <inertia ixx="0.02" iyy="0.021" izz="0.004" ixy="0.001" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.2"/><geometry><cylinder radius="0.03" length="0.4"/></geometry></collision></link>
  <link name="lower"><inertial><origin xyz="0.01 0 -0.15" rpy="0 0 0.3"/><mass value="0.8"/>
    <inertia ixx="0.01" iyy="0.011" izz="0.001" ixy="0" ixz="0.0005" iyz="0"/></inertial></link>
  <link name="tool"><inertial><origin xyz="0 0 -0.03"/><mass value="0.2"/>
    <inertia ixx="0.0001" iyy="0.0001" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="slider"><inertial><mass value="0.3"/><inertia ixx="0.001" iyy="0.002" izz="0.003" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 1" rpy="0.1 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="20" velocity="10"/><dynamics damping="0.05"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/><origin xyz="0 0 -0.4" rpy="0 0 0.2"/>
    <axis xyz="0.2 1 0"/></joint>
  <joint name="wrist" type="fixed"><parent link="lower"/><child link="tool"/><origin xyz="0 0 -0.3"/></joint>
  <joint name="rail" type="prismatic"><parent link="lower"/><child link="slider"/><origin xyz="0 0 -0.1" rpy="0 1.57 0"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
</robot>
"""


@pytest.fixture
def arm(tmp_path) -> str:
    path = tmp_path / "arm.urdf"
    path.write_text(ARM)
    return str(path)


# ----- Pinocchio --------------------------------------------------------------------------------------------

def test_pinocchio_runs_the_swinging_rod_as_rbody_does():
    """Hinges alone: the same classical rk4 on the same equations, so rbody and Pinocchio agree to round-off, and
    both follow the closed form to rk4's error."""
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=2.0)
    run = pin_backend.run(rod, 1e-3)
    ours = rbody.simulate(rod, dt=1e-3, method="rk4")
    assert np.max(np.abs(run["theta"] - ours["theta"])) < 1e-13
    assert np.max(np.abs(run["theta"] - rod.exact(run.t)["theta"])) < 1e-9
    assert run.meta["model_origin"] == "layout"
    assert max(run.meta["dynamics"][k] for k in ("mass_matrix_relative", "bias_relative", "qacc_relative")) < 1e-12


def test_pinocchio_free_rotation_follows_the_closed_form():
    """A free body through JointModelFreeFlyer (body-frame velocities mapped to rbody's world ones)."""
    body = rbody.Inertia(2.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]))
    scene = scenes.free_rotation(body, omega0=(0.05, 2.0, 0.05), t_end=2.0)
    run = pin_backend.run(scene, 1e-3)
    exact = scene.exact(run.t)
    assert np.max(np.abs(run["omega_body"] - exact["omega_body"])) < 1e-9
    assert run.meta["dynamics"]["qacc_relative"] < 1e-12


def test_pinocchio_runs_the_users_urdf_file(arm):
    """The same file through Pinocchio's own parser: qpos, qvel and every body's state equal rbody's run to rk4's
    truncation error (the continuous elbow is integrated in Pinocchio's (cos, sin) embedding, rbody's as an angle:
    both fourth order, measured 3.6e-11 apart after 0.5 s at dt = 1e-3)."""
    scene = rbody.from_urdf(arm, t_end=0.5, qvel0=[1.0, -2.0, 0.5], constraints=False)  # the bare tree, as aba
    run = pin_backend.run(scene, 1e-3)
    ours = rbody.simulate(scene, dt=1e-3, method="rk4")
    assert run.meta["model_origin"] == "file"
    for name in ("qpos", "qvel", "energy", "lower.com", "slider.velocity", "upper.omega"):
        assert np.max(np.abs(run[name] - ours[name])) < 1e-9, name
    quat = np.abs(np.sum(run["lower.quat"] * ours["lower.quat"], axis=1))
    assert np.min(quat) > 1 - 1e-13


def test_pinocchio_floating_base_agrees_at_truncation_level(arm):
    """A floating base: rbody's Runge-Kutta-Munthe-Kaas and the embedded rk4 here are both fourth order; they
    agree to the truncation error."""
    scene = rbody.from_urdf(arm, floating_base=True, t_end=0.5, constraints=False,
                            qvel0=[0.1, 0.0, 0.2, 0.5, -1.0, 2.0, 1.0, -1.0, 0.3])
    run = pin_backend.run(scene, 1e-3)
    ours = rbody.simulate(scene, dt=1e-3, method="rk4")
    assert np.max(np.abs(run["qpos"] - ours["qpos"])) < 1e-10
    assert np.max(np.abs(run["energy"] - ours["energy"])) < 1e-9  # the shoulder's damping dissipates in both


@pytest.mark.parametrize("scene, reason", [
    (scenes.rolling("disc", radius=0.1, incline=0.5, friction=1.0, t_end=0.5), "contact"),
    (scenes.rocket(100.0, burn_rate=10.0, exhaust_speed=50.0, dry_mass=40.0, drag=2.0, t_end=1.0), "body_mass"),
])
def test_pinocchio_refuses_what_it_cannot_run(scene, reason):
    ok, why = supports(scene, "pinocchio")
    assert not ok and reason in why


def test_pinocchio_refuses_a_urdf_read_with_its_limits_and_says_how_to_compare(arm):
    """aba has no joint limits: a URDF read with its constraints (the default) is refused, with the way to run the
    bare tree; its dynamics are still compared (build)."""
    ok, why = supports(rbody.from_urdf(arm), "pinocchio")
    assert not ok and "constraints=False" in why and "--no-constraints" in why
    assert supports(rbody.from_urdf(arm, constraints=False), "pinocchio") == (True, "")
    with pytest.raises(NotImplementedError, match="aba has none of them"):
        pin_backend.run(rbody.from_urdf(arm, t_end=0.01), 1e-3)


# ----- Bullet -----------------------------------------------------------------------------------------------

bullet_needed = pytest.mark.skipif(not supports(scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0), "bullet")[0],
                                   reason="pybullet is not installed (pip install 'rbody[bullet]')")


@bullet_needed
def test_bullet_pendulum_is_first_order():
    """Semi-implicit Euler: the rod's phase error halves when dt halves (its only integrator)."""
    bullet = get("bullet")
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=2.0)
    errors = []
    for dt in (1e-3, 5e-4):
        run = bullet.run(rod, dt)
        errors.append(float(np.max(np.abs(run["theta"] - rod.exact(run.t)["theta"]))))
    assert 1e-4 < errors[0] < 5e-3          # measured 1.8e-3 rad at dt = 1e-3 over 2 s
    assert 1.7 < errors[0] / errors[1] < 2.3


@bullet_needed
def test_bullet_default_damping_is_undone():
    """Bullet damps every body by 0.04 by default; with it undone the rod's energy stays within the integrator's
    O(dt) oscillation instead of decaying."""
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=5.0)
    run = get("bullet").run(rod, 1e-3)
    energy = run["energy"]
    assert np.max(np.abs(energy - energy[0])) < 5e-3 * abs(energy[0])
    assert abs(energy[-1] - energy[0]) < 5e-3 * abs(energy[0])


@bullet_needed
def test_bullet_rolling_and_elastic_balls():
    """Rolling on an incline (rigid contact, friction 1) and a head-on elastic impact of two equal balls."""
    bullet = get("bullet")
    disc = scenes.rolling("disc", radius=0.1, incline=0.5, friction=1.0, t_end=1.0)
    run = bullet.run(disc, 1e-3)
    assert np.max(np.abs(run["distance"] - disc.exact(run.t)["distance"])) < 2e-3  # measured 7.9e-4 m
    pair = scenes.line_collisions((1.0, 1.0), (0.0, 0.5), (1.0, 0.0), radii=0.1, walls=(), t_end=0.6)
    run = bullet.run(pair, 1e-3)
    assert int(run["collisions"][-1]) == 1
    np.testing.assert_allclose(run["velocities"][-1], [0.0, 1.0], rtol=0, atol=1e-2)  # measured (0.005, 0.995)


@bullet_needed
def test_bullet_loses_the_bounce_off_a_static_wall():
    """Finding (pybullet 3.2.7): a sphere meeting a static box or plane with restitution 1 (and the velocity
    threshold lowered) stops dead instead of bouncing; sphere against sphere bounces. The pi scene's ball meets its
    wall and stays there: Bullet misses the count."""
    scene = scenes.pi_collisions(0, speed=1.0, spacing=0.3, radius=0.05)
    run = get("bullet").run(scene, 1e-3)
    assert int(run["collisions"][-1]) < scene.expected_collisions
    assert abs(run["velocities"][-1][0]) < 0.1  # the light ball, stopped at the wall (exactly: 1 m/s away)


@bullet_needed
def test_bullet_runs_the_users_urdf_file(tmp_path):
    """loadURDF of the same file (its elbow axis written unit): within Bullet's first-order error of rbody's run,
    halving with dt."""
    path = tmp_path / "unit_axes.urdf"
    path.write_text(ARM.replace('xyz="0.2 1 0"', 'xyz="0.19611613513818404 0.9805806756909202 0"'))
    scene = rbody.from_urdf(str(path), t_end=0.5, qvel0=[1.0, -2.0, 0.5])
    ours = rbody.simulate(scene, dt=1e-4, method="rk4")
    errors = []
    for dt in (1e-3, 5e-4):
        run = get("bullet").run(scene, dt)
        assert run.meta["settings"]["model"] == "file"
        errors.append(float(np.max(np.abs(run["qpos"] - ours["qpos"][::int(round(dt / 1e-4))]))))
    assert errors[0] < 1e-2 and 1.6 < errors[0] / errors[1] < 2.4
    assert np.max(np.abs(run["lower.com"] - ours["lower.com"][::5])) < 1e-2  # lower + tool, merged as rbody does
    assert run.meta["notes"] == []


@bullet_needed
def test_bullet_steps_a_non_unit_urdf_axis_as_written(arm):
    """Finding (pybullet 3.2.7): the elbow's axis (0.2, 1, 0) is not unit; Bullet's mass matrix normalises it but its
    stepping does not, so the run keeps an offset of ~7.7e-3 rad from the model's motion whatever dt; named in
    meta["notes"]."""
    scene = rbody.from_urdf(arm, t_end=0.5, qvel0=[1.0, -2.0, 0.5])
    ours = rbody.simulate(scene, dt=1e-4, method="rk4")
    errors = []
    for dt in (1e-3, 5e-4):
        run = get("bullet").run(scene, dt)
        errors.append(float(np.max(np.abs(run["qpos"] - ours["qpos"][::int(round(dt / 1e-4))]))))
    assert errors[1] > 0.9 * errors[0] > 4e-3  # no convergence: a model difference, not the integrator's
    assert any("'elbow'" in note and "axis" in note for note in run.meta["notes"])


# ----- compare on a URDF ------------------------------------------------------------------------------------

def test_compare_a_urdf_with_every_engine(arm, tmp_path):
    from validation.__main__ import main
    from validation.comparison import compare

    from validation.comparison import load_model

    held = compare(arm, t_end=0.3)  # the file's limits held: rbody rigidly, MuJoCo softly, Bullet by its own
    assert held.runs["pinocchio"].status == "refused" and "--no-constraints" in held.runs["pinocchio"].note
    assert held.row("qpos", "rbody", "mujoco").largest < 1e-12  # no stop reached in 0.3 s: the same rk4
    c = compare(load_model(arm, t_end=0.3, constraints=False))
    assert tuple(c.runs) == ENGINES
    assert c.runs["pinocchio"].status == "ran" and c.runs["mujoco"].status == "ran"
    assert c.runs["pymunk"].status == "refused"
    assert c.row("qpos", "rbody", "pinocchio").largest < 1e-12
    assert c.row("qpos", "rbody", "mujoco").largest < 1e-12
    if c.runs["bullet"].status == "ran":
        assert c.row("qpos", "rbody", "bullet").largest < 1e-2
    assert main(["compare", arm, "--t-end", "0.2", "--engines", "rbody,pinocchio", "--no-constraints", "--out",
                 str(tmp_path / "o")]) == 0
    assert (tmp_path / "o" / "arm.md").exists()


# ----- the main command ---------------------------------------------------------------------------------------

def test_the_main_command_runs_the_peers_where_they_can_express_a_scene():
    """Pinocchio runs the contact-free trees (same rk4 as rbody: the same error to round-off), Bullet the trees and
    the contacts (first order); a scene a peer cannot express, or one the main command skips, is a refused row with
    the reason."""
    from dataclasses import replace

    from validation.cases import default_cases
    from validation.evaluate import evaluate

    cases = {c.name: c for c in default_cases(quick=True)}
    rows, _ = evaluate(cases["swinging_rod"], ("rbody", "pinocchio"))
    value = {(r.backend, r.metric): r for r in rows}
    ours, theirs = value["rbody", "max_abs_error"], value["pinocchio", "max_abs_error"]
    assert theirs.verdict == "ok" and theirs.value == pytest.approx(ours.value, rel=1e-3)
    rows, _ = evaluate(cases["rolling_disc"], ("pinocchio",))
    assert rows[0].verdict == "refused" and "contact" in rows[0].note
    skipped = replace(cases["pi_collisions_0"], skipped={"bullet": "not run here: the reason"})
    rows, _ = evaluate(skipped, ("bullet",))
    assert [(r.verdict, r.note) for r in rows] == [("refused", "not run here: the reason")]
