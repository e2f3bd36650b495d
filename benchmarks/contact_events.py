"""Event-driven contacts (method "rk4") on the closed forms of issue 22: errors against the closed forms and the
wall-clock time of each run (the second of two runs: the first compiles), with the machine and versions.

    PYTHONPATH=$PWD python benchmarks/contact_events.py
"""

from __future__ import annotations

import math
import platform
import time

import numpy as np

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81


def ball(r, height, mu, e):
    body = Body("ball", Inertia.solid_sphere(1.0, r), shapes=(Shape("s", "sphere", (r,)),), pos=(0, 0, r + height))
    return Layout(bodies=(body,), joints=(Joint("free", "free", "ball"),), fixed=(Shape("floor", "plane", (0, 0)),),
                  contacts=(Contact("floor", "s", friction=mu, restitution=e),))


def incline(mu, alpha=0.3, half=(0.1, 0.1, 0.05)):
    q = (math.cos(alpha / 2), 0.0, math.sin(alpha / 2), 0.0)
    R = quat_to_matrix(np.array(q))
    box = Body("box", Inertia.box(1.0, 2 * np.array(half)), shapes=(Shape("b", "box", half),),
               pos=tuple(R[:, 2] * half[2]), quat=q)
    return Layout(bodies=(box,), joints=(Joint("free", "free", "box"),),
                  fixed=(Shape("ramp", "plane", (0, 0), quat=q),), contacts=(Contact("ramp", "b", friction=mu),)), R


def timed(scene, dt, method):
    rbody.simulate(scene, dt=dt, method=method)
    start = time.perf_counter()
    run = rbody.simulate(scene, dt=dt, method=method)
    return run, time.perf_counter() - start


def main() -> None:
    import numba
    print(f"{platform.processor() or platform.machine()}, {platform.system()} {platform.release()}; numpy "
          f"{np.__version__}, numba {numba.__version__}")
    print("| case | closed form | method | dt [s] | error | run [s] | events |")
    print("|---|---|---|---|---|---|---|")
    H, r, e = 1.0, 0.1, 0.5
    T0 = math.sqrt(2 * H / G)
    for method in ("rk4", "moreau"):
        run, cost = timed(Scene.from_layout(ball(r, H, 0.5, e), t_end=1.2), 1e-3, method)
        vz = run["ball.velocity"][:, 2]
        if method == "rk4":
            impacts = run.events["time"][run.events["what"] == "impact"][:3]
        else:
            impacts = run.t[1:][(vz[1:] > 0) & (vz[:-1] <= 0)][:3]
        closed = T0 * np.array([1, 1 + 2 * e, 1 + 2 * e + 2 * e ** 2])
        print(f"| ball dropped 1 m, e = 0.5 | impacts at T0 (1, 1 + 2e, 1 + 2e + 2e^2) | {method} | 1e-3 | "
              f"{np.abs(impacts - closed).max():.2g} s | {cost:.3g} | {len(run.events['time'])} |")
    v0, mu = 2.0, 0.3
    t_star = 2 * v0 / (7 * mu * G)
    for method in ("rk4", "moreau"):
        run, cost = timed(Scene.from_layout(ball(r, 0.0, mu, 0.0), t_end=1.0, qvel0=[v0, 0, 0, 0, 0, 0]), 1e-3, method)
        v, w = run["ball.velocity"][:, 0], run["ball.omega"][:, 1]
        if method == "rk4":
            start = run.events["time"][0]
        else:
            start = run.t[np.argmax(np.abs(v - r * w) <= 1e-12)]
        print(f"| sphere thrown sliding, v0 = 2, mu = 0.3 | rolls from t* = {t_star:.6f} s at 5/7 v0 | {method} | 1e-3 "
              f"| t*: {abs(start - t_star):.2g} s, speed {np.abs(v[-1] - 5 / 7 * v0):.2g} m/s | {cost:.3g} | "
              f"{len(run.events['time'])} |")
    alpha = 0.3
    for factor in (1 + 1e-6, 1 - 1e-6):
        layout, R = incline(math.tan(alpha) * factor, alpha)
        mu = math.tan(alpha) * factor
        run, cost = timed(Scene.from_layout(layout, t_end=2.0), 1e-2, "rk4")
        x = (run["box.com"] - run["box.com"][0]) @ R[:, 0]
        a = max(G * (math.sin(alpha) - mu * math.cos(alpha)), 0.0)
        print(f"| block on incline, mu = tan(alpha)({factor:.6f}) | {'sticks' if a == 0 else 'x = a t^2/2'} | rk4 | "
              f"1e-2 | {np.abs(x - a * run.t ** 2 / 2).max():.2g} m | {cost:.3g} | {len(run.events['time'])} |")
    from rbody.scenes.collisions import pi_collisions
    import sys
    sys.path.insert(0, "tests/rbody")
    from test_mjcf_contact_scenes import line_model
    for digits in (1, 2, 3):
        exact = pi_collisions(digits)
        scene = rbody.from_mjcf(line_model(list(exact.masses), list(exact.positions), exact.radius), t_end=exact.t_end,
                                qvel0=list(exact.velocities))
        run, cost = timed(scene, exact.t_end / (200 * 10 ** (digits - 1)), "rk4")
        count = int((run.events["what"] == "impact").sum())
        print(f"| pi collisions as MJCF, N = {digits} | floor(pi 10^N) = {math.floor(math.pi * 10 ** digits)} | rk4 | "
              f"t_end/{200 * 10 ** (digits - 1)} | {count} impacts | {cost:.3g} | {len(run.events['time'])} |")


if __name__ == "__main__":
    main()
