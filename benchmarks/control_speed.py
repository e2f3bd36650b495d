"""What a control input costs a run: rbody.simulate(scene, ctrl=...) on a 3-link arm with a slide (4 bodies,
5 actuators: position servos, a filtered general actuator, an integrated-velocity servo, a tendon motor).

    python benchmarks/control_speed.py [--steps 5000] [--repeats 3]

Prints the machine and versions, then microseconds per step of the whole simulate call (saving every step)
for rk4 and for MuJoCo's integrator "implicitfast", with
- no control (zeros), a constant control (nu,), a schedule (n_steps, nu): written into the model's parameter row
  and read inside the compiled loop;
- a callable ctrl(t, qpos, qvel): one Python call a step (the loop is stepped one step at a time);
and MuJoCo's mj_step on the same file with d.ctrl set from Python before each step, for reference.
Every figure is the minimum over --repeats runs after a warm-up. Benchmarks are not tests; the machine may be
shared (the load average is printed): compare figures of one run with each other.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mujoco  # noqa: E402
import numba  # noqa: E402

import rbody  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

ARM = """
<mujoco model="arm3">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="RK4"><flag contact="disable"/></option>
  <default><joint damping="0.05"/></default>
  <worldbody>
    <body name="l1" pos="0 0 1"><joint name="j1" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body name="l2" pos="0.4 0 0"><joint name="j2" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="l3" pos="0.3 0 0"><joint name="j3" axis="0 0 1"/>
          <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03"/>
          <body name="s" pos="0.2 0 0"><joint name="s" type="slide" axis="1 0 0"/><geom type="sphere" size="0.04"/>
          </body>
        </body></body></body>
  </worldbody>
  <tendon><fixed name="t" stiffness="3" damping="0.2"><joint joint="j1" coef="1"/><joint joint="j3" coef="0.5"/>
  </fixed></tendon>
  <actuator>
    <position joint="j1" kp="50" kv="5" ctrlrange="-1 1"/>
    <position joint="j2" kp="30" dampratio="0.8"/>
    <general joint="j3" dyntype="filter" dynprm="0.05" gainprm="2" biastype="affine" biasprm="0 -3 -0.5"/>
    <intvelocity joint="s" kp="40" kv="4" actrange="-0.2 0.2"/>
    <motor tendon="t" gear="2" forcerange="-1 1"/>
  </actuator>
</mujoco>
"""
DT = 0.002


def policy(t, qpos, qvel):
    return np.array([1.5 * np.sin(3 * t), 0.5 * np.cos(2 * t), 0.3, 0.5 * np.sin(t), np.sin(5 * t)])


def best(function, repeats: int) -> float:
    """Minimum wall time [s] of function() over `repeats` runs after one warm-up."""
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"machine    {describe_machine()}; numba threads {numba.get_num_threads()}; load avg {load}")
    print(f"versions   python {platform.python_version()}  numpy {np.__version__}  numba {numba.__version__}  "
          f"mujoco {mujoco.__version__}")
    steps = args.steps
    scene = rbody.from_mjcf(ARM, t_end=steps * DT)
    nu = scene.multibody.nu
    schedule = np.array([policy(k * DT, None, None) for k in range(steps)])
    controls = {"none (zeros)": None, "constant (nu,)": policy(0.0, None, None),
                "schedule (n_steps, nu)": schedule, "callable ctrl(t, qpos, qvel)": policy}
    for ctrl in controls.values():  # compile and build everything first
        for method in ("rk4", "implicitfast"):
            rbody.simulate(scene, dt=DT, method=method, ctrl=ctrl)
    print(f"\nus per step, whole simulate call, {steps} steps of {DT} s, save every step (nu = {nu})")
    print(f"{'control':32s} {'rk4':>10s} {'implicitfast':>14s}")
    for label, ctrl in controls.items():
        row = []
        for method in ("rk4", "implicitfast"):
            seconds = best(lambda: rbody.simulate(scene, dt=DT, method=method, ctrl=ctrl), args.repeats)
            row.append(1e6 * seconds / steps)
        print(f"{label:32s} {row[0]:10.2f} {row[1]:14.2f}")

    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)

    def mujoco_loop():
        mujoco.mj_resetData(m, d)
        for k in range(steps):
            d.ctrl[:] = schedule[k]
            mujoco.mj_step(m, d)
    print(f"{'MuJoCo mj_step RK4, ctrl from Python':32s} {1e6 * best(mujoco_loop, args.repeats) / steps:10.2f}")


if __name__ == "__main__":
    main()
