"""Fluid forces (rbody.layout.Fluid, rbody.engine.fluid, rbody.mjcf.fluid): MuJoCo's inertia-box and ellipsoid
models against MuJoCo's qfrc_passive and runs, their export, and a sphere falling to its terminal speed."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Scene
from rbody.errors import MethodNotApplicable
from rbody.layout import Fluid, FluidBox
from rbody.mjcf import MJCFError, layout_from_mjcf

FLUID = """<mujoco><option density="1.2" viscosity="0.02" wind="0.5 -0.3 0.1" integrator="INTEGRATOR">
<flag contact="disable"/></option><worldbody>
<body name="cap" pos="0 0 1"><freejoint/>
  <geom type="capsule" size="0.1 0.3" euler="10 20 30" fluidshape="ellipsoid" fluidcoef="0.6 0.3"/>
  <geom type="sphere" size="0.05" pos="0.5 0 0"/></body>
<body name="cyl" pos="1 0 1"><freejoint/><geom type="cylinder" size="0.1 0.3" euler="10 20 30"/>
  <body name="arm" pos="0.2 0 0"><joint name="j" axis="0 1 0" damping="0.1"/><geom type="box" size="0.1 0.05 0.02" pos="0.1 0 0"/>
    <body name="tip" pos="0.2 0 0"><joint name="k" type="ball"/>
      <geom type="ellipsoid" size="0.05 0.08 0.1" fluidshape="ellipsoid"/></body></body></body>
<body name="inert" pos="2 0 1"><freejoint/><inertial pos="0.1 0 0" mass="1" diaginertia="0.1 0.1 0.2" euler="0 30 0"/>
  <geom size="0.1"/></body>
<body name="sph" pos="3 0 1"><freejoint/><geom size="0.1"/></body>
</worldbody><actuator><position joint="j" kp="5" kv="0.2"/></actuator></mujoco>"""
BOXES_ONLY = FLUID.replace(' fluidshape="ellipsoid" fluidcoef="0.6 0.3"', "").replace(' fluidshape="ellipsoid"', "")


def random_state(model, rng):
    q = model.qpos0.copy()
    for kind, a in zip(model.arrays.joint_kinds, model.arrays.qposadr):
        if kind == "free":
            q[a:a + 3] += rng.uniform(-1, 1, 3)
            quat = rng.normal(size=4)
            q[a + 3:a + 7] = quat / np.linalg.norm(quat)
        elif kind == "ball":
            quat = rng.normal(size=4)
            q[a:a + 4] = quat / np.linalg.norm(quat)
        else:
            q[a] += rng.uniform(-1, 1)
    return q, rng.uniform(-2, 2, model.nv)


def mujoco_run(xml, steps, ctrl):
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.ctrl[:] = ctrl
    qpos = [d.qpos.copy()]
    for _ in range(steps):
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
    return np.array(qpos)


def test_both_fluid_models_equal_mujocos_passive_forces_and_export():
    xml = FLUID.replace("INTEGRATOR", "RK4")
    scene = rbody.from_mjcf(xml)
    fluid = scene.tree.fluid
    assert [b.body for b in fluid.boxes] == ["cyl", "arm", "inert", "sph"]
    assert [e.body for e in fluid.ellipsoids] == ["cap", "tip"]
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    ellipsoid_geoms = [i for i in range(m.ngeom) if m.geom_fluid[i, 0] > 0]
    for shape, g in zip(fluid.ellipsoids, ellipsoid_geoms):  # the compiler's added-mass factors, as MuJoCo forms them
        np.testing.assert_allclose(shape.virtual_mass + shape.virtual_inertia, m.geom_fluid[g, 6:], rtol=1e-14)
        np.testing.assert_array_equal(shape.coefficients, m.geom_fluid[g, 1:6])
    exported = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))
    d2 = mujoco.MjData(exported)
    model = scene.multibody
    rng = np.random.default_rng(0)
    for _ in range(4):
        q, v = random_state(model, rng)
        for mm, dd in ((m, d), (exported, d2)):
            dd.qpos[:], dd.qvel[:] = q, v
            mujoco.mj_forward(mm, dd)
        scale = np.max(np.abs(d.qfrc_passive))
        assert np.max(np.abs(model.passive_forces(q, v) - d.qfrc_passive)) < 1e-14 * scale
        assert np.max(np.abs(d2.qfrc_passive - d.qfrc_passive)) < 1e-14 * scale


@pytest.mark.parametrize("xml, integrator, method", [
    (FLUID, "Euler", "mujoco_euler"), (FLUID, "RK4", "rk4"),
    (BOXES_ONLY, "implicitfast", "implicitfast"), (BOXES_ONLY, "implicit", "implicit")])
def test_runs_in_a_fluid_equal_mujocos_at_the_files_step(xml, integrator, method):
    xml = xml.replace("INTEGRATOR", integrator)
    scene = rbody.from_mjcf(xml, t_end=1.0)
    run = rbody.simulate(scene, dt=scene.timestep, method=method, ctrl=[0.3])
    assert np.max(np.abs(run["qpos"] - mujoco_run(xml, 500, [0.3]))) < 1e-12


def test_the_implicit_integrators_are_refused_with_the_ellipsoid_model():
    scene = rbody.from_mjcf(FLUID.replace("INTEGRATOR", "implicitfast"), t_end=0.1)
    with pytest.raises(MethodNotApplicable, match="mjd_ellipsoidFluid"):
        rbody.simulate(scene, dt=0.002, method="implicitfast")


def falling_sphere(density: float, viscosity: float) -> Scene:
    """A solid sphere of radius 0.1 m and mass 0.05 kg falling from rest: its inertia box has sides b = r sqrt(12/5)."""
    radius, mass = 0.1, 0.05
    body = Body("ball", Inertia.solid_sphere(mass, radius))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "ball"),),
                    fluid=Fluid(density=density, viscosity=viscosity, boxes=(FluidBox("ball"),)))
    return Scene.from_layout(layout, t_end=6.0)


def test_a_sphere_falling_in_a_dense_fluid_follows_v_t_tanh_g_t_over_v_t():
    """m v' = m g - rho b^2 v^2 / 2: v = v_t tanh(g t / v_t), v_t = sqrt(2 m g / (rho b^2))."""
    scene = falling_sphere(density=1.2, viscosity=0.0)
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    side = 0.1 * math.sqrt(12 / 5)
    terminal = math.sqrt(2 * 0.05 * 9.81 / (1.2 * side**2))
    exact = -terminal * np.tanh(9.81 * run.t / terminal)
    assert np.max(np.abs(run["qvel"][:, 2] - exact)) < 1e-11
    assert abs(run["qvel"][-1, 2] + terminal) < 1e-6 * terminal  # it has reached its terminal speed


def test_a_sphere_falling_in_a_viscous_fluid_follows_stokes_drag():
    """m v' = m g - 3 pi b mu v: v = v_t (1 - e^{-t/tau}), v_t = m g / (3 pi b mu), tau = m / (3 pi b mu)."""
    scene = falling_sphere(density=0.0, viscosity=0.5)
    run = rbody.simulate(scene, dt=2.5e-4, method="rk4")  # h / tau = 3.6e-3: rk4's error ~ 1e-13 over the run
    side = 0.1 * math.sqrt(12 / 5)
    rate = 3 * math.pi * side * 0.5 / 0.05
    exact = -9.81 / rate * (1 - np.exp(-rate * run.t))
    assert np.max(np.abs(run["qvel"][:, 2] - exact)) < 1e-12


@pytest.mark.parametrize("geom, match", [
    ('<geom type="mesh" mesh="m" fluidshape="ellipsoid"/>', "on a mesh geom"),
    ('<geom size="0.1" fluidshape="sphere"/>', "fluidshape='sphere'"),
])
def test_fluid_refusals_name_file_line_and_reason(geom, match, tmp_path):
    (tmp_path / "m.stl").write_text("solid m\nendsolid m\n")
    xml = tmp_path / "f.xml"
    xml.write_text(f"""<mujoco><option density="1"><flag contact="disable"/></option>
      <asset><mesh name="m" file="m.stl"/></asset><worldbody><body><joint/>
      {geom}<geom size="0.2"/></body></worldbody></mujoco>""")
    with pytest.raises(MJCFError, match=match) as error:
        layout_from_mjcf(str(xml))
    assert "f.xml, line 3" in str(error.value)
