"""rbody.urdf: URDF robots read by rbody have the masses, mass matrix, bias forces and forward dynamics of
Pinocchio's own parse of the same file (pin.buildModelFromUrdf) to 1e-12, and of MuJoCo's URDF loader where it
loads the file; closed forms through URDF (the swinging rod, the double pendulum's energy); bad URDF refused with
the file, the line and the element. Every URDF here is written for these tests."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
mujoco = pytest.importorskip("mujoco")

import rbody  # noqa: E402
from rbody import scenes  # noqa: E402
from rbody.urdf import URDFError, from_urdf, layout_from_urdf  # noqa: E402
from validation.backends import pinocchio as pin_backend  # noqa: E402

RTOL = 1e-12


def inertial(mass, xyz="0 0 0", rpy="0 0 0", moments=(0.01, 0.01, 0.01, 0, 0, 0)) -> str:
    ixx, iyy, izz, ixy, ixz, iyz = moments
    return (f'<inertial><origin xyz="{xyz}" rpy="{rpy}"/><mass value="{mass}"/><inertia ixx="{ixx}" iyy="{iyy}" '
            f'izz="{izz}" ixy="{ixy}" ixz="{ixz}" iyz="{iyz}"/></inertial>')


# Every joint kind, rpy origins everywhere, a fixed link merged, a continuous joint, damping, limits, a mimic, and
# a massless link on a moving joint folded into its only moving child; off-diagonal inertias in rotated frames.
EVERY_JOINT = f"""<?xml version="1.0"?>
<robot name="every_joint">
  <link name="base">{inertial(3.0, "0.01 0.02 -0.03", "0.3 -0.2 0.1", (0.05, 0.06, 0.07, 0.001, -0.002, 0.003))}
    <collision><origin xyz="0 0 0.1" rpy="0 0.2 0"/><geometry><box size="0.2 0.3 0.4"/></geometry></collision></link>
  <link name="sensor">{inertial(0.4, "0.05 0 0", "0.5 0.5 0.5", (0.002, 0.003, 0.004, 0.0001, 0, 0))}</link>
  <link name="upper">{inertial(2.0, "0 0.01 -0.2", "0.1 0.3 -0.2", (0.03, 0.031, 0.004, 0.001, 0.0005, -0.0007))}
    <collision><origin xyz="0 0 -0.2"/><geometry><cylinder radius="0.04" length="0.4"/></geometry></collision>
    <visual><geometry><sphere radius="0.05"/></geometry><material name="red"/></visual></link>
  <link name="lower">{inertial(1.5, "0.02 0 -0.15", "-0.2 0.1 0.4", (0.02, 0.022, 0.003, 0.0, 0.001, 0.0))}</link>
  <link name="tool">{inertial(0.3, "0 0 -0.05", "0 0 0", (0.001, 0.001, 0.0005, 0, 0, 0))}</link>
  <link name="carriage">{inertial(0.8, "0.03 -0.01 0", "0 0 0.7", (0.004, 0.005, 0.006, 0, 0, 0.0002))}</link>
  <link name="finger_a">{inertial(0.1, "0 0.02 0", "0 0 0", (0.0001, 0.0002, 0.0001, 0, 0, 0))}</link>
  <link name="finger_b">{inertial(0.1, "0 -0.02 0", "0 0 0", (0.0001, 0.0002, 0.0001, 0, 0, 0))}</link>
  <link name="gimbal"/>
  <link name="puck">{inertial(0.7, "0.1 0.05 0", "0 0 0.3", (0.003, 0.004, 0.005, 0.0002, 0, 0))}</link>
  <joint name="mount" type="fixed"><parent link="base"/><child link="sensor"/><origin xyz="0.1 0 0.2" rpy="0.2 0.4 -0.6"/></joint>
  <joint name="shoulder" type="revolute"><parent link="sensor"/><child link="upper"/>
    <origin xyz="0.05 0.1 -0.1" rpy="0.3 -0.2 0.5"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="40" velocity="5"/><dynamics damping="0.2" friction="0.5"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0.02 -0.4" rpy="-0.1 0 0.2"/><axis xyz="0.3 0.9 -0.2"/><dynamics damping="0.05"/></joint>
  <joint name="wrist" type="fixed"><parent link="lower"/><child link="tool"/><origin xyz="0 0 -0.3" rpy="0 0 1.2"/></joint>
  <joint name="rail" type="prismatic"><parent link="base"/><child link="carriage"/>
    <origin xyz="0 -0.2 0" rpy="1.0 0.2 0"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="grip_a" type="prismatic"><parent link="carriage"/><child link="finger_a"/><origin xyz="0 0.05 0"/>
    <axis xyz="0 1 0"/><limit lower="-0.1" upper="0.1" effort="1" velocity="1"/></joint>
  <joint name="grip_b" type="prismatic"><parent link="carriage"/><child link="finger_b"/><origin xyz="0 -0.05 0"/>
    <axis xyz="0 -1 0"/><limit lower="-0.1" upper="0.1" effort="1" velocity="1"/><mimic joint="grip_a" multiplier="1" offset="0"/></joint>
  <joint name="tilt" type="revolute"><parent link="base"/><child link="gimbal"/><origin xyz="0 0.3 0" rpy="0 0.5 0"/>
    <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="slide_plane" type="planar"><parent link="gimbal"/><child link="puck"/><origin xyz="0.1 0 0.05" rpy="0.1 0 0"/>
    <axis xyz="0 0 1"/></joint>
</robot>
"""

NON_PHYSICAL = f"""<robot name="lopsided">
  <link name="base"/>
  <link name="arm">{inertial(2.0, "0.1 0 -0.2", "0.3 0.1 0", (0.01, 0.012, 0.05, 0.001, 0, 0))}</link>
  <link name="hand">{inertial(1.0, "0 0 -0.1", "0 0 0", (0.02, 0.03, 0.01, 0, 0, 0))}</link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-4" upper="4" effort="1" velocity="1"/></joint>
  <joint name="j2" type="continuous"><parent link="arm"/><child link="hand"/><origin xyz="0 0 -0.4" rpy="0.2 0 0"/>
    <axis xyz="1 0 0"/></joint>
</robot>
"""


def write(tmp_path, text: str, name: str = "robot.urdf") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def random_states(scene, count: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    model = scene.multibody
    for _ in range(count):
        q, v = rng.normal(size=model.nq), rng.normal(size=model.nv)
        for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
            if kind == "free":
                q[address + 3:address + 7] /= np.linalg.norm(q[address + 3:address + 7])
        yield q, v


def assert_close(ours, theirs, what: str) -> None:
    scale = max(float(np.max(np.abs(theirs))), 1e-300)
    assert float(np.max(np.abs(ours - theirs))) <= RTOL * scale, (what, float(np.max(np.abs(ours - theirs))), scale)


def assert_pinocchio_dynamics(scene, count: int = 6) -> None:
    """Mass matrix, bias forces and forward dynamics equal Pinocchio's parse of scene.source at random states."""
    model = pin_backend.build(scene)
    assert model.origin == "file"
    for q, v in random_states(scene, count):
        theirs = model.dynamics(q, v)
        assert_close(scene.multibody.mass_matrix(q), theirs["mass_matrix"], "mass matrix")
        assert_close(scene.multibody.bias_forces(q, v), theirs["bias"], "bias forces")
        assert_close(scene.multibody.forward_dynamics(q, v), theirs["qacc"], "forward dynamics")


def mujoco_from_urdf(path: str, floating_base: bool = False):
    """MuJoCo's URDF loader's model of `path`, constraints off (no limit or friction force), with a free joint
    'root_joint' on the root body for a floating base."""
    spec = mujoco.MjSpec.from_file(path)
    if floating_base:
        root = spec.worldbody.first_body()
        root.add_freejoint(name="root_joint")
    model = spec.compile()
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    return model


def mujoco_dynamics(model, q, v):
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q, v
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    return M, data.qfrc_bias.copy(), data.qacc.copy()


# ----- against Pinocchio's parse of the same file ---------------------------------------------------------

@pytest.mark.parametrize("floating_base", [False, True])
def test_every_joint_kind_equals_pinocchio(tmp_path, floating_base):
    scene = from_urdf(write(tmp_path, EVERY_JOINT), floating_base=floating_base)
    names = scene.multibody.joint_names
    expected = ("shoulder", "elbow", "rail", "grip_a", "grip_b", "tilt", "slide_plane_TX", "slide_plane_TY",
                "slide_plane_RZ")
    assert names == (("root_joint",) if floating_base else ()) + expected  # MuJoCo's loader's order: file order
    assert_pinocchio_dynamics(scene)


def test_masses_equal_pinocchio(tmp_path):
    """Each moving body's mass, centre of mass and tensor (merged fixed links included) equal the inertia
    Pinocchio appends to that link's joint, in the joint frame; the massless link holds nothing."""
    path = write(tmp_path, EVERY_JOINT)
    scene = from_urdf(path)
    model = pin.buildModelFromUrdf(path)
    for body in scene.tree.bodies:
        joint = model.frames[model.getFrameId(body.name, pin.BODY)].parentJoint
        theirs = model.inertias[joint]
        assert body.inertia.mass == pytest.approx(theirs.mass, rel=RTOL)
        np.testing.assert_allclose(body.inertia.com, theirs.lever, rtol=0, atol=RTOL)
        np.testing.assert_allclose(body.inertia.tensor, theirs.inertia, rtol=0, atol=RTOL * np.max(theirs.inertia))
    upper = next(b for b in scene.tree.bodies if b.name == "upper")
    assert "tool" not in [b.name for b in scene.tree.bodies] and "gimbal" not in [b.name for b in scene.tree.bodies]
    assert model.inertias[model.getJointId("tilt")].mass == 0  # Pinocchio keeps the massless link on its joint
    lower = next(b for b in scene.tree.bodies if b.name == "lower")
    assert lower.inertia.mass == pytest.approx(1.8)  # lower + tool, merged through the fixed wrist
    assert upper.inertia.mass == 2.0


def test_declared_values_recorded_not_applied_without_constraints(tmp_path):
    scene = from_urdf(write(tmp_path, EVERY_JOINT), constraints=False)
    assert not scene.tree.constrained
    assert scene.limits == {"shoulder": (-3.0, 3.0), "rail": (-1.0, 1.0), "grip_a": (-0.1, 0.1),
                            "grip_b": (-0.1, 0.1), "tilt": (-3.0, 3.0)}
    assert scene.effort_limits["shoulder"] == 40.0 and scene.velocity_limits["shoulder"] == 5.0
    assert scene.joint_friction == {"shoulder": 0.5}
    assert scene.mimics == {"grip_b": ("grip_a", 1.0, 0.0)}
    notes = " ".join(scene.import_notes)
    assert "NOT applied" in notes and "mimics" in notes and "folded into its only moving child 'puck'" in notes
    joints = {j.name: j for j in scene.tree.joints}
    assert joints["shoulder"].damping == 0.2 and joints["elbow"].damping == 0.05
    assert [j.body for j in scene.tree.joints if j.name.startswith(("tilt", "slide_plane"))] == ["puck"] * 4
    assert [s.name for s in scene.visuals["upper"]] == ["upper_visual_0"]
    assert [s.kind for s in scene.tree.fixed] == ["box"]
    applied = from_urdf(write(tmp_path, EVERY_JOINT))  # the default: all three applied (tests/rbody/test_urdf_constraints.py)
    joints = {j.name: j for j in applied.tree.joints}
    assert joints["rail"].range == (-1.0, 1.0) and joints["shoulder"].frictionloss == 0.5
    assert [(e.joint1, e.joint2) for e in applied.tree.equalities] == [("grip_b", "grip_a")]


def test_rpy_is_fixed_axis_roll_pitch_yaw(tmp_path):
    """rpy (r, p, y) turns about the fixed x, then y, then z: R = Rz(y) Ry(p) Rx(r)."""
    text = f"""<robot name="r"><link name="w"/><link name="a">{inertial(1.0)}</link>
      <joint name="j" type="continuous"><parent link="w"/><child link="a"/><origin rpy="0.3 -0.7 1.1"/></joint></robot>"""
    body = layout_from_urdf(text).layout.bodies[0]

    def turn(axis, angle):
        c, s = math.cos(angle), math.sin(angle)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        m = np.eye(3)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m

    expected = turn(2, 1.1) @ turn(1, -0.7) @ turn(0, 0.3)
    np.testing.assert_allclose(rbody.motion.quat_to_matrix(np.array(body.quat)), expected, rtol=0, atol=1e-15)


def test_non_physical_inertia_loaded_as_given_and_named(tmp_path):
    path = write(tmp_path, NON_PHYSICAL)
    scene = from_urdf(path)
    arm = next(b for b in scene.tree.bodies if b.name == "arm")
    moments = np.linalg.eigvalsh(arm.inertia.tensor)
    assert moments[0] + moments[1] < moments[2]  # the file's tensor, not a repaired one
    note = next(n for n in scene.import_notes if "'arm'" in n)
    gap = moments[2] - moments[0] - moments[1]
    assert "triangle inequality" in note and f"{100 * gap / moments[2]:.3g} %" in note
    assert not any("'hand'" in n for n in scene.import_notes)
    assert_pinocchio_dynamics(scene)
    with pytest.raises(ValueError, match="mass matrix|Error"):  # MuJoCo's loader refuses it without balanceinertia
        mujoco.MjModel.from_xml_path(path)


def test_balance_inertia_is_mujocos_rule(tmp_path):
    """balance_inertia=True equals MuJoCo's loader with <compiler balanceinertia="true">: masses, M, bias, qacc."""
    scene = from_urdf(write(tmp_path, NON_PHYSICAL), balance_inertia=True)
    balanced = NON_PHYSICAL.replace('<robot name="lopsided">',
                                    '<robot name="lopsided"><mujoco><compiler balanceinertia="true"/></mujoco>')
    model = mujoco_from_urdf(write(tmp_path, balanced, "balanced.urdf"))
    arm = next(b for b in scene.tree.bodies if b.name == "arm")
    np.testing.assert_allclose(np.linalg.eigvalsh(arm.inertia.tensor), model.body_inertia[model.body("arm").id],
                               rtol=RTOL)
    for q, v in random_states(scene, 4):
        M, bias, qacc = mujoco_dynamics(model, q, v)
        assert_close(scene.multibody.mass_matrix(q), M, "M")
        assert_close(scene.multibody.bias_forces(q, v), bias, "bias")
        assert_close(scene.multibody.forward_dynamics(q, v), qacc, "qacc")


# ----- against MuJoCo's URDF loader ---------------------------------------------------------------------

MUJOCO_LOADS = EVERY_JOINT.replace("<link name=\"gimbal\"/>", f'<link name="gimbal">{inertial(0.2)}</link>').replace(
    ' friction="0.5"', "")


@pytest.mark.parametrize("floating_base", [False, True])
def test_equals_mujocos_loader(tmp_path, floating_base):
    """Where MuJoCo's loader loads the file (no massless moving link, no dry friction): the same joints in the same
    order, the same masses, mass matrix, bias forces and forward dynamics (damping included)."""
    path = write(tmp_path, MUJOCO_LOADS)
    scene = from_urdf(path, floating_base=floating_base)
    model = mujoco_from_urdf(path, floating_base)
    assert tuple(model.joint(i).name for i in range(model.njnt)) == scene.multibody.joint_names
    for body in scene.tree.bodies:
        assert body.inertia.mass == pytest.approx(model.body_mass[model.body(body.name).id], rel=RTOL)
    for q, v in random_states(scene, 4):
        M, bias, qacc = mujoco_dynamics(model, q, v)
        assert_close(scene.multibody.mass_matrix(q), M, "M")
        assert_close(scene.multibody.bias_forces(q, v), bias, "bias")
        assert_close(scene.multibody.forward_dynamics(q, v), qacc, "qacc")
    assert_pinocchio_dynamics(scene, 2)


def test_planar_damping_is_mujocos_and_pinocchio_drops_it(tmp_path):
    """Finding: Pinocchio's parse keeps no damping for a planar joint (model.damping is 0 on its three degrees
    of freedom); MuJoCo's loader puts the joint's damping on its two slides and its hinge, and so does rbody."""
    text = EVERY_JOINT.replace('<axis xyz="0 0 1"/></joint>', '<axis xyz="0 0 1"/><dynamics damping="0.1"/></joint>')
    text = text.replace("<link name=\"gimbal\"/>", f'<link name="gimbal">{inertial(0.2)}</link>')
    path = write(tmp_path, text.replace(' friction="0.5"', ""))
    scene = from_urdf(path)
    assert [j.damping for j in scene.tree.joints if j.name.startswith("slide_plane")] == [0.1] * 3
    assert np.all(pin.buildModelFromUrdf(path).damping[-3:] == 0)
    model = mujoco_from_urdf(path)
    np.testing.assert_array_equal(model.dof_damping[-3:], [0.1] * 3)
    for q, v in random_states(scene, 3):
        assert_close(scene.multibody.forward_dynamics(q, v), mujoco_dynamics(model, q, v)[2], "qacc")


def test_branching_order_is_mujocos_not_pinocchios(tmp_path):
    """A link's children in file order (MuJoCo) where Pinocchio sorts them by joint name; fixed links fused in
    place."""
    text = f"""<robot name="tree"><link name="base"/>
      <link name="z">{inertial(1)}</link><link name="f">{inertial(1)}</link><link name="a">{inertial(1)}</link>
      <link name="c">{inertial(1)}</link>
      <joint name="zz" type="continuous"><parent link="base"/><child link="z"/></joint>
      <joint name="ff" type="fixed"><parent link="z"/><child link="f"/><origin xyz="0 0 -1"/></joint>
      <joint name="cc" type="continuous"><parent link="z"/><child link="c"/><axis xyz="0 1 0"/></joint>
      <joint name="aa" type="continuous"><parent link="f"/><child link="a"/><axis xyz="0 0 1"/></joint></robot>"""
    path = write(tmp_path, text)
    scene = from_urdf(path)
    model = mujoco_from_urdf(path)
    assert scene.multibody.joint_names == ("zz", "aa", "cc")
    assert tuple(model.joint(i).name for i in range(model.njnt)) == scene.multibody.joint_names
    assert tuple(pin.buildModelFromUrdf(path).names)[1:] == ("zz", "cc", "aa")  # Pinocchio: a link's children by name
    assert_pinocchio_dynamics(scene)


def test_to_mjcf_of_a_urdf_scene_compiles_with_the_same_dynamics(tmp_path):
    scene = from_urdf(write(tmp_path, EVERY_JOINT), floating_base=True)
    model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    for q, v in random_states(scene, 3):
        M, bias, _ = mujoco_dynamics(model, q, v)
        assert_close(scene.multibody.mass_matrix(q), M, "M")
        assert_close(scene.multibody.bias_forces(q, v), bias, "bias")


# ----- closed forms through URDF ------------------------------------------------------------------------

def rod_urdf(lengths, masses) -> str:
    links, joints, parent = [], [], "world"
    for i, (length, mass) in enumerate(zip(lengths, masses)):
        moment = mass * length**2 / 12
        links.append(f'<link name="rod{i}">{inertial(mass, f"0 0 {-length / 2!r}", "0 0 0", (moment, moment, 0, 0, 0, 0))}'
                     f'<collision><origin xyz="0 0 {-length / 2!r}"/><geometry><cylinder radius="0.01" '
                     f'length="{length!r}"/></geometry></collision></link>')
        origin = "0 0 0" if i == 0 else f"0 0 {-lengths[i - 1]!r}"
        joints.append(f'<joint name="hinge{i}" type="continuous"><parent link="{parent}"/><child link="rod{i}"/>'
                      f'<origin xyz="{origin}"/><axis xyz="0 1 0"/></joint>')
        parent = f"rod{i}"
    return f'<robot name="rods"><link name="world"/>{"".join(links)}{"".join(joints)}</robot>'


def test_swinging_rod_through_urdf_follows_the_closed_form(tmp_path):
    """A uniform rod hinged at its end, written as URDF: theta(t) and the period are the chapter's exact ones."""
    exact = scenes.swinging_rod(1.2, 3.0, theta0=1.0, t_end=3.0)
    scene = from_urdf(write(tmp_path, rod_urdf([1.2], [3.0])), t_end=3.0, qpos0=[1.0])
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    theta = exact.exact(run.t)["theta"]
    assert np.max(np.abs(run["qpos"][:, 0] - theta)) < 1e-10
    energy = run["energy"]
    assert np.max(np.abs(energy - energy[0])) < 1e-10 * abs(energy[0])
    crossings = np.flatnonzero((run["qvel"][:-1, 0] < 0) & (run["qvel"][1:, 0] >= 0))
    assert crossings.size >= 1
    tail = run["qvel"][crossings[0]:crossings[0] + 2, 0]
    t_cross = run.t[crossings[0]] - tail[0] * (run.t[1] - run.t[0]) / (tail[1] - tail[0])
    assert t_cross == pytest.approx(exact.period / 2, abs=1e-6)  # omega turns upward at half a period


def test_double_pendulum_through_urdf_conserves_energy(tmp_path):
    scene = from_urdf(write(tmp_path, rod_urdf([1.0, 0.7], [1.0, 0.5])), t_end=5.0, qpos0=[1.5, -0.5])
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    energy = run["energy"]
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(energy))
    theta1, theta2 = 1.5, 1.0  # absolute angles from the downward vertical; the URDF's second hinge is relative
    heights = (-0.5 * math.cos(theta1), -math.cos(theta1) - 0.35 * math.cos(theta2))
    assert energy[0] == pytest.approx(9.81 * (1.0 * heights[0] + 0.5 * heights[1]), rel=1e-14)


# ----- meshes and packages --------------------------------------------------------------------------------

def test_package_meshes_through_package_dirs_and_ros_package_path(tmp_path, monkeypatch):
    import trimesh

    mesh_dir = tmp_path / "share" / "my_robot" / "meshes"
    mesh_dir.mkdir(parents=True)
    trimesh.creation.box((0.1, 0.2, 0.3)).export(mesh_dir / "link.stl")
    text = f"""<robot name="m"><link name="base"/><link name="a">{inertial(1.0)}
      <collision><geometry><mesh filename="package://my_robot/meshes/link.stl" scale="1 1 1"/></geometry></collision></link>
      <joint name="j" type="continuous"><parent link="base"/><child link="a"/></joint></robot>"""
    path = write(tmp_path, text)
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    with pytest.raises(URDFError, match=r"robot\.urdf, line 2, <mesh>: mesh 'package://my_robot/meshes/link\.stl' not found"):
        from_urdf(path)
    scene = from_urdf(path, package_dirs=[tmp_path / "share"])
    shape = scene.tree.bodies[0].shapes[0]
    assert shape.kind == "mesh" and os.path.samefile(shape.mesh, mesh_dir / "link.stl")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "share"))
    assert from_urdf(path).tree.bodies[0].shapes[0].mesh == shape.mesh
    mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))  # the mesh compiles in MuJoCo


# ----- refused, with file, line and element -------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    (f'<robot name="r"><link name="a">{inertial(1)}</link>\n<link name="b">{inertial(1)}\n'
     '<collision><geometry><mesh filename="missing.stl"/></geometry></collision></link>\n'
     '<joint name="j" type="continuous"><parent link="a"/><child link="b"/></joint></robot>',
     r"robot\.urdf, line 3, <mesh>: mesh file 'missing\.stl' not found"),
    (f'<robot name="r"><link name="a">{inertial(1)}</link><link name="b">{inertial(1)}</link>\n'
     '<joint name="j" type="screw"><parent link="a"/><child link="b"/></joint></robot>',
     r"robot\.urdf, line 2, <joint name='j'>: type='screw': unknown joint type"),
    (f'<robot name="r"><link name="a">{inertial(1)}</link><link name="b">{inertial(1)}</link>'
     f'<link name="c">{inertial(1)}</link>\n'
     '<joint name="j1" type="continuous"><parent link="a"/><child link="b"/></joint>\n'
     '<joint name="j2" type="continuous"><parent link="b"/><child link="c"/></joint>\n'
     '<joint name="j3" type="continuous"><parent link="a"/><child link="c"/></joint></robot>',
     r"robot\.urdf, line 4, <joint name='j3'>: link 'c' already has a parent through joint 'j2' \(line 3\).*loop"),
    (f'<robot name="r"><link name="a">{inertial(1)}</link><link name="b">{inertial(1)}</link>\n'
     '<joint name="j1" type="continuous"><parent link="a"/><child link="b"/></joint>\n'
     '<joint name="j2" type="continuous"><parent link="b"/><child link="a"/></joint></robot>',
     r"robot\.urdf, line 1, <robot name='r'>: no root link \(every link has a parent\): the joints form a loop"),
    ('<robot name="r"><link name="a">\n<inertial><mass value="1"/></link></robot>',
     r"robot\.urdf, line 2, column \d+: malformed XML"),
    (f'<robot name="r"><link name="a">{inertial(1)}</link>\n<link name="b"/>\n'
     '<joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint></robot>',
     r"robot\.urdf, line 3, <joint name='j'>: link 'b' has no mass .*no moving child"),
    (f'<robot name="r"><link name="a">{inertial(1)}<sensor name="cam"/></link></robot>',
     r"robot\.urdf, line 1, <sensor name='cam'>: unknown element <sensor> in <link>"),
    (f'<robot name="r"><link name="a">{inertial(1)}</link><link name="b">{inertial(1)}</link>\n'
     '<joint name="j" type="continuous"><parent link="a"/><child link="nope"/></joint></robot>',
     r"robot\.urdf, line 2, <child>: link 'nope' is not a <link> of the robot"),
])
def test_bad_urdf_is_refused_with_file_line_and_element(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(URDFError, match=message):
        from_urdf(path)


def test_bad_arguments_are_refused(tmp_path):
    path = write(tmp_path, NON_PHYSICAL)
    with pytest.raises(URDFError, match="qpos0 has shape"):
        from_urdf(path, qpos0=[1.0, 2.0, 3.0])
    with pytest.raises(URDFError, match="floating_base"):
        from_urdf(path, floating_base="yes")
    with pytest.raises(URDFError, match="no such file"):
        from_urdf(tmp_path / "none.urdf")
