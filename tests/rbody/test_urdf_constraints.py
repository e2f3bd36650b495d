"""rbody.from_urdf hands the file's <limit lower upper>, <dynamics friction> and <mimic> to the constraint layer
(constraints=True, the default): a rod falling onto its stop meets the closed form and never passes it beyond
round-off, a joint whose friction exceeds gravity's torque does not move, a mimic follower stays at multiplier *
leader + offset to round-off. constraints=False records them only (the bare tree, as Pinocchio's aba runs the file).
MuJoCo's URDF loader applies the same three softly: how far its runs of the same files stray is measured and
recorded as findings. Every URDF here is written for these tests."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ellipk, ellipkinc

import rbody
from rbody.urdf import URDFError, from_urdf

G = 9.81
MGL = 1.0 * G * 0.5          # the rod: 1 kg, 1 m, hinged at its end; m g (L/2) [N m]
THETA0, STOP = 1.0, 0.5
W0 = math.sqrt(3 * G / 2)    # I = m L^2 / 3 about the end: w0^2 = m g (L/2) / I
K2 = math.sin(THETA0 / 2) ** 2
# released from rest at THETA0, the rod reaches -STOP at t = (K(k^2) - F(phi, k^2)) / w0, sin(theta/2) = k sin(phi)
IMPACT_TIME = (ellipk(K2) - ellipkinc(math.asin(math.sin(-STOP / 2) / math.sin(THETA0 / 2)), K2)) / W0


def rod_link(name: str) -> str:
    moment = 1.0 / 12
    return (f'<link name="{name}"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/><inertia ixx="{moment!r}" '
            f'iyy="{moment!r}" izz="{1e-6 * moment!r}" ixy="0" ixz="0" iyz="0"/></inertial></link>')


def rod_urdf(limit: str = "", dynamics: str = "", kind: str = "revolute") -> str:
    return (f'<robot name="rod"><link name="world"/>{rod_link("rod")}<joint name="hinge" type="{kind}">'
            f'<parent link="world"/><child link="rod"/><axis xyz="0 1 0"/>{limit}{dynamics}</joint></robot>')


def twin_urdf(multiplier: float, offset: float, follower: str = "revolute") -> str:
    """Two rods on parallel hinges 1 m apart; the second mimics the first."""
    return (f'<robot name="twin"><link name="world"/>{rod_link("a")}{rod_link("b")}'
            '<joint name="ja" type="continuous"><parent link="world"/><child link="a"/><axis xyz="0 1 0"/></joint>'
            f'<joint name="jb" type="{follower}"><parent link="world"/><child link="b"/><origin xyz="1 0 0"/>'
            '<axis xyz="0 1 0"/><limit lower="-10" upper="10" effort="1" velocity="1"/>'
            f'<mimic joint="ja" multiplier="{multiplier!r}" offset="{offset!r}"/></joint></robot>')


def write(tmp_path, text: str, name: str = "robot.urdf") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


LIMIT = f'<limit lower="{-STOP}" upper="2" effort="1" velocity="10"/>'


# ----- limits ---------------------------------------------------------------------------------------------

def test_a_rod_falling_onto_its_urdf_limit_stops_there():
    """Released at 1 rad, the rod hits its stop at -0.5 rad at the closed-form time (incomplete elliptic
    integral), plastically (URDF has no restitution: e = 0), never passes it beyond round-off, and then swings
    between -0.5 and 0.5 rad for ever."""
    scene = from_urdf(rod_urdf(LIMIT), qpos0=[THETA0], t_end=3.0)
    assert scene.tree.joints[0].range == (-STOP, 2.0) and scene.limits == {"hinge": (-STOP, 2.0)}
    run = rbody.simulate(scene, dt=1e-3)
    impacts = run.events["time"][run.events["what"] == "impact"]
    assert impacts[0] == pytest.approx(IMPACT_TIME, abs=1e-11)
    assert run.events["energy_lost"][0] == pytest.approx(MGL * (math.cos(STOP) - math.cos(THETA0)), abs=1e-10)
    theta = run["qpos"][:, 0]
    assert theta.min() >= -STOP - 1e-15
    after = run.t > IMPACT_TIME + 0.05
    assert theta[after].max() <= STOP + 1e-12 and theta[after].max() == pytest.approx(STOP, abs=1e-6)
    assert np.ptp(run["energy"] + run["dissipated"]) < 1e-11


def test_a_limit_with_lower_equal_upper_is_no_range(tmp_path):
    scene = from_urdf(rod_urdf('<limit lower="0.3" upper="0.3" effort="1" velocity="1"/>'))
    assert scene.tree.joints[0].range is None and not scene.tree.constrained
    assert any("is no range" in note and "ignores it too" in note for note in scene.import_notes)


# ----- dry friction ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("theta0", [0.3, -0.2])
def test_friction_above_gravitys_torque_holds_the_joint_still(theta0):
    """m g (L/2) sin(theta0) < friction: the joint sticks from the start, to the last bit, for the whole run."""
    friction = 1.02 * MGL * abs(math.sin(theta0))
    scene = from_urdf(rod_urdf(dynamics=f'<dynamics friction="{friction!r}"/>'), qpos0=[theta0], t_end=2.0)
    assert scene.tree.joints[0].frictionloss == friction and scene.joint_friction == {"hinge": friction}
    run = rbody.simulate(scene, dt=1e-3)
    assert run.meta["events"] == 0 and np.all(run["qpos"][:, 0] == theta0) and np.all(run["sticking"])
    np.testing.assert_allclose(run["constraint_force"][:, 0], MGL * math.sin(theta0), rtol=1e-12)


def test_friction_below_gravitys_torque_lets_it_swing_and_stop_by_the_energy_balance():
    """Just below the holding friction the rod slips at once; friction takes exactly what it dissipates (energy +
    dissipated constant) and the rod stops where gravity's torque no longer exceeds the friction."""
    theta0 = 0.3
    friction = 0.5 * MGL * math.sin(theta0)
    scene = from_urdf(rod_urdf(dynamics=f'<dynamics friction="{friction!r}"/>'), qpos0=[theta0], t_end=4.0)
    run = rbody.simulate(scene, dt=1e-3)
    assert run.events["what"][-1] == "stick" and run["qpos"][0, 0] != run["qpos"][-1, 0]
    assert MGL * abs(math.sin(run["qpos"][-1, 0])) <= friction
    assert np.ptp(run["energy"] + run["dissipated"]) < 1e-10


# ----- mimic ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("multiplier, offset, follower", [(2.0, 0.1, "revolute"), (-0.7, -0.2, "revolute"),
                                                          (0.5, 0.05, "prismatic")])
def test_a_mimic_follower_stays_at_multiplier_times_leader_plus_offset(multiplier, offset, follower):
    scene = from_urdf(twin_urdf(multiplier, offset, follower), qpos0=[1.2, offset + multiplier * 1.2], t_end=2.0)
    (tie,) = scene.tree.equalities
    assert (tie.kind, tie.joint1, tie.joint2, tie.polycoef) == ("joint", "jb", "ja", (offset, multiplier, 0, 0, 0))
    run = rbody.simulate(scene, dt=1e-3)
    qa, qb = run["qpos"][:, 0], run["qpos"][:, 1]
    assert np.ptp(qa) > 1.0  # it swings
    assert np.max(np.abs(qb - (multiplier * qa + offset))) < 1e-12
    assert np.ptp(run["energy"] + run["dissipated"]) < 1e-9


def test_the_default_initial_state_puts_a_follower_where_its_mimic_does():
    assert from_urdf(twin_urdf(2.0, 0.1)).qpos0.tolist() == [0.0, 0.1]
    off = from_urdf(twin_urdf(2.0, 0.1), qpos0=[1.0, 0.0], t_end=0.1)
    run = rbody.simulate(off, dt=1e-3)
    assert run.events["what"][0] == "start"  # projected onto the mimic at once
    assert np.max(np.abs(run["qpos"][1:, 1] - (2 * run["qpos"][1:, 0] + 0.1))) < 1e-12


def test_a_mimic_of_a_planar_joint_is_refused_with_its_line():
    text = twin_urdf(1.0, 0.0).replace('type="continuous"', 'type="planar"').replace(
        '<axis xyz="0 1 0"/></joint>', '<axis xyz="0 0 1"/></joint>', 1)
    with pytest.raises(URDFError, match=r"<mimic>: joint 'ja' is planar: a mimic ties revolute"):
        from_urdf(text)
    assert from_urdf(text, constraints=False).mimics == {"jb": ("ja", 1.0, 0.0)}  # recorded only


def test_negative_friction_is_refused():
    with pytest.raises(URDFError, match=r"<dynamics>: friction=-0.1: a dry friction force must be >= 0"):
        from_urdf(rod_urdf(dynamics='<dynamics friction="-0.1"/>'))


# ----- Bullet's loadURDF of the same files (validation.backends.bullet) ------------------------------------

def test_bullet_holds_the_same_three_from_the_file(tmp_path):
    """Bullet keeps loadURDF's limit (an ERP-corrected constraint: the rod passes its stop by 3.0e-3 rad at
    dt = 1 ms, a finding), holds dry friction by a velocity motor (the held rod does not move at all) and a mimic by
    a gear constraint (to round-off); with constraints=False its limit is removed, as rbody's is."""
    pytest.importorskip("pybullet")
    from validation.backends import get

    bullet = get("bullet")
    path = write(tmp_path, rod_urdf(LIMIT))
    held = bullet.run(from_urdf(path, qpos0=[THETA0], t_end=3.0), 1e-3)["qpos"][:, 0]
    assert 1e-3 < -STOP - held.min() < 1e-2  # measured 3.0e-3 rad past the stop
    free = bullet.run(from_urdf(path, qpos0=[THETA0], t_end=3.0, constraints=False), 1e-3)["qpos"][:, 0]
    assert free.min() == pytest.approx(-THETA0, abs=1e-2)  # swings through to -1 rad
    friction = 1.02 * MGL * math.sin(0.3)
    path = write(tmp_path, rod_urdf(dynamics=f'<dynamics friction="{friction!r}"/>', kind="continuous"), "f.urdf")
    assert np.all(bullet.run(from_urdf(path, qpos0=[0.3], t_end=1.0), 1e-3)["qpos"][:, 0] == 0.3)
    path = write(tmp_path, twin_urdf(-0.7, -0.2), "twin.urdf")
    qpos = bullet.run(from_urdf(path, qpos0=[1.2, -0.2 - 0.7 * 1.2], t_end=2.0), 1e-3)["qpos"]
    assert np.ptp(qpos[:, 0]) > 1.0 and np.max(np.abs(qpos[:, 1] - (-0.7 * qpos[:, 0] - 0.2))) < 1e-12


# ----- constraints=False: the bare tree, as Pinocchio's aba runs the file --------------------------------

def test_constraints_false_records_them_and_runs_the_bare_tree():
    text = twin_urdf(2.0, 0.1).replace('<axis xyz="0 1 0"/></joint>',
                                       f'<axis xyz="0 1 0"/>{LIMIT}<dynamics friction="0.2"/></joint>', 1)
    text = text.replace('type="continuous"', 'type="revolute"')
    applied, bare = from_urdf(text), from_urdf(text, constraints=False)
    assert applied.constraints and applied.tree.constrained and not bare.constraints
    assert [(j.range, j.frictionloss) for j in applied.tree.joints] == [((-STOP, 2.0), 0.2), ((-10.0, 10.0), 0.0)]
    assert [(j.range, j.frictionloss) for j in bare.tree.joints] == [(None, 0.0), (None, 0.0)]
    assert not bare.tree.equalities and not bare.tree.constrained
    for scene in (applied, bare):  # recorded either way
        assert scene.limits == {"ja": (-STOP, 2.0), "jb": (-10.0, 10.0)} and scene.joint_friction == {"ja": 0.2}
        assert scene.mimics == {"jb": ("ja", 2.0, 0.1)}
    assert sum("NOT applied" in n for n in bare.import_notes) == 2 and "independent joint" in " ".join(bare.import_notes)
    assert not any("NOT applied" in n for n in applied.import_notes)
    assert bare.qpos0.tolist() == [0.0, 0.0]
    with pytest.raises(URDFError, match="constraints"):
        from_urdf(text, constraints="no")


# ----- MuJoCo's URDF loader: the same three, soft ----------------------------------------------------------

mujoco = pytest.importorskip("mujoco")


def mujoco_run(path: str, qpos0, t_end: float, dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's loader's model of `path`, RK4 at dt, its default softness: (t (T,), qpos (T, nq))."""
    model = mujoco.MjModel.from_xml_path(path)
    model.opt.timestep, model.opt.integrator = dt, mujoco.mjtIntegrator.mjINT_RK4
    data = mujoco.MjData(model)
    data.qpos[:] = qpos0
    mujoco.mj_forward(model, data)
    steps = int(round(t_end / dt))
    qpos = np.empty((steps + 1, model.nq))
    qpos[0] = data.qpos
    for k in range(1, steps + 1):
        mujoco.mj_step(model, data)
        qpos[k] = data.qpos
    return np.arange(steps + 1) * dt, qpos


def test_mujocos_loader_reads_the_same_three_and_holds_them_softly(tmp_path):
    """Findings (MuJoCo 4.0.0, RK4, dt = 1 ms, its default solref/solimp): the rod passes its stop by 0.024 rad
    (rbody: 0), the friction-held rod creeps 9.0e-3 rad in 2 s (rbody: still to the last bit), the mimic follower
    strays from multiplier * leader + offset by 2.9e-4 rad (rbody: below 1e-12). MuJoCo's loader makes the same constraints: a range,
    frictionloss, and a joint equality with polycoef (offset, multiplier)."""
    path = write(tmp_path, rod_urdf(LIMIT))
    model = mujoco.MjModel.from_xml_path(path)
    assert model.jnt_range[0].tolist() == [-STOP, 2.0] and bool(model.jnt_limited[0])
    _, qpos = mujoco_run(path, [THETA0], 3.0)
    past = -STOP - qpos[:, 0].min()
    assert past > 1e-2  # measured 0.024 rad past the stop

    friction = 1.02 * MGL * math.sin(0.3)
    path = write(tmp_path, rod_urdf(dynamics=f'<dynamics friction="{friction!r}"/>'), "friction.urdf")
    assert mujoco.MjModel.from_xml_path(path).dof_frictionloss[0] == pytest.approx(friction)
    _, qpos = mujoco_run(path, [0.3], 2.0)
    creep = abs(qpos[-1, 0] - 0.3)
    assert creep > 1e-3  # measured 9.0e-3 rad

    path = write(tmp_path, twin_urdf(2.0, 0.1), "twin.urdf")
    model = mujoco.MjModel.from_xml_path(path)
    assert model.neq == 1 and model.eq_data[0, :2].tolist() == [0.1, 2.0]
    _, qpos = mujoco_run(path, [1.2, 2.5], 2.0)
    stray = np.max(np.abs(qpos[:, 1] - (2 * qpos[:, 0] + 0.1)))
    assert stray > 1e-4  # measured 2.9e-4 rad
    print(f"MuJoCo {mujoco.__version__}: past the stop {past:.3g} rad, creep {creep:.3g} rad, mimic {stray:.3g} rad")


def test_a_mimic_of_a_missing_joint_is_refused_with_its_line():
    """Found in a published robot (a hand whose mimics name 'index_q1' where the joint is 'Left_index_q1')."""
    text = twin_urdf(1.0, 0.0).replace('<mimic joint="ja"', '<mimic joint="nope"')
    with pytest.raises(URDFError, match=r"line 1, <mimic>: joint 'jb' mimics joint 'nope', which is not a joint"):
        from_urdf(text)
    assert from_urdf(text, constraints=False).mimics == {"jb": ("nope", 1.0, 0.0)}


def test_two_fingers_on_their_stops_tied_by_a_mimic_run():
    """A gripper as published robots write it (Panda, PR2, Baxter, TALOS): two fingers, each with a stop at 0, the
    second mimicking the first, both on their stops with gravity pressing the first onto its stop and the second
    away from it. The stops and the mimic are redundant: one force holds both. rbody holds the first stop, leaves
    the second (no force: the mimic keeps it there) and runs; both stay at their stops to round-off. (Before: the
    minimum-norm split of the redundant set pulled on the second stop, and the run was refused at t = 0.)"""
    finger = ('<link name="{0}"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" '
              'ixz="0" iyz="0"/></inertial></link>')
    text = ('<robot name="gripper"><link name="world"/>' + finger.format("hand") + finger.format("a")
            + finger.format("b") +
            '<joint name="tilt" type="fixed"><parent link="world"/><child link="hand"/><origin rpy="1.0 0 0"/></joint>'
            '<joint name="j1" type="prismatic"><parent link="hand"/><child link="a"/><axis xyz="0 1 0"/>'
            '<limit lower="0" upper="0.04" effort="1" velocity="1"/></joint>'
            '<joint name="j2" type="prismatic"><parent link="hand"/><child link="b"/><axis xyz="0 -1 0"/>'
            '<limit lower="0" upper="0.04" effort="1" velocity="1"/><mimic joint="j1"/></joint></robot>')
    run = rbody.simulate(from_urdf(text, t_end=0.5), dt=1e-3)
    assert np.max(np.abs(run["qpos"])) < 1e-15
    assert np.all(run["active_limits"].sum(axis=1) >= 1)  # the first finger's stop holds


def test_early_urdfs_joint_properties_are_ignored_as_pinocchio_ignores_them():
    """<joint_properties damping friction> (early URDF, in pybullet's quadrupeds): urdfdom, Pinocchio and Bullet
    ignore it; rbody too, with a note, naming non-zero values as not applied."""
    text = rod_urdf(dynamics='<joint_properties damping="0.0" friction="0.0"/>', kind="continuous")
    scene = from_urdf(text)
    assert scene.tree.joints[0].damping == 0 and any("<joint_properties> ignored" in n for n in scene.import_notes)
    loud = from_urdf(rod_urdf(dynamics='<joint_properties damping="0.5"/>', kind="continuous"))
    assert loud.tree.joints[0].damping == 0 and any("NOT applied" in n for n in loud.import_notes)
