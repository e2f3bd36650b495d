"""compare() and `python -m validation compare` on a user's own MJCF file: MuJoCo compiles the file itself (never
rbody's re-export), both engines run the file's integrator at its step from the same state under the same
controls, an engine that cannot run the model is a row saying why, and nothing compared is a non-zero exit."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pytest

import rbody
from validation.__main__ import main
from validation.comparison import compare

ARM = (Path(__file__).parents[1] / "rbody" / "test_control.py").read_text().split('ARM = """')[1].split('"""')[0]
KEY = '<keyframe><key name="bent" qpos="0.3 -0.5 0.2 0.05" ctrl="0.5 0.2 0 0 0"/></keyframe></mujoco>'


def policy(t, qpos, qvel):
    return np.array([np.sin(3 * t), 0.5 * np.cos(2 * t), 0.3, 0.5 * np.sin(t), np.sin(5 * t)])


@pytest.fixture
def arm(tmp_path) -> Path:
    path = tmp_path / "arm.xml"
    path.write_text(ARM.replace('integrator="RK4"', 'integrator="implicitfast"').replace("</mujoco>", KEY))
    return path


def test_the_users_file_runs_in_mujoco_as_it_is_with_its_own_integrator(arm):
    c = compare(arm, engines=["rbody", "mujoco"], t_end=2.0, keyframe="bent", ctrl=policy)
    mujoco_run = c.runs["mujoco"].trajectory
    assert mujoco_run.meta["source"] == str(arm) and mujoco_run.meta["settings"]["own file"]
    assert mujoco_run.meta["integrator"] == "implicitfast" and c.method == "implicitfast" and c.dt == 0.002
    np.testing.assert_allclose(mujoco_run["qpos"][0], [0.3, -0.5, 0.2, 0.05])  # the keyframe
    for observable in ("qpos", "qvel", "act", "actuator_force", "l3.com", "s.quat", "energy"):
        assert c.row(observable, "rbody", "mujoco").largest < 1e-12, observable
    schedule = np.array([policy(k * 0.002, None, None) for k in range(1000)])
    by_array = compare(arm, engines=["rbody", "mujoco"], t_end=2.0, keyframe=0, ctrl=schedule)
    assert by_array.row("qpos", "rbody", "mujoco").largest < 1e-12
    state = compare(arm, engines=["rbody", "mujoco"], t_end=0.5, qpos0=[0.1, 0.2, 0.3, 0.0], qvel0=[1, 0, 0, 0])
    np.testing.assert_allclose(state.runs["mujoco"].trajectory["qvel"][0], [1, 0, 0, 0])
    assert state.row("qpos", "rbody", "mujoco").largest < 1e-12


def test_an_import_error_shows_as_a_divergence(arm, monkeypatch):
    """MuJoCo reads the file itself: an rbody reader that got a mass wrong is seen (with rbody's re-export on both
    sides it could not be)."""
    reader = rbody.from_mjcf

    def misread(*args, **kwargs):
        scene = reader(*args, **kwargs)
        bodies = list(scene.tree.bodies)
        inertia = bodies[0].inertia
        bodies[0] = dataclasses.replace(bodies[0], inertia=rbody.Inertia(1.01 * inertia.mass, inertia.com,
                                                                          1.01 * inertia.tensor))
        return dataclasses.replace(scene, tree=dataclasses.replace(scene.tree, bodies=tuple(bodies)))

    monkeypatch.setattr(rbody, "from_mjcf", misread)
    c = compare(arm, engines=["rbody", "mujoco"], t_end=1.0, keyframe="bent")
    assert c.row("qpos", "rbody", "mujoco").largest > 1e-4


def test_a_file_rbody_refuses_is_a_row_that_says_why_and_nothing_compared_exits_3(arm, tmp_path, capsys):
    refused = tmp_path / "cylinder.xml"
    refused.write_text(arm.read_text().replace('<motor tendon="t" gear="2" forcerange="-1 1"/>',
                                               '<cylinder tendon="t"/>'))
    c = compare(refused, engines=["rbody", "mujoco"], t_end=0.2)
    assert c.runs["rbody"].status == "refused" and "<cylinder>: cylinder actuators" in c.runs["rbody"].note
    assert c.runs["mujoco"].status == "ran" and c.rows == ()
    assert main(["compare", str(refused), "--out", str(tmp_path / "out"), "--t-end", "0.2"]) == 3
    err = capsys.readouterr().err
    assert "NOTHING COMPARED" in err and "cylinder actuators" in err


def test_the_command_takes_a_keyframe_a_state_and_controls(arm, tmp_path, capsys):
    np.save(tmp_path / "ctrl.npy", np.array([policy(k * 0.002, None, None) for k in range(250)]))
    out = str(tmp_path / "out")
    assert main(["compare", str(arm), "--t-end", "0.5", "--keyframe", "0", "--ctrl", str(tmp_path / "ctrl.npy"),
                 "--engines", "rbody,mujoco", "--out", out]) == 0
    assert main(["compare", str(arm), "--t-end", "0.5", "--qpos0", "0.1 0.2 0.3 0", "--qvel0", "0 0 1 0",
                 "--engines", "rbody,mujoco", "--out", out]) == 0
    table = capsys.readouterr().out
    assert "qpos" in table and "rbody-mujoco" in table
    assert main(["compare", str(arm), "--qpos0", "1 2", "--engines", "rbody,mujoco", "--out", out]) == 2
    assert "qpos0" in capsys.readouterr().err


def test_overlapping_geoms_are_summed_on_request(tmp_path):
    path = tmp_path / "overlap.xml"
    path.write_text("""<mujoco><option><flag contact="disable"/></option><worldbody><body><joint axis="0 1 0"/>
      <geom size="0.1" pos="0.2 0 0"/><geom type="box" size="0.1 0.1 0.1" pos="0.25 0 0"/></body></worldbody>
      <keyframe><key qpos="0.5"/></keyframe></mujoco>""")
    refused = compare(path, engines=["rbody", "mujoco"], t_end=0.2)
    assert refused.runs["rbody"].status == "refused" and "overlap" in refused.runs["rbody"].note
    summed = compare(path, engines=["rbody", "mujoco"], t_end=0.2, keyframe=0, overlapping_geoms="sum")
    assert summed.row("qpos", "rbody", "mujoco").largest < 1e-13  # MuJoCo's Euler on both sides


def test_to_mjcf_of_a_mesh_robot_compiles_with_the_same_masses_even_for_an_inside_out_mesh(tmp_path):
    """MuJoCo refuses inertia="exact" for an inside-out mesh; the body's explicit <inertial> makes the mesh's
    mass unused, so to_mjcf writes it with MuJoCo's legacy mode and the model compiles."""
    import trimesh

    box = trimesh.creation.box((0.2, 0.1, 0.05))
    box.faces = box.faces[:, ::-1]  # every face turned inside out: a negative volume
    box.export(tmp_path / "part.stl")
    xml = tmp_path / "robot.xml"
    xml.write_text(f"""<mujoco><compiler meshdir="{tmp_path}"/><option><flag contact="disable"/></option>
      <asset><mesh name="part" file="part.stl"/></asset><worldbody><body><joint axis="0 1 0"/>
      <inertial pos="0.1 0 0" mass="1.5" diaginertia="0.01 0.02 0.03"/><geom type="mesh" mesh="part"/></body>
      </worldbody></mujoco>""")
    original = mujoco.MjModel.from_xml_path(str(xml))
    text = rbody.to_mjcf(rbody.from_mjcf(xml))
    assert 'inertia="legacy"' in text
    exported = mujoco.MjModel.from_xml_string(text)
    np.testing.assert_allclose(exported.body_mass, original.body_mass, rtol=1e-15)
    np.testing.assert_allclose(np.sort(exported.body_inertia, axis=1), np.sort(original.body_inertia, axis=1),
                               rtol=1e-14)
