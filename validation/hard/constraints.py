"""Hard cases of the constraint layer: MuJoCo's divergence from the rigid limit on closed forms.

Each case is one MJCF file, read by rbody (rbody.from_mjcf: limits, frictionloss and equalities held rigidly) and
compiled by MuJoCo as it stands (soft: solref/solimp springs in constraint space), and one closed form. Both engines'
runs are measured against the closed form by the same function, so that a number is MuJoCo's divergence from rigid
mechanics, not a disagreement between two simulators:

- limit_pendulum: a rod released at theta0 = 1 rad onto a stop at -0.5 rad (e = 0, MuJoCo's default critically
  damped limit): how far the rod passes its stop, when it comes back up (from the impact time, an incomplete
  elliptic integral, and the swing from rest at the stop), and the swing after (exactly +-0.5 rad: it stops dead,
  then swings back);
- elastic_limit: the same stop with e = 1 (MuJoCo: an undamped limit, solreflimit "-100000 0", stiffness 1e5 and no
  damping): the same measures, the rebound's height (exactly theta0);
- friction_oscillator: a mass on a spring with dry friction F (2F/k lost per half swing, stops for ever at the first
  turning point within F/k): the stop's position and the creep over the last second;
- friction_pendulum: a rod with dry friction in its hinge (stops where the exact energy balance says);
- four_bar: a parallelogram closed by a connect (elliptic period; the loop's closure error);
- coupling: two hinges tied 1:1 by a joint equality (their difference);
- limbs: a humanoid-like tree whose reference pose lies outside its ranges (how far any joint stays past a stop).

`soft` (a dict) sets MuJoCo's softness in the file: solreflimit, solimplimit, solreffriction, solimpfriction on the
joints' default class, solref and solimp on the equalities' (benchmarks/constraints_vs_mujoco.py sweeps them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipk, ellipkinc

G = 9.81


def _soft(soft: dict | None) -> tuple[str, str]:
    """(joint attributes, equality attributes) of MuJoCo's softness settings."""
    soft = soft or {}
    joint = " ".join(f'{k}="{v}"' for k, v in soft.items() if k.startswith(("solreflimit", "solimplimit",
                                                                            "solreffriction", "solimpfriction")))
    equality = " ".join(f'{k}="{v}"' for k, v in soft.items() if k in ("solref", "solimp"))
    return joint, equality


def _document(body: str, soft: dict | None, equality: str = "", extra_default: str = "", custom: str = "") -> str:
    joint, eq = _soft(soft)
    return (f'<mujoco><compiler angle="radian"/><option><flag contact="disable"/></option>{custom}'
            f'<default><joint {joint} {extra_default}/><equality {eq}/></default>'
            f'<worldbody>{body}</worldbody>{equality}</mujoco>')


def rod_along(mass: float, length: float, axis: str = "-z") -> str:
    """A thin rod's exact inertial (the closed forms' m L^2/12 about its centre) and a geom to draw it."""
    moment = repr(mass * length**2 / 12)
    pos, end, diag = {"-z": (f"0 0 {-length / 2!r}", f"0 0 {-length!r}", f"{moment} {moment} 1e-9"),
                      "x": (f"{length / 2!r} 0 0", f"{length!r} 0 0", f"1e-9 {moment} {moment}")}[axis]
    return (f'<inertial pos="{pos}" mass="{mass!r}" diaginertia="{diag}"/>'
            f'<geom type="capsule" fromto="0 0 0 {end}" size="0.01" contype="0" conaffinity="0"/>')


ROD = rod_along(1.0, 1.0)


def _rod_pendulum_period_terms(theta0: float) -> tuple[float, float]:
    """(w0, k^2) of the thin rod (1 kg, 1 m) about its end, released from theta0."""
    return math.sqrt(3 * G / 2), math.sin(theta0 / 2) ** 2


# ----- the cases -------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Case:
    """One hard case: its MJCF (xml(soft) -> str), duration [s] and measure(t (T,), qpos (T, nq), sites (T, s, 3)
    or None, error (T,) rbody's loop error or None) -> {metric: divergence from the closed form}."""

    name: str
    xml: Callable[[dict | None], str]
    t_end: float
    measure: Callable
    summary: str


def limit_pendulum_xml(soft=None, restitution: float = 0.0) -> str:
    custom = (f'<custom><numeric name="rbody.restitution" data="{restitution}"/></custom>' if restitution else "")
    return _document(f'<body name="rod"><joint name="h" axis="0 1 0" range="-0.5 2"/>{ROD}</body>', soft,
                     custom=custom)


THETA0, STOP = 1.0, 0.5


def _impact_time() -> float:
    w0, k2 = _rod_pendulum_period_terms(THETA0)
    return _impact_time_to(-STOP)


def _time_from_rest(amplitude: float, theta: float) -> float:
    """Time [s] the rod released at rest from -amplitude takes to rise to theta (-amplitude <= theta <= amplitude)."""
    w0, k2 = _rod_pendulum_period_terms(amplitude)
    return (ellipk(k2) - ellipkinc(math.asin(max(-1.0, min(1.0, math.sin(-theta / 2) / math.sqrt(k2)))), k2)) / w0


def _upward_crossing(t, x, level, after) -> float:
    """The first time after `after` at which the samples x rise through level, by the cubic through the four samples
    around it (so that the sampling adds only O(dt^4) to what is measured)."""
    i = np.flatnonzero((t[:-1] >= after) & (x[:-1] < level) & (x[1:] >= level))
    if i.size == 0:
        return math.inf
    i = int(i[0])
    window = slice(max(i - 1, 0), min(i + 3, len(t)))
    cubic = np.polynomial.Polynomial.fit(t[window] - t[i], x[window] - level, min(3, len(t[window]) - 1))
    roots = [r.real for r in cubic.roots() if abs(r.imag) < 1e-12 and -1e-12 <= r.real <= t[i + 1] - t[i] + 1e-12]
    linear = (level - x[i]) / (x[i + 1] - x[i]) * (t[i + 1] - t[i])
    return float(t[i] + (min(roots, key=lambda r: abs(r - linear)) if roots else linear))


def _peak(t, x, mask) -> float:
    """The largest value of x over the samples in mask, refined by the parabola through its sample and neighbours."""
    index = np.flatnonzero(mask)
    i = int(index[np.argmax(x[index])])
    if i == 0 or i == len(x) - 1:
        return float(x[i])
    a, b, c = x[i - 1], x[i], x[i + 1]
    curvature = a - 2 * b + c
    return float(b - (c - a) ** 2 / (8 * curvature)) if curvature < 0 else float(b)


REBOUND_LEVEL = -STOP + 0.05  # [rad] the rod's way back up, measured here


def measure_limit(t, qpos, sites=None, error=None, elastic=False) -> dict:
    """past the stop: the largest excursion beyond it; rebound time: when the rod passes REBOUND_LEVEL on its way back
    up (rigid: e = 0, from rest at the stop; e = 1, the fall reversed); then the swing after (e = 0: exactly STOP) or
    the rebound's height (e = 1: exactly theta0)."""
    theta = qpos[:, 0]
    t1 = _impact_time()
    if elastic:
        exact = 2 * t1 - (_impact_time_to(REBOUND_LEVEL))
    else:
        exact = t1 + _time_from_rest(STOP, REBOUND_LEVEL)
    out = {"past the stop [rad]": max(float(np.max(-STOP - theta)), 0.0),
           "rebound time [s]": abs(_upward_crossing(t, theta, REBOUND_LEVEL, t1 - 0.05) - exact)}
    after = t > t1 + 0.1
    if elastic:
        window = after & (t < 3 * t1)
        out["rebound height [rad]"] = abs(_peak(t, theta, window) - THETA0)
    else:
        out["swing after [rad]"] = abs(_peak(t, theta, after) - STOP)
    return out


def _impact_time_to(theta: float) -> float:
    """Time [s] the rod released at rest from THETA0 takes to fall to theta."""
    w0, k2 = _rod_pendulum_period_terms(THETA0)
    return (ellipk(k2) - ellipkinc(math.asin(math.sin(theta / 2) / math.sin(THETA0 / 2)), k2)) / w0


def oscillator_xml(soft=None) -> str:
    return _document('<body name="block"><joint name="x" type="slide" axis="1 0 0" stiffness="50" '
                     'frictionloss="3"/><inertial pos="0 0 0" mass="2" diaginertia="0.01 0.01 0.01"/></body>', soft)


OSC_X0 = 1.0


def oscillator_stop() -> float:
    reach, x = 3.0 / 50.0, OSC_X0
    while abs(x) > reach:
        x = -(x - 2 * reach * math.copysign(1.0, x))
    return x


def measure_oscillator(t, qpos, sites=None, error=None) -> dict:
    x = qpos[:, 0]
    last = t >= t[-1] - 1.0
    return {"stop [m]": abs(float(x[-1]) - oscillator_stop()), "creep in the last second [m]": float(np.ptp(x[last]))}


def friction_pendulum_xml(soft=None) -> str:
    return _document(f'<body name="rod"><joint name="h" axis="0 1 0" frictionloss="{0.3 * G * 0.5}"/>{ROD}</body>',
                     soft)


PEND_THETA0 = 2.5


def friction_pendulum_stop(mass_moment: float = G * 0.5, friction: float = 0.3 * G * 0.5) -> float:
    a = PEND_THETA0
    while mass_moment * abs(math.sin(a)) > friction:
        s, span = math.copysign(1.0, a), 2 * abs(a)
        a = a - s * brentq(lambda u: mass_moment * (math.cos(a - s * u) - math.cos(a)) - friction * u,
                           1e-9 * span, span, xtol=1e-16, rtol=4 * np.finfo(float).eps)
    return a


def measure_friction_pendulum(t, qpos, sites=None, error=None) -> dict:
    theta = qpos[:, 0]
    last = t >= t[-1] - 1.0
    return {"stop [rad]": abs(float(theta[-1]) - friction_pendulum_stop()),
            "creep in the last second [rad]": float(np.ptp(theta[last]))}


FOUR_BAR_THETA0 = 0.6


def four_bar_xml(soft=None) -> str:
    body = ('<body name="crank"><joint name="a" axis="0 1 0"/>'
            f'{ROD}<body name="coupler" pos="0 0 -1"><joint name="b" axis="0 1 0"/>{rod_along(0.5, 0.8, "x")}'
            '<site name="end" pos="0.8 0 0"/></body></body>'
            f'<body name="rocker" pos="0.8 0 0"><joint name="c" axis="0 1 0"/>{ROD}<site name="tip" pos="0 0 -1"/>'
            '</body>')
    return _document(body, soft, '<equality><connect name="loop" body1="coupler" body2="rocker" anchor="0.8 0 0"/>'
                                 '</equality>')


def four_bar_period() -> float:
    m, mc, L = 1.0, 0.5, 1.0
    w0 = math.sqrt((m + mc) * G / ((2 * m / 3 + mc) * L))
    return 4 * ellipk(math.sin(FOUR_BAR_THETA0 / 2) ** 2) / w0


def _periods(t, x) -> np.ndarray:
    i = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))
    crossings = t[i] + x[i] / (x[i] - x[i + 1]) * (t[i + 1] - t[i])
    return np.diff(crossings)


def measure_four_bar(t, qpos, sites=None, error=None) -> dict:
    loop = (float(np.abs(error).max()) if error is not None else
            float(np.linalg.norm(sites[:, 0] - sites[:, 1], axis=-1).max()))
    periods = _periods(t, qpos[:, 0])
    return {"loop error [m]": loop, "period [s]": float(np.abs(periods - four_bar_period()).max())}


def coupling_xml(soft=None) -> str:
    body = (f'<body name="a"><joint name="qa" axis="0 1 0"/>{ROD}</body><body name="b" pos="0.4 0 0">'
            f'<joint name="qb" axis="0 1 0"/>{rod_along(0.5, 0.6)}</body>')
    return _document(body, soft, '<equality><joint joint1="qb" joint2="qa"/></equality>')


def measure_coupling(t, qpos, sites=None, error=None) -> dict:
    return {"coupling error [rad]": float(np.abs(qpos[:, 1] - qpos[:, 0]).max())}


LIMBS = """<mujoco model="limbs">
  <compiler angle="degree"/>
  <option timestep="0.002"><flag contact="disable"/></option>
  <default><joint damping="0.2" frictionloss="0.05"/><geom type="capsule" size="0.04" density="1000"/></default>
  <worldbody>
    <body name="torso" pos="0 0 1.4">
      <geom fromto="0 0 0 0 0 -0.5" size="0.1"/>
      <body name="head" pos="0 0 0.1"><joint name="neck" type="ball" range="0 40"/>
        <geom type="sphere" pos="0 0 0.1" size="0.09"/></body>
      <body name="upper_arm_r" pos="0 -0.2 0" euler="60 0 0"><joint name="shoulder_r" type="ball" range="0 45"/>
        <geom fromto="0 0 0 0 0 -0.3"/>
        <body name="forearm_r" pos="0 0 -0.3"><joint name="elbow_r" axis="0 1 0" range="10 150"/>
          <geom fromto="0 0 0 0 0 -0.25" size="0.035"/></body></body>
      <body name="upper_arm_l" pos="0 0.2 0"><joint name="shoulder_l" type="ball" range="0 90"/>
        <geom fromto="0 0 0 0 0 -0.3"/>
        <body name="forearm_l" pos="0 0 -0.3"><joint name="elbow_l" axis="0 1 0" range="10 150"/>
          <geom fromto="0 0 0 0 0 -0.25" size="0.035"/></body></body>
      <body name="thigh_r" pos="0 -0.1 -0.5"><joint name="hip_r_y" axis="0 1 0" range="-120 20"/>
        <joint name="hip_r_x" axis="1 0 0" range="-30 30"/>
        <geom fromto="0 0 0 0 0 -0.4" size="0.06"/>
        <body name="shin_r" pos="0 0 -0.4"><joint name="knee_r" axis="0 1 0" range="5 150"/>
          <geom fromto="0 0 0 0 0 -0.4" size="0.05"/>
          <body name="foot_r" pos="0 0 -0.4"><joint name="ankle_r" axis="0 1 0" range="-50 -10"/>
            <geom fromto="-0.03 0 0 0.15 0 0" size="0.03"/></body></body></body>
      <body name="thigh_l" pos="0 0.1 -0.5"><joint name="hip_l_y" axis="0 1 0" range="-120 20"/>
        <joint name="hip_l_x" axis="1 0 0" range="-30 30"/>
        <geom fromto="0 0 0 0 0 -0.4" size="0.06"/>
        <body name="shin_l" pos="0 0 -0.4"><joint name="knee_l" axis="0 1 0" range="5 150"/>
          <geom fromto="0 0 0 0 0 -0.4" size="0.05"/>
          <body name="foot_l" pos="0 0 -0.4"><joint name="ankle_l" axis="0 1 0" range="-50 -10"/>
            <geom fromto="-0.03 0 0 0.15 0 0" size="0.03"/></body></body></body>
    </body>
  </worldbody>
</mujoco>"""


def _excursions(t, qpos, xml) -> np.ndarray:
    """(T,) the largest distance [rad] any joint of the file lies past its range at each sample (ball joints: their
    rotation angle past the cone's)."""
    from rbody import from_mjcf

    scene = from_mjcf(xml, overlapping_geoms="sum")
    worst = np.zeros(len(t))
    for name, (low, high) in scene.limits.items():
        j = scene.multibody.joint_names.index(name)
        address = int(scene.multibody.arrays.qposadr[j])
        if scene.multibody.arrays.joint_kinds[j] == "ball":
            quat = qpos[:, address:address + 4]
            value = 2 * np.arctan2(np.linalg.norm(quat[:, 1:], axis=-1), np.abs(quat[:, 0]))
        else:
            value = qpos[:, address]
        worst = np.maximum(worst, np.maximum(low - value, value - high))
    return np.maximum(worst, 0.0)


def measure_limbs(t, qpos, sites=None, error=None) -> dict:
    """past a stop after t = 0 (the rigid limit: round-off), at the end, and how long until every joint is within 1e-3
    rad of its range for good (inf: not within the run; MuJoCo's limits push a joint back over their time constant,
    against the load that holds it there)."""
    past = _excursions(t, qpos, LIMBS)
    outside = np.flatnonzero(past > 1e-3)
    back = 0.0 if outside.size == 0 else (math.inf if outside[-1] == len(t) - 1 else float(t[outside[-1] + 1]))
    return {"past a stop after t = 0 [rad]": float(past[1:].max()), "past a stop at the end [rad]": float(past[-1]),
            "back within 1e-3 rad [s]": back}


CASES: dict[str, Case] = {case.name: case for case in (
    Case("limit_pendulum", lambda soft=None: limit_pendulum_xml(soft), 3.0, measure_limit,
         "a rod onto its stop, e = 0"),
    Case("elastic_limit", lambda soft=None: limit_pendulum_xml(soft or {"solreflimit": "-100000 0"}, 1.0), 3.0,
         lambda *a, **k: measure_limit(*a, **k, elastic=True), "a rod onto its stop, e = 1"),
    Case("friction_oscillator", oscillator_xml, 7.0, measure_oscillator, "a mass on a spring with dry friction"),
    Case("friction_pendulum", friction_pendulum_xml, 10.0, measure_friction_pendulum,
         "a rod with dry friction in its hinge"),
    Case("four_bar", four_bar_xml, 10.0, measure_four_bar, "a parallelogram four-bar closed by a connect"),
    Case("coupling", coupling_xml, 3.0, measure_coupling, "two hinges tied 1:1"),
    Case("limbs", lambda soft=None: _with_soft(LIMBS, soft), 1.0, measure_limbs,
         "a humanoid-like tree whose reference pose lies outside its ranges"),
)}

INITIAL = {"limit_pendulum": [THETA0], "elastic_limit": [THETA0], "friction_oscillator": [OSC_X0],
           "friction_pendulum": [PEND_THETA0], "four_bar": [FOUR_BAR_THETA0, -FOUR_BAR_THETA0, FOUR_BAR_THETA0],
           "coupling": [1.2, 1.2], "limbs": None}


# ----- the runs ----------------------------------------------------------------------------------------------------

def run_mujoco(xml, qpos0, t_end: float, dt: float, integrator: str = "RK4") -> tuple[np.ndarray, ...]:
    """(t (T,), qpos (T, nq), sites (T, nsite, 3), seconds of stepping) of MuJoCo on the file (an XML string, or a
    pathlib.Path whose includes are relative to it) at step dt."""
    import time
    from pathlib import Path

    import mujoco

    model = (mujoco.MjModel.from_xml_path(str(xml)) if isinstance(xml, Path) else mujoco.MjModel.from_xml_string(xml))
    model.opt.timestep = dt
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    data = mujoco.MjData(model)
    if qpos0 is not None:
        data.qpos[:len(qpos0)] = qpos0
    mujoco.mj_forward(model, data)
    steps = int(round(t_end / dt))
    qpos = np.empty((steps + 1, model.nq))
    sites = np.empty((steps + 1, model.nsite, 3))
    qpos[0], sites[0] = data.qpos, data.site_xpos
    start = time.perf_counter()
    for k in range(1, steps + 1):
        mujoco.mj_step(model, data)
        qpos[k] = data.qpos
        sites[k] = data.site_xpos
    return np.arange(steps + 1) * dt, qpos, sites, time.perf_counter() - start


def run_rbody(xml: str, qpos0, t_end: float, dt: float, method: str = "rk4"):
    """(t, qpos, constraint error (T, rows), seconds) of rbody on the same file."""
    import time

    from rbody import from_mjcf, simulate

    scene = from_mjcf(xml, t_end=t_end, qpos0=qpos0)
    start = time.perf_counter()
    run = simulate(scene, dt=dt, method=method)
    return run.t, run["qpos"], run["constraint_error"], time.perf_counter() - start


def _with_soft(xml: str, soft: dict | None) -> str:
    joint, equality = _soft(soft)
    return xml.replace("<default><joint ", f"<default><joint {joint} ", 1) if joint else xml


def divergence(name: str, engine: str, dt: float, soft: dict | None = None, **settings) -> dict:
    """The case's metrics (divergence from its closed form) for `engine` ("rbody" or "mujoco") at step dt."""
    case = CASES[name]
    xml = case.xml(soft)
    qpos0 = INITIAL[name]
    if engine == "mujoco":
        t, qpos, sites, seconds = run_mujoco(xml, qpos0, case.t_end, dt, **settings)
        metrics = case.measure(t, qpos, sites, None)
    else:
        t, qpos, error, seconds = run_rbody(xml, qpos0, case.t_end, dt, **settings)
        metrics = case.measure(t, qpos, None, error if name == "four_bar" else None)
    return {"seconds": seconds, **metrics}


__all__ = ["CASES", "INITIAL", "Case", "divergence", "run_mujoco", "run_rbody", "G"]
