"""Contacts in the rigid limit against their closed forms, and MuJoCo's defaults on the same scenes: prints the
errors docs/contacts.md quotes, with the machine and versions. Usage: python benchmarks/contacts_closed_forms.py"""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "rbody" / "engine"))

import mujoco  # noqa: E402
import numba  # noqa: E402

import rbody  # noqa: E402
from rbody import Scene  # noqa: E402
from test_contact_closed_forms import G, ball_layout, incline  # noqa: E402


def rolling(dt=1e-3, v0=2.0, mu=0.3, r=0.1):
    run = rbody.simulate(Scene.from_layout(ball_layout(r, 0.0, mu), t_end=1.0, qvel0=[v0, 0, 0, 0, 0, 0]), dt=dt)
    v, w, z = run["ball.velocity"][:, 0], run["ball.omega"][:, 1], run["ball.com"][:, 2]
    start = run.t[np.argmax(np.abs(v - r * w) <= 1e-12)]
    xml = f"""<mujoco><option timestep="{dt}"/><worldbody><geom type="plane" size="0 0 1" friction="{mu}"/>
      <body pos="0 0 {r}"><freejoint/><geom type="sphere" size="{r}" mass="1" friction="{mu}"/></body></worldbody>
      <keyframe><key qvel="{v0} 0 0 0 0 0"/></keyframe></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    sink = 0.0
    for _ in range(int(round(1.0 / dt))):
        mujoco.mj_step(m, d)
        sink = max(sink, r - d.qpos[2])
    print(f"rolling sphere (dt={dt}): rbody t* {start:.4f} s (closed form {2 * v0 / (7 * mu * G):.6f}), speed error "
          f"{abs(v[-1] - 5 / 7 * v0):.2g} m/s, height error {np.abs(z - r).max():.2g} m; MuJoCo (defaults): speed error "
          f"{abs(d.qvel[0] - 5 / 7 * v0):.2g} m/s, slip {d.qvel[0] - r * d.qvel[4]:.2g} m/s, sinks {sink:.2g} m")


def block(factor, t_end, dt, alpha=0.3):
    mu = np.tan(alpha) * factor
    layout, R = incline(mu, alpha)
    run = rbody.simulate(Scene.from_layout(layout, t_end=t_end), dt=dt)
    x = (run["box.com"] - run["box.com"][0]) @ R[:, 0]
    a = G * (np.sin(alpha) - mu * np.cos(alpha))
    t = run.t
    if a <= 0:
        print(f"block, mu = tan(alpha) x {factor}: sticks, moved {np.abs(run['box.com'] - run['box.com'][0]).max():.2g}"
              f" m in {t_end} s")
    else:
        print(f"block, mu = tan(alpha) x {factor}: slides, |x - a t(t+dt)/2| {np.abs(x - a * t * (t + dt) / 2).max():.2g}"
              f" m, |x - a t^2/2| {np.abs(x - a * t ** 2 / 2).max():.2g} m (a t_end dt / 2 = {a * t_end * dt / 2:.2g})")


def stack_in_mujoco(t_end=100.0, dt=2e-3):
    """The test's stack of five boxes (each narrower than the one below) as MJCF, MuJoCo's defaults: how far the boxes
    sink into each other and drift over t_end (rbody: 1.6e-14 over 100 s, tests/rbody/engine)."""
    bodies, z = [], 0.0
    for k in range(5):
        hx, hy, hz = 0.3 - 0.04 * k, 0.25 - 0.04 * k, 0.05
        z += hz
        bodies.append(f'<body pos="{0.01 * k} {-0.005 * k} {z}"><freejoint/><geom type="box" size="{hx} {hy} {hz}" '
                      f'mass="{1.0 + k}" friction="0.5"/></body>')
        z += hz
    xml = (f'<mujoco><option timestep="{dt}"/><worldbody><geom type="plane" size="0 0 1" friction="0.5"/>'
           + "".join(bodies) + "</worldbody></mujoco>")
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    start = d.qpos.copy()
    for _ in range(int(round(t_end / dt))):
        mujoco.mj_step(m, d)
    sink = max(start[7 * k + 2] - d.qpos[7 * k + 2] for k in range(5))
    drift = max(np.linalg.norm(d.qpos[7 * k:7 * k + 2] - start[7 * k:7 * k + 2]) for k in range(5))
    print(f"stack of five boxes, MuJoCo (defaults, dt={dt}), {t_end} s: top box {sink:.3g} m lower (sinking into the "
          f"contacts below), horizontal drift {drift:.3g} m; rbody: 1.6e-14 (qpos, 100 s, dt = 10 ms)")


def main():
    print(platform.processor() or platform.machine(), platform.platform())
    print(f"numpy {np.__version__}, numba {numba.__version__}, mujoco {mujoco.__version__}")
    start = time.perf_counter()
    rolling()
    for factor, t_end, dt in ((1 + 1e-6, 100.0, 1e-2), (1 - 1e-6, 2.0, 1e-3), (0.3, 2.0, 1e-3)):
        block(factor, t_end, dt)
    stack_in_mujoco()
    print(f"({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
