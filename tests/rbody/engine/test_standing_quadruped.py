"""A quadruped standing on four feet with dry friction in its joints (this test's own MJCF, in the manner of published
quadrupeds: a free trunk, hip and knee hinges with frictionloss and damping, position servos, sphere feet, a floor):
the step's problem has 24 rows of rank 18 (12 joint friction rows in their boxes, 4 sticking feet), whose solution
Gauss-Seidel approaches over some 10^5 sweeps and the state-reading finishes miss; rbody.engine.constraints.cone's
sticking_qp (an active-set method on the box QP of sticking contacts) solves it exactly. It must stand: no
SimulationError, the feet held (no slip beyond round-off once settled, no sinking), the weight on the feet."""

import numpy as np
import pytest

import rbody
from rbody.engine.constraints.cone import cone_residual, sticking_qp

# Three joints a leg (abduction, hip, knee) and condim 6 feet, a 40 kg trunk held by position servos without damping,
# dropped 1 cm: the landing's problems have 36 rows of rank 18 (12 joint friction boxes, 4 feet with spin and
# rolling) on which Gauss-Seidel crawls along W's null space and every state read from its iterates misses (left at
# 2.4e-7 after 2000 sweeps before rbody.engine.constraints.interior); Tresca's problem from inside finds the states.
LEG3 = """
<body name="{name}_abduct" pos="{x} {y} 0">
  <joint name="{name}_abduct" axis="1 0 0" class="leg"/>
  <geom type="sphere" size="0.03" mass="0.5" contype="0" conaffinity="0"/>
  <body name="{name}_hip" pos="0 {side} 0">
    <joint name="{name}_hip" axis="0 1 0" class="leg"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.02" mass="0.6" contype="0" conaffinity="0"/>
    <body name="{name}_knee" pos="0 0 -0.2">
      <joint name="{name}_knee" axis="0 1 0" class="leg"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.16" size="0.015" mass="0.3" contype="0" conaffinity="0"/>
      <geom name="{name}_foot" type="sphere" pos="0 0 -0.2" size="0.02" mass="0.05" condim="6"
            friction="0.8 0.02 0.01"/>
    </body>
  </body>
</body>"""

LEG = """
<body name="{name}_hip" pos="{x} {y} 0">
  <joint name="{name}_hip" axis="0 1 0" class="leg"/>
  <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.02" mass="0.6" contype="0" conaffinity="0"/>
  <body name="{name}_knee" pos="0 0 -0.2">
    <joint name="{name}_knee" axis="0 1 0" class="leg"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.16" size="0.015" mass="0.3" contype="0" conaffinity="0"/>
    <geom name="{name}_foot" type="sphere" pos="0 0 -0.2" size="0.02" mass="0.05"/>
  </body>
</body>"""

XML = """<mujoco>
<option timestep="0.002"/>
<default><default class="leg"><joint damping="{damping}" frictionloss="{loss}" armature="0.01"/></default></default>
<worldbody>
<geom name="floor" type="plane" size="0 0 1" friction="0.8"/>
<body name="trunk" pos="0 0 {height}"><freejoint/>
<geom type="box" size="0.25 0.1 0.05" mass="{trunk}" contype="0" conaffinity="0"/>
{legs}
</body></worldbody>
<actuator>{servos}</actuator>
<keyframe><key name="stand" qpos="0 0 {lifted} 1 0 0 0 {angles}" ctrl="{angles}"/></keyframe>
</mujoco>"""

HIP, KNEE = 0.5, -1.0


def standing_xml() -> str:
    names = [("fl", 0.2, 0.12), ("fr", 0.2, -0.12), ("rl", -0.2, 0.12), ("rr", -0.2, -0.12)]
    legs = "".join(LEG.format(name=n, x=x, y=y) for n, x, y in names)
    servos = "".join(f'<position joint="{n}_{j}" kp="60" kv="2"/>' for n, _x, _y in names for j in ("hip", "knee"))
    angles = " ".join(f"{HIP} {KNEE}" for _ in names)
    # the foot below the hip: 0.2 cos(hip) + 0.2 cos(hip + knee), then the foot's radius
    height = 0.2 * np.cos(HIP) + 0.2 * np.cos(HIP + KNEE) + 0.02
    return XML.format(height=height, lifted=height, legs=legs, servos=servos, angles=angles, damping=2, loss=0.2,
                      trunk=6)


def landing_xml(drop: float = 0.01) -> str:
    """The quadruped of LEG3, its feet `drop` [m] above the floor."""
    names = [("fl", 0.2, 0.1, 0.05), ("fr", 0.2, -0.1, -0.05), ("rl", -0.2, 0.1, 0.05), ("rr", -0.2, -0.1, -0.05)]
    legs = "".join(LEG3.format(name=n, x=x, y=y, side=side) for n, x, y, side in names)
    servos = "".join(f'<position joint="{n}_{j}" kp="100"/>' for n, *_ in names for j in ("abduct", "hip", "knee"))
    angles = " ".join(f"0 {HIP} {KNEE}" for _ in names)
    height = 0.2 * np.cos(HIP) + 0.2 * np.cos(HIP + KNEE) + 0.02
    return XML.format(height=height, lifted=height + drop, legs=legs, servos=servos, angles=angles, damping=2,
                      loss=0.1, trunk=40)


def test_a_quadruped_with_joint_friction_stands_on_its_feet(tmp_path):
    path = tmp_path / "quadruped.xml"
    path.write_text(standing_xml())
    scene = rbody.from_mjcf(path, keyframe="stand", t_end=1.0)
    run = rbody.simulate(scene, dt=scene.timestep, method=scene.file_method)  # raised before sticking_qp
    gaps = run["contact_distance"]
    assert gaps.min() >= -1e-12  # no sinking
    assert run["contacts"][-1] == 4
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), 9.81 * (6 + 4 * 0.95), rtol=1e-6)
    feet = run["contact_point"][run.t >= 0.5]  # settled: the feet do not slip
    assert np.abs(feet - feet[0]).max() <= 1e-9


def test_sticking_qp_solves_a_problem_with_dependent_rows():
    """Six rows over three dofs (rank 3): two box rows, two normals (>= 0) and two free rows, b in W's range (the
    quadratic is bounded below, so a solution exists). From rest the active-set method reaches it to round-off,
    within the bounds."""
    from rbody.engine.constraints.cone import ROW, NORMAL

    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 3))
    W = J @ J.T
    b = J @ np.array([0.0, -1.0, 0.2])
    lo = np.array([-0.05, -0.05, 0.0, -np.inf, 0.0, -np.inf])
    hi = np.array([0.05, 0.05, np.inf, np.inf, np.inf, np.inf])
    role = np.array([ROW, ROW, NORMAL, ROW, NORMAL, ROW], dtype=np.int64)
    mu = np.zeros(6)
    lam = np.zeros(6)
    residual = sticking_qp(W, b, lo, hi, role, mu, lam)
    assert residual <= 1e-12
    assert residual == cone_residual(W, b, lo, hi, role, mu, lam)
    assert np.all(lam >= lo) and np.all(lam <= hi)


def test_a_quadruped_on_condim_6_feet_lands_and_comes_to_rest(tmp_path):
    path = tmp_path / "landing.xml"
    path.write_text(landing_xml())
    scene = rbody.from_mjcf(path, keyframe="stand", t_end=1.2)
    run = rbody.simulate(scene, dt=scene.timestep, method=scene.file_method)  # raised before the interior finish
    assert run["contact_distance"].min() >= -1e-12  # no sinking
    assert run["contacts"][-1] == 4
    mass = 40 + 4 * (0.5 + 0.6 + 0.3 + 0.05)
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), 9.81 * mass, rtol=1e-9)  # at rest: the weight
    rest = run.t >= 0.9  # (it comes to rest at 0.834 s)
    assert np.abs(run["qvel"][rest]).max() <= 1e-12
    pushing = run["contact_normal_force"][-1] > 0.0  # the four feet on the floor (the feet's own pairs apart)
    feet = run["contact_point"][rest][:, pushing]
    assert np.abs(feet - feet[0]).max() <= 1e-12  # held by static friction, rolling and spinning included
