"""The smooth MJCF features a published model uses, each equal to MuJoCo's own compilation and computation on MJCF
written here: gravcomp, settotalmass, joint springdamper, <frame>, option flags, a body welded to the world with
overlapping geoms, a model with nothing that moves, and loading that computes no unused mesh mass property."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import rbody
from rbody.mjcf import layout_from_mjcf

OFF = '<option><flag contact="disable"/></option>'


def mujoco_state(xml: str, q, v, ctrl=None):
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = q, v
    if ctrl is not None:
        d.ctrl[:] = ctrl
    mujoco.mj_forward(m, d)
    return m, d


def random_state(model, rng):
    q = model.qpos0 + rng.uniform(-0.5, 0.5, model.nq)
    for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
        if kind in ("ball", "free"):
            at = address + (3 if kind == "free" else 0)
            quat = rng.normal(size=4)
            q[at:at + 4] = quat / np.linalg.norm(quat)
    return q, rng.uniform(-1, 1, model.nv)


GRAVCOMP = f"""<mujoco>{OFF}<worldbody>
<body name="a" pos="0 0 1" gravcomp="1"><joint name="j1" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
  <body name="b" pos="0.4 0 0" gravcomp="0.5"><joint name="j2" axis="0 1 0" actuatorgravcomp="true" actuatorfrcrange="-0.3 0.3"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0.1" size="0.03"/>
    <body name="c" pos="0.3 0 0" gravcomp="0.7"><joint name="j3" type="ball"/><geom type="box" size="0.1 0.05 0.02" pos="0.1 0 0"/>
    </body></body></body>
<body name="f" pos="1 0 1" gravcomp="1"><freejoint/><geom size="0.1"/></body>
</worldbody><actuator><motor joint="j2"/></actuator></mujoco>"""


def test_gravcomp_and_actuatorgravcomp_equal_mujocos_passive_and_actuator_forces():
    scene = rbody.from_mjcf(GRAVCOMP)
    model = scene.multibody
    assert [b.gravcomp for b in scene.tree.bodies] == [1.0, 0.5, 0.7, 1.0]
    rng = np.random.default_rng(0)
    for _ in range(4):
        q, v = random_state(model, rng)
        ctrl = rng.uniform(-1, 1, 1)
        _, d = mujoco_state(GRAVCOMP, q, v, ctrl)
        assert np.max(np.abs(model.passive_forces(q, v) - d.qfrc_passive)) < 1e-14
        assert np.max(np.abs(model.actuator_forces(q, v, ctrl) - d.qfrc_actuator)) < 1e-15  # clamped at -0.3..0.3
        assert np.max(np.abs(model.forward_dynamics(q, v, ctrl=ctrl) - d.qacc)) < 1e-11 * np.max(np.abs(d.qacc))
    # a floating body that compensates all its weight stays where it is
    run = rbody.simulate(rbody.from_mjcf(GRAVCOMP, t_end=0.5), dt=1e-3, method="rk4")
    assert np.max(np.abs(run["f.com"] - run["f.com"][0])) < 1e-12
    exported = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))
    np.testing.assert_array_equal(exported.body_gravcomp, mujoco.MjModel.from_xml_string(GRAVCOMP).body_gravcomp)
    np.testing.assert_array_equal(exported.jnt_actgravcomp[:3], [0, 1, 0])


def test_gravcomp_follows_the_flags_as_mujoco_does():
    both_off = GRAVCOMP.replace('<flag contact="disable"/>', '<flag contact="disable" spring="disable" damper="disable"/>')
    scene = rbody.from_mjcf(both_off)
    assert all(b.gravcomp == 0 for b in scene.tree.bodies) and any("gravcomp" in n for n in scene.import_notes)
    q, v = random_state(scene.multibody, np.random.default_rng(1))
    _, d = mujoco_state(both_off, q, v, [0.2])
    np.testing.assert_allclose(scene.multibody.passive_forces(q, v), d.qfrc_passive, rtol=0, atol=1e-15)
    np.testing.assert_allclose(scene.multibody.actuator_forces(q, v, [0.2]), d.qfrc_actuator, rtol=0, atol=1e-15)


SPRINGY = """<mujoco><compiler settotalmass="7"/><option><flag contact="disable"/></option><worldbody>
<body name="a" pos="0 0 1"><joint name="j1" axis="0 1 0" springdamper="0.1 0.7" armature="0.02"/>
  <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
  <body name="b" pos="0.4 0 0"><joint name="j2" type="slide" axis="1 0 0" springdamper="0.05 1.5"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0.1" size="0.03"/></body></body>
</worldbody><actuator><position joint="j2" kp="10" dampratio="1"/></actuator></mujoco>"""


@pytest.mark.parametrize("total", ["7", None])
def test_settotalmass_and_springdamper_compile_to_mujocos_masses_stiffness_and_damping(total):
    xml = SPRINGY if total else SPRINGY.replace(' settotalmass="7"', "")
    m = mujoco.MjModel.from_xml_string(xml)
    scene = rbody.from_mjcf(xml)
    layout = scene.tree
    np.testing.assert_allclose([b.inertia.mass for b in layout.bodies], m.body_mass[1:], rtol=1e-15)
    assert sum(b.inertia.mass for b in layout.bodies) == pytest.approx(7.0 if total else m.body_mass.sum(), rel=1e-15)
    moments = np.array([np.linalg.eigvalsh(b.inertia.tensor) for b in layout.bodies])
    np.testing.assert_allclose(moments, np.sort(m.body_inertia[1:], axis=1), rtol=1e-14)
    np.testing.assert_allclose([j.stiffness for j in layout.joints], m.jnt_stiffness, rtol=1e-14)
    np.testing.assert_allclose([j.damping for j in layout.joints], m.dof_damping, rtol=1e-14)
    np.testing.assert_allclose(layout.actuators[0].biasprm, m.actuator_biasprm[0, :3], rtol=1e-14)
    assert any("springdamper" in note for note in scene.import_notes)


FRAMES = """<mujoco><compiler angle="degree"/><option><flag contact="disable"/></option>
<default><default class="heavy"><geom density="3000"/><joint damping="0.3"/></default></default>
<worldbody>
<frame pos="0.1 0.2 0.3" euler="10 20 30">
 <body name="a" pos="0 0 1"><joint name="j1" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
  <frame pos="0.4 0 0" quat="0.9 0.1 0.2 0.3" childclass="heavy">
    <frame euler="0 0 45"><body name="b"><joint name="j2" axis="0 1 0"/>
       <geom type="box" size="0.1 0.05 0.02" pos="0.1 0 0" euler="5 0 0"/></body></frame>
    <geom type="capsule" fromto="0.1 0 0 0.1 0 0.2" size="0.05"/>
  </frame>
 </body>
</frame>
</worldbody></mujoco>"""


def test_nested_frames_with_childclass_place_bodies_and_geoms_as_mujoco_does():
    scene = rbody.from_mjcf(FRAMES)
    model = scene.multibody
    m, d = mujoco_state(FRAMES, [0.3, -0.7], [0.5, 1.0])
    np.testing.assert_allclose([b.inertia.mass for b in scene.tree.bodies], m.body_mass[1:], rtol=1e-15)
    assert [j.damping for j in scene.tree.joints] == [0.0, 0.3]  # the frame's childclass reaches the body
    full = np.zeros((2, 2))
    mujoco.mj_fullM(m, d, full)
    np.testing.assert_allclose(model.mass_matrix([0.3, -0.7]), full, rtol=1e-13)
    np.testing.assert_allclose(model.bias_forces([0.3, -0.7], [0.5, 1.0]), d.qfrc_bias, rtol=1e-13)
    np.testing.assert_allclose(model.body_poses([0.3, -0.7])[0], d.xipos[1:], rtol=0, atol=1e-15)


def test_a_model_with_nothing_that_moves_loads_and_runs_a_constant_trajectory():
    xml = """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/><body pos="0 0 1"><geom size="0.1"/>
      <geom type="box" size="0.1 0.1 0.1" pos="0.05 0 0"/></body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    scene = rbody.from_mjcf(xml, t_end=0.1)
    assert (scene.multibody.nq, scene.multibody.nv) == (m.nq, m.nv) == (0, 0)
    assert any("welded to the world" in note for note in scene.import_notes)  # overlapping geoms: noted, summed
    assert scene.tree.bodies[0].inertia.mass == pytest.approx(m.body_mass[1], rel=1e-15)
    for method in ("rk4", "mujoco_euler"):
        run = rbody.simulate(scene, dt=0.01, method=method)
        assert run["qpos"].shape == (11, 0)
        np.testing.assert_array_equal(run["body1.com"], np.broadcast_to(run["body1.com"][0], (11, 3)))
        assert np.ptp(run["energy"]) == 0.0


def test_overlapping_geoms_on_a_moving_body_are_still_refused():
    xml = f"""<mujoco>{OFF}<worldbody><body><joint/><geom size="0.1"/><geom type="box" size="0.1 0.1 0.1"
      pos="0.05 0 0"/></body></worldbody></mujoco>"""
    with pytest.raises(ValueError, match="overlap"):
        layout_from_mjcf(xml)


def test_gravity_off_is_noted():
    xml = """<mujoco><option><flag contact="disable" gravity="disable"/></option><worldbody><body><joint/>
      <geom size="0.1"/></body></worldbody></mujoco>"""
    read = layout_from_mjcf(xml)
    assert read.gravity == 0.0 and any("gravity off" in note for note in read.notes)


def test_a_mesh_whose_mass_an_inertial_makes_unused_is_never_read(tmp_path, monkeypatch):
    """The file is not even a mesh: from_mjcf only needs its path for the Shape."""
    (tmp_path / "part.stl").write_text("not a mesh")
    xml = tmp_path / "robot.xml"
    xml.write_text(f"""<mujoco>{OFF}<asset><mesh name="part" file="part.stl"/></asset><worldbody>
      <body><joint/><inertial pos="0 0 0" mass="2" diaginertia="0.1 0.1 0.1"/><geom type="mesh" mesh="part"/></body>
      </worldbody></mujoco>""")
    import rbody.mjcf.parse as parse

    monkeypatch.setattr(parse, "mesh_mass", lambda *a, **k: pytest.fail("a mesh's mass properties were computed"))
    read = layout_from_mjcf(str(xml))
    assert read.layout.bodies[0].shapes[0].mesh == str(tmp_path / "part.stl")
    assert read.layout.bodies[0].inertia.mass == 2.0


def test_a_world_fixed_height_field_is_static_terrain_and_one_on_a_body_is_refused():
    asset = '<asset><hfield name="h" nrow="3" ncol="3" size="1 1 0.1 0.1" elevation="0 1 0 1 0 1 1 1 0"/></asset>'
    xml = f"""<mujoco>{asset}{OFF}<worldbody><geom type="hfield" hfield="h"/>
      <body pos="0 0 1"><joint/><geom size="0.1"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    read = layout_from_mjcf(xml)
    assert any("height field" in note for note in read.notes)
    (terrain,) = read.layout.fixed
    assert terrain.kind == "hfield" and terrain.size == (1.0, 1.0, 0.1, 0.1)
    # MuJoCo's normalised data, row 0 at y = -1: elevation's last row (its rows are listed from y = +1 down)
    np.testing.assert_array_equal(np.ravel(terrain.heights), model.hfield_data)
    np.testing.assert_array_equal(terrain.heights[0], [1.0, 1.0, 0.0])
    assert len(layout_from_mjcf(xml.replace(OFF, "")).layout.contacts) == 1  # the terrain and the body's sphere
    with pytest.raises(ValueError, match=r"line 2, <geom>: hfield geoms are not supported on a body"):
        layout_from_mjcf(f"""<mujoco>{asset}{OFF}<worldbody><body><joint/><geom size="0.1"/>
          <geom type="hfield" hfield="h"/></body></worldbody></mujoco>""")


def test_size_nkey_allocates_keyframes_at_qpos0_as_mujoco_does():
    """<size nkey="3"> with one <key>: MuJoCo's model has three keyframes, the two extra ones at qpos0 with no
    velocity and no control; rbody lists the same three and starts from any of them."""
    xml = """<mujoco><size nkey="3"/><worldbody><body><joint name="h" axis="0 1 0"/><geom size="0.1" pos="0 0 -1"/>
      </body></worldbody><actuator><motor joint="h"/></actuator>
      <keyframe><key name="up" qpos="1.0" ctrl="0.5"/></keyframe></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    model = layout_from_mjcf(xml)
    assert len(model.keyframes) == m.nkey == 3
    for (qpos, qvel), key_qpos, key_qvel in zip(model.keyframes.values(), m.key_qpos, m.key_qvel):
        np.testing.assert_array_equal(qpos, key_qpos)
        np.testing.assert_array_equal(qvel, key_qvel)
    last = rbody.from_mjcf(xml, keyframe=2)
    assert last.qpos0[0] == 0.0 and last.ctrl0[0] == m.key_ctrl[2, 0] == 0.0
    assert rbody.from_mjcf(xml, keyframe="up").ctrl0[0] == 0.5
