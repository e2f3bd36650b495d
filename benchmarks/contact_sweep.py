"""MuJoCo's contact settings swept as error against cost on contact scenes with closed forms, rbody (rigid limit)
beside them; and the cost per step of a standing humanoid figure and of a gripper holding a box (issue 22).

    PYTHONPATH=$PWD python benchmarks/contact_sweep.py [--quick] [--repeats 3] [--figure docs/contact_sweep.png]
                                                        [--csv FILE] [--skip-sweep] [--skip-costs]

Prints the machine, its load and the package versions, then
1. the sweep. Scenes (the ones of tests/rbody/engine/test_contact_closed_forms.py, imported, exported to MuJoCo by
   rbody.to_mjcf so that both engines run the same bodies, pairs and initial state):
   - sphere: a sphere (r = 0.1 m) thrown sliding at v0 = 2 m/s without spin, mu = 0.3: error in the rolling speed
     |v(t_end) - 5/7 v0| [m/s] and in the time the slip v - r w falls below 1e-3 v0 (closed form
     t* - 1e-3 v0 / (7/2 mu g), t* = 2 v0 / (7 mu g); the slip linearly interpolated between samples) [s];
   - incline: a box on a plane tilted alpha = 0.3 rad, just inside the friction cone, mu = tan(alpha)(1 + 1e-3):
     the largest displacement of its centre over t_end [m] (closed form 0);
   - stack: five boxes stacked on a floor: the largest sinking (fall of a box's centre) and horizontal drift of any
     box over t_end [m] (closed form 0 for both), the error being the larger of the two.
   MuJoCo (Euler, its default integrator; solimp 0.9 0.95 0.001 and solref "timeconst 1" on every pair, its
   defaults) over every combination of solver (Newton, CG, PGS), cone (pyramidal, elliptic), impratio (1, 10, 100),
   noslip_iterations (0, 10), solref's time constant (0.02, 0.002) and the step dt (DTS, 0.1 to 1e-4 s: the
   coarsest steps are where an exact scheme's cost is least); MuJoCo runs a time constant below 2 dt as 2 dt, so
   of those at or below 2 dt only the largest is run (the same run), labelled with the 2 dt it ran at. rbody: method
   "moreau" over the same dts, and the event-driven "rk4" (dt its sampling interval) on the sphere and the
   incline at the two coarsest.
   Cost: wall time per simulated second [s/s], the minimum over --repeats timed runs (runs shorter than
   SHORT_SECONDS repeated until they add up to it, at most SHORT_REPEATS times) (the stepping loop with the
   keeping of every state for MuJoCo, mujoco.rollout on one thread; the whole simulate() call for
   rbody, after one untimed warm-up per scene and method, which compiles), with the spread (max - min) / min.
   A point predicted (from the previous, coarser one) to take more than MAX_RUN_SECONDS is not run, and says so.
   Printed: per scene and error level, the cheapest MuJoCo setting reaching it and the cheapest rbody run, their
   costs and ratio; per MuJoCo family (solver, cone), its smallest error (its floor on this grid).
2. the costs: a standing humanoid figure (HUMANOID, this file's own model: 12 bodies, a free torso, 18 hinges with
   ranges and springs, capsule feet on a floor plane) and a parallel gripper holding a box (GRIPPER: two box pads
   on slide joints pushed by their joint springs, a free box held by friction), 1 s at dt = 2 ms: cost per step
   (min / median / max over --repeats runs) of rbody (moreau) and MuJoCo (defaults, and its cheapest setting at
   that dt that keeps the figure's torso within STILL_TOLERANCE of where it started, or the box's slip within
   SLIP_TOLERANCE), with how far the torso moved and how far the box slipped in each.

--quick: the sphere, incline and stack over two dts, t_end 0.5 s, a smaller MuJoCo grid, one timed run, no
figure unless --figure is given; finishes in well under a minute once numba's cache is warm.
Benchmarks are not tests: the machine may be shared (the load average is printed); compare figures of one run.
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import platform
import re
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.append(str(ROOT / "tests" / "rbody" / "engine"))  # last: its helper modules shadow nothing

import mujoco  # noqa: E402
from mujoco import rollout  # noqa: E402
import numba  # noqa: E402

import rbody  # noqa: E402
from rbody import Scene, from_mjcf, to_mjcf  # noqa: E402
from rbody.files import atomic_path, write_atomic  # noqa: E402
from rbody.motion import quat_to_matrix  # noqa: E402
from test_contact_closed_forms import G, ball_layout, incline, stack_layout  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

DTS = {False: (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4), True: (1e-2, 1e-3)}
T_END = {False: {"sphere": 1.0, "incline": 2.0, "stack": 2.0}, True: {"sphere": 0.5, "incline": 0.5, "stack": 0.5}}
SOLVERS = {False: ("Newton", "CG", "PGS"), True: ("Newton", "PGS")}
CONES = ("pyramidal", "elliptic")
IMPRATIOS = {False: (1.0, 10.0, 100.0), True: (1.0, 100.0)}
NOSLIPS = (0, 10)
TIMECONSTS = {False: (0.02, 0.002), True: (0.02,)}
LEVELS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10, 1e-12)
MAX_RUN_SECONDS = {False: 30.0, True: 3.0}
ZERO_DRAWN_AT = 1e-17  # an error of exactly 0 is drawn here on the log axes

V0, MU_SPHERE, RADIUS = 2.0, 0.3, 0.1
ALPHA, CONE_MARGIN = 0.3, 1e-3
SLIP_THRESHOLD = 1e-3 * V0  # [m/s] the slip below which the sphere counts as rolling, for the time of rolling


# ----- settings and results ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MujocoSetting:
    """One point of MuJoCo's contact settings (integrator Euler throughout)."""

    solver: str = "Newton"
    cone: str = "pyramidal"
    impratio: float = 1.0
    noslip: int = 0
    timeconst: float = 0.02

    @property
    def family(self) -> str:
        return f"{self.solver} {self.cone}"

    @property
    def label(self) -> str:
        return f"{self.solver} {self.cone} impratio {self.impratio:g} noslip {self.noslip} tc {self.timeconst:g}"

    def label_at(self, dt: float) -> str:
        """The label of the run at step dt: a time constant below 2 dt as MuJoCo runs it (2 dt)."""
        if self.timeconst >= 2 * dt:
            return self.label
        return f"{self.label} (run as 2 dt = {2 * dt:g})"

    def apply(self, model: mujoco.MjModel, dt: float) -> None:
        model.opt.timestep = dt
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
        model.opt.solver = getattr(mujoco.mjtSolver, f"mjSOL_{self.solver.upper()}")
        model.opt.cone = getattr(mujoco.mjtCone, f"mjCONE_{self.cone.upper()}")
        model.opt.impratio = self.impratio
        model.opt.noslip_iterations = self.noslip
        if model.npair:
            model.pair_solref[:, 0] = self.timeconst
            model.pair_solref[:, 1] = 1.0
        model.geom_solref[:, 0] = self.timeconst
        model.geom_solref[:, 1] = 1.0


DEFAULTS = MujocoSetting()


def mujoco_grid(quick: bool) -> list[MujocoSetting]:
    return [MujocoSetting(*values) for values in itertools.product(
        SOLVERS[quick], CONES, IMPRATIOS[quick], NOSLIPS, TIMECONSTS[quick])]


@dataclass
class Row:
    """One run of the sweep: errors by measure, cost per simulated second [s/s] (min over repeats) and spread."""

    scene: str
    engine: str          # "mujoco" or "rbody"
    family: str          # MuJoCo: "solver cone"; rbody: its method
    setting: str
    dt: float
    errors: dict = field(default_factory=dict)
    cost: float = math.nan
    spread: float = math.nan
    repeats: int = 0
    failure: str = ""


# ----- the scenes and their measures --------------------------------------------------------------------------------

@dataclass(frozen=True)
class Case:
    name: str
    scene: Callable[[float], Scene]          # t_end -> Scene
    measures: Callable[[dict], dict]         # samples -> {measure: error}
    primary: tuple[str, ...]                  # the measures plotted and tabled
    event_driven: bool                        # rbody's rk4 applies


def sphere_scene(t_end: float) -> Scene:
    return Scene.from_layout(ball_layout(RADIUS, 0.0, MU_SPHERE), t_end=t_end, qvel0=[V0, 0, 0, 0, 0, 0])


def sphere_measures(run: dict) -> dict:
    """speed: |v(t_end) - 5/7 v0| [m/s]; t_star: error of the time the slip falls below SLIP_THRESHOLD [s] (inf if
    it never does); sink: the largest fall of the centre below r [m].

    The time is read from the sliding samples: the line through the last two samples above the threshold, carried
    to it. The slip falls linearly while the sphere slides and stops at 0 with a kink at t*, within 2e-4 s of the
    threshold's crossing: a line between the last sliding sample and the first rolling one (the reading before)
    cuts that kink, and read the closed form itself, sampled every 3e-3 or 1e-2 s, 7.6e-4 or 5.6e-3 s late. With
    a single sample above the threshold, or where the slip did not fall between the last two (a soft contact's
    slip may stall before it drops), the line between the last sample above it and the first below it."""
    t, v, w = run["t"], run["v"][:, 0], run["w"][:, 1]
    slip = v - RADIUS * w
    below = np.flatnonzero(np.abs(slip) <= SLIP_THRESHOLD)
    exact = (V0 - SLIP_THRESHOLD) / (3.5 * MU_SPHERE * G)
    if below.size == 0:
        t_cross = math.inf
    elif below[0] == 0:
        t_cross = float(t[0])
    else:
        k = below[0]
        first = k - 2 if k >= 2 and abs(slip[k - 2]) > abs(slip[k - 1]) else k - 1  # the line's samples
        s0, s1 = abs(slip[first]), abs(slip[first + 1])
        t_cross = float(t[first] + (t[first + 1] - t[first]) * (s0 - SLIP_THRESHOLD) / (s0 - s1))
    return {"speed": abs(float(v[-1]) - 5 / 7 * V0), "t_star": abs(t_cross - exact),
            "sink": max(0.0, float(np.max(RADIUS - run["qpos"][:, 2])))}


def incline_scene(t_end: float) -> Scene:
    layout, _ = incline(math.tan(ALPHA) * (1 + CONE_MARGIN), ALPHA)
    return Scene.from_layout(layout, t_end=t_end)


def incline_measures(run: dict) -> dict:
    """creep: the largest displacement of the box's centre from where it started [m] (closed form 0)."""
    com = run["qpos"][:, :3]
    return {"creep": float(np.max(np.linalg.norm(com - com[0], axis=1)))}


def stack_scene(t_end: float) -> Scene:
    return Scene.from_layout(stack_layout(), t_end=t_end)


def stack_measures(run: dict) -> dict:
    """sink: the largest fall of any box's centre [m]; drift: its largest horizontal displacement [m]; rest: the
    larger of the two (closed form 0 for all)."""
    qpos = run["qpos"]
    boxes = qpos.shape[1] // 7
    z = qpos[:, [7 * k + 2 for k in range(boxes)]]
    xy = np.stack([qpos[:, 7 * k:7 * k + 2] for k in range(boxes)], axis=1)
    sink = max(0.0, float(np.max(z[0] - z)))
    drift = float(np.max(np.linalg.norm(xy - xy[0], axis=-1)))
    return {"rest": max(sink, drift), "sink": sink, "drift": drift}


CASES = (Case("sphere", sphere_scene, sphere_measures, ("speed", "t_star"), True),
         Case("incline", incline_scene, incline_measures, ("creep",), True),
         Case("stack", stack_scene, stack_measures, ("rest",), False))
UNITS = {"speed": "m/s", "t_star": "s", "creep": "m", "rest": "m", "sink": "m", "drift": "m"}
WHAT = {("sphere", "speed"): "sphere thrown sliding: rolling speed 5/7 v0",
        ("sphere", "t_star"): "sphere thrown sliding: time rolling starts",
        ("incline", "creep"): "block on an incline, mu = tan(alpha)(1 + 1e-3): creep (0)",
        ("stack", "rest"): "five boxes stacked: sinking and drift (0)"}


# ----- running MuJoCo -----------------------------------------------------------------------------------------------

def mujoco_model(scene: Scene) -> mujoco.MjModel:
    """The scene as MuJoCo compiles it from rbody.to_mjcf: the same bodies, pairs and initial state (keyframe 0),
    MuJoCo's default solimp and solref on every pair."""
    xml = to_mjcf(scene, integrator="Euler", solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001))
    return mujoco.MjModel.from_xml_string(xml)


def world_omega(qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """(T, 3) world-frame angular velocity of the first free joint from MuJoCo's body-frame one [rad/s]."""
    return np.einsum("tij,tj->ti", quat_to_matrix(qpos[:, 3:7]), qvel[:, 3:6])


def mujoco_rollout(model: mujoco.MjModel, data: mujoco.MjData, steps: int, keyframe: int | None = 0):
    """(seconds, qpos (steps + 1, nq), qvel (steps + 1, nv)): `steps` steps from the keyframe (or from qpos0 at rest)
    through mujoco.rollout (the stepping loop in C, one thread, every state kept); seconds is the rollout's wall
    time."""
    if keyframe is None:
        mujoco.mj_resetData(model, data)
    else:
        mujoco.mj_resetDataKeyframe(model, data, keyframe)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, initial, kind)
    states = np.empty((1, steps, initial.size))
    start = time.perf_counter()
    rollout.rollout(model, data, initial[None], nstep=steps, state=states)
    seconds = time.perf_counter() - start
    path = np.concatenate([initial[None], states[0]])  # FULLPHYSICS: time, qpos, qvel, ...
    qpos, qvel = path[:, 1:1 + model.nq], path[:, 1 + model.nq:1 + model.nq + model.nv]
    if np.any(np.diff(path[:, 0]) <= 0):
        # MuJoCo met a bad acceleration and reset the state to qpos0 (its autoreset): the run failed; poison it so
        # that it is reported as non-finite rather than measured as a body back at its start
        qpos = np.full_like(qpos, np.nan)
    return seconds, qpos, qvel


SHORT_SECONDS = 0.05  # runs shorter than this are repeated until they add up to it (at most SHORT_REPEATS times)
SHORT_REPEATS = 30   # (a run of 0.2 to 3 ms: its minimum over three calls moved by half between two sweeps)


def repeat(run: Callable[[], tuple], repeats: int, budget: float = 2.0) -> tuple[list[float], tuple]:
    """Call run() (which returns (seconds, *result)) up to `repeats` times, stopping once `budget` seconds of them
    have been spent (at least once); where more than one run is asked for, short runs more often, until they add up
    to SHORT_SECONDS or SHORT_REPEATS are taken (both engines' points alike); the seconds of each call and the first
    result."""
    seconds, first = [], None
    while (not seconds or sum(seconds) < budget) and (
            len(seconds) < repeats
            or (repeats > 1 and len(seconds) < SHORT_REPEATS and sum(seconds) < SHORT_SECONDS)):
        out = run()
        seconds.append(out[0])
        if first is None:
            first = out[1:]
    return seconds, first


def spread_of(seconds: Sequence[float]) -> float:
    return (max(seconds) - min(seconds)) / min(seconds) if min(seconds) > 0 else math.nan


def clamped_duplicate(timeconst: float, dt: float, timeconsts: Sequence[float]) -> float | None:
    """The grid's larger time constant whose run at step dt this one's is (MuJoCo runs any time constant below 2 dt
    as 2 dt: the same run as one at 2 dt or below it), or None where this one is run: at or above 2 dt, or the
    largest of those below with none at 2 dt."""
    if timeconst >= 2 * dt:
        return None
    larger = [other for other in timeconsts if timeconst < other <= 2 * dt]
    return max(larger) if larger else None


def mujoco_point(case: Case, model, data, setting: MujocoSetting, dt: float, t_end: float, repeats: int,
                 timeconsts: Sequence[float] = TIMECONSTS[False]) -> Row:
    row = Row(case.name, "mujoco", setting.family, setting.label_at(dt), dt)
    same = clamped_duplicate(setting.timeconst, dt, timeconsts)
    if same is not None:
        row.failure = f"not run: the run of tc {same:g} (MuJoCo runs both as 2 dt = {2 * dt:g})"
        return row
    setting.apply(model, dt)
    steps = int(round(t_end / dt))
    with np.errstate(all="ignore"):
        seconds, (qpos, qvel) = repeat(lambda: mujoco_rollout(model, data, steps), repeats)
    if not (np.all(np.isfinite(qpos)) and np.all(np.isfinite(qvel))):
        row.failure = "unstable: non-finite acceleration (MuJoCo reset the state)"
        return row
    samples = {"t": np.arange(steps + 1) * dt, "qpos": qpos, "v": qvel[:, :3], "w": world_omega(qpos, qvel)}
    row.errors = case.measures(samples)
    row.cost, row.spread, row.repeats = min(seconds) / t_end, spread_of(seconds), len(seconds)
    return row


# ----- running rbody ------------------------------------------------------------------------------------------------

def rbody_samples(run) -> dict:
    """The measures' samples of an rbody run: t, qpos, and the first body's velocity and angular velocity (world)."""
    bodies = [name[:-len(".velocity")] for name in run.data if name.endswith(".velocity")]
    return {"t": run.t, "qpos": run["qpos"], "v": run[f"{bodies[0]}.velocity"], "w": run[f"{bodies[0]}.omega"]}


def rbody_timed(scene: Scene, dt: float, method: str, save_every: int = 1):
    """(seconds, trajectory) of one simulate() call, its AccuracyWarning silenced (the error is measured here)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        run = rbody.simulate(scene, dt=dt, method=method, save_every=save_every)
        return time.perf_counter() - start, run


def rbody_series(case: Case, method: str, dts: Sequence[float], t_end: float, repeats: int, quick: bool) -> list[Row]:
    scene = case.scene(t_end)
    rows: list[Row] = []
    try:
        rbody_timed(scene, dts[0], method)  # warm-up: compiles, fills caches
    except Exception:  # noqa: BLE001 - the point itself reports it
        pass
    previous = None  # (dt, seconds of one run)
    for dt in dts:
        row = Row(case.name, "rbody", method, method, dt)
        rows.append(row)
        if previous is not None and previous[1] * previous[0] / dt > MAX_RUN_SECONDS[quick]:
            row.failure = f"not run: predicted {previous[1] * previous[0] / dt:.0f} s > {MAX_RUN_SECONDS[quick]:g} s"
            continue
        try:
            seconds, (run,) = repeat(lambda: rbody_timed(scene, dt, method), repeats)
        except (ValueError, RuntimeError, ArithmeticError) as error:  # SimulationError is a RuntimeError
            row.failure = f"{type(error).__name__}: {str(error).splitlines()[0][:160]}"
            continue
        previous = (dt, min(seconds))
        row.errors = case.measures(rbody_samples(run))
        row.cost, row.spread, row.repeats = min(seconds) / t_end, spread_of(seconds), len(seconds)
    return rows


# ----- the sweep ---------------------------------------------------------------------------------------------------

def sweep(quick: bool, repeats: int, log=sys.stdout) -> list[Row]:
    rows: list[Row] = []
    grid = mujoco_grid(quick)
    for case in CASES:
        t_end = T_END[quick][case.name]
        started = time.perf_counter()
        model = mujoco_model(case.scene(t_end))
        data = mujoco.MjData(model)
        for setting in grid:
            for dt in DTS[quick]:
                rows.append(mujoco_point(case, model, data, setting, dt, t_end, repeats, TIMECONSTS[quick]))
        print(f"  {case.name}: MuJoCo, {len(grid)} settings x {len(DTS[quick])} dts, "
              f"{time.perf_counter() - started:.1f} s", file=log, flush=True)
        methods = ("moreau", "rk4") if case.event_driven else ("moreau",)
        for method in methods:
            started = time.perf_counter()
            dts = DTS[quick] if method == "moreau" else DTS[quick][:2]
            rows += rbody_series(case, method, dts, t_end, repeats, quick)
            print(f"  {case.name}: rbody {method}, {time.perf_counter() - started:.1f} s", file=log, flush=True)
    return rows


def cheapest(rows: Sequence[Row], scene: str, measure: str, engine: str, level: float) -> Row | None:
    """The cheapest run of `engine` on `scene` whose `measure` error is at most `level` (None when none is)."""
    fits = [r for r in rows if r.engine == engine and r.scene == scene and not r.failure
            and measure in r.errors and r.errors[measure] <= level]
    return min(fits, key=lambda r: r.cost) if fits else None


def floor_of(rows: Sequence[Row], scene: str, measure: str, engine: str, family: str | None = None) -> Row | None:
    """The run with the smallest `measure` error (ties: the cheapest)."""
    fits = [r for r in rows if r.engine == engine and r.scene == scene and not r.failure and measure in r.errors
            and (family is None or r.family == family)]
    return min(fits, key=lambda r: (r.errors[measure], r.cost)) if fits else None


def cost_cell(row: Row) -> str:
    """The cost [s/s] with its spread over the repeats, or "1 run" when it was timed once."""
    return f"{row.cost:.3g} " + (f"(+{100 * row.spread:.0f}%)" if row.repeats > 1 else "(1 run)")


def level_table(rows: Sequence[Row]) -> list[str]:
    """Per scene and measure, each error level some MuJoCo run reaches: the cheapest MuJoCo setting reaching it and
    the cheapest rbody run reaching it, their costs and ratio; then one row for the levels below MuJoCo's floor on
    the grid (none of its runs reaches them), with rbody's cheapest run there."""
    lines = ["| scene: measure | error level | cheapest MuJoCo setting reaching it (dt): its error | MuJoCo cost [s/s] "
             "| cheapest rbody run (dt): its error | rbody cost [s/s] | rbody / MuJoCo |",
             "|---|---|---|---|---|---|---|"]

    def cell(row: Row | None, measure: str, label: str) -> tuple[str, str]:
        if row is None:
            return "none reaches it", "-"
        return f"{label} ({row.dt:g}): {row.errors[measure]:.2g}", cost_cell(row)

    for case in CASES:
        for measure in case.primary:
            name = f"{case.name}: {measure} [{UNITS[measure]}]"
            for level in LEVELS:
                theirs = cheapest(rows, case.name, measure, "mujoco", level)
                ours = cheapest(rows, case.name, measure, "rbody", level)
                if theirs is None:
                    floor = floor_of(rows, case.name, measure, "mujoco")
                    below = f"below MuJoCo's floor ({floor.errors[measure]:.2g})" if floor else "MuJoCo: no run"
                    mj = cell(None, measure, "")
                    rb = cell(ours, measure, ours.family if ours else "")
                    lines.append(f"| {name} | {level:g} and below: {below} | {mj[0]} | {mj[1]} | {rb[0]} | {rb[1]} "
                                 f"| - |")
                    break
                mj, rb = cell(theirs, measure, theirs.setting), cell(ours, measure, ours.family if ours else "")
                ratio = f"{ours.cost / theirs.cost:.2g}" if ours else "-"
                lines.append(f"| {name} | {level:g} | {mj[0]} | {mj[1]} | {rb[0]} | {rb[1]} | {ratio} |")
    return lines


def floor_table(rows: Sequence[Row]) -> list[str]:
    """Per scene and measure: each MuJoCo family's smallest error (its floor on this grid), with the setting and its
    cost, and rbody's smallest and its cost."""
    families = sorted({r.family for r in rows if r.engine == "mujoco"})
    lines = ["| scene: measure | engine, family | smallest error | at (dt) | cost [s/s] | MuJoCo defaults at dt = 1e-3 |",
             "|---|---|---|---|---|---|"]
    for case in CASES:
        for measure in case.primary:
            name = f"{case.name}: {measure} [{UNITS[measure]}]"
            default = [r for r in rows if r.scene == case.name and r.setting == DEFAULTS.label and r.dt == 1e-3
                       and not r.failure]
            at_default = f"{default[0].errors[measure]:.2g}" if default else "-"
            for engine, family in [("mujoco", f) for f in families] + [("rbody", "moreau"), ("rbody", "rk4")]:
                best = floor_of(rows, case.name, measure, engine, family)
                if best is None:
                    continue
                lines.append(f"| {name} | {engine} {family} | {best.errors[measure]:.2g} | {best.setting} "
                             f"({best.dt:g}) | {cost_cell(best)} | {at_default} |")
    return lines


def failures(rows: Sequence[Row]) -> list[str]:
    """One line per (scene, engine, reason) of the points not run or failed, with their count."""
    counted: dict[tuple, int] = {}
    for r in rows:
        if r.failure:
            key = (r.scene, r.engine, r.failure)
            counted[key] = counted.get(key, 0) + 1
    return [f"- {scene}, {engine}: {why} ({n} points)" for (scene, engine, why), n in sorted(counted.items())]


def write_csv(rows: Sequence[Row], path: Path) -> None:
    measures = sorted({m for r in rows for m in r.errors})
    lines = [",".join(["scene", "engine", "family", "setting", "dt", *measures, "cost", "spread", "repeats",
                       "failure"])]
    for r in rows:
        lines.append(",".join([r.scene, r.engine, r.family, r.setting, f"{r.dt:g}",
                               *(f"{r.errors[m]:.6g}" if m in r.errors else "" for m in measures),
                               f"{r.cost:.6g}", f"{r.spread:.3g}", str(r.repeats), r.failure.replace(",", ";")]))
    write_atomic(path, "\n".join(lines) + "\n")


# ----- the figure --------------------------------------------------------------------------------------------------

MARKERS = {"Newton": "o", "CG": "s", "PGS": "^"}
COLORS = {"pyramidal": "tab:blue", "elliptic": "tab:orange"}


def figure(rows: Sequence[Row], path: Path) -> None:
    """Error against cost per scene and measure, log-log: each MuJoCo family (solver by marker, cone by colour,
    every impratio, noslip, time constant and dt of it), rbody's moreau and rk4 as lines over dt."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(case, measure) for case in CASES for measure in case.primary]
    columns = 2
    fig, axes = plt.subplots(math.ceil(len(panels) / columns), columns, figsize=(11, 4.6 * math.ceil(len(panels) / 2)),
                             squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax, (case, measure) in zip(axes.flat, panels):
        for family in sorted({r.family for r in rows if r.engine == "mujoco"}):
            solver, cone = family.split()
            pts = [r for r in rows if r.scene == case.name and r.engine == "mujoco" and r.family == family
                   and not r.failure and math.isfinite(r.errors.get(measure, math.nan))]
            if pts:
                ax.scatter([r.cost for r in pts], [max(r.errors[measure], ZERO_DRAWN_AT) for r in pts], s=14,
                           marker=MARKERS[solver], facecolors="none", edgecolors=COLORS[cone], linewidths=0.8,
                           label=f"MuJoCo {family}")
        for method, style in (("moreau", "k-"), ("rk4", "r--")):
            pts = sorted((r for r in rows if r.scene == case.name and r.engine == "rbody" and r.family == method
                          and not r.failure and math.isfinite(r.errors.get(measure, math.nan))), key=lambda r: r.cost)
            if pts:
                ax.plot([r.cost for r in pts], [max(r.errors[measure], ZERO_DRAWN_AT) for r in pts], style,
                        marker="D", ms=4, lw=1.5, label=f"rbody {method}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cost: wall time per simulated second [s/s]")
        ax.set_ylabel(f"error [{UNITS[measure]}]")
        ax.set_title(WHAT[(case.name, measure)], fontsize=9)
        ax.grid(True, which="major", alpha=0.3)
    axes.flat[0].legend(fontsize=7, loc="center left")
    fig.suptitle(f"MuJoCo {mujoco.__version__} contact settings (solver, cone, impratio, noslip, timeconst, dt) "
                 f"against rbody; an error of 0 is drawn at {ZERO_DRAWN_AT:g}", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as temporary:
        fig.savefig(temporary, format="png", dpi=110)
    plt.close(fig)


# ----- 2. the humanoid figure and the gripper ----------------------------------------------------------------------

HUMANOID = """<mujoco model="standing_figure">
  <!-- rbody's own standing figure (benchmarks/contact_sweep.py): a free torso with a head, an abdomen, two legs of
       thigh, shin and foot, two arms of upper and lower arm with a hand; hinges with ranges, and joint springs
       (stiffness about qpos0) that hold the upright pose; each foot two capsules lying on a floor plane. Only the
       floor touches the figure (floor contype 1 conaffinity 0, the figure's geoms contype 0 conaffinity 1). -->
  <option timestep="0.002"/>
  <default>
    <joint type="hinge" stiffness="500" damping="5" armature="0.01" limited="true" range="-0.8 0.8"/>
    <geom type="capsule" friction="1" density="1000" contype="0" conaffinity="1"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" contype="1" conaffinity="0"/>
    <body name="torso" pos="0 0 1.115">
      <freejoint name="root"/>
      <geom name="chest" fromto="0 -0.08 0.05 0 0.08 0.05" size="0.08"/>
      <geom name="head" type="sphere" pos="0 0 0.27" size="0.1"/>
      <body name="abdomen" pos="0 0 -0.15">
        <joint name="abdomen_y" axis="0 1 0"/>
        <joint name="abdomen_x" axis="1 0 0" range="-0.5 0.5"/>
        <geom name="belly" fromto="0 -0.07 0 0 0.07 0" size="0.075"/>
        {legs}
      </body>
      {arms}
    </body>
  </worldbody>
</mujoco>"""
LEG = """<body name="thigh_{s}" pos="0 {y} -0.12">
          <joint name="hip_x_{s}" axis="1 0 0" range="-0.6 0.6"/>
          <joint name="hip_y_{s}" axis="0 1 0" range="-1.5 0.5"/>
          <geom name="thigh_{s}" fromto="0 0 -0.02 0 0 -0.34" size="0.06"/>
          <body name="shin_{s}" pos="0 0 -0.42">
            <joint name="knee_{s}" axis="0 1 0" range="-0.1 2.4"/>
            <geom name="shin_{s}" fromto="0 0 -0.02 0 0 -0.32" size="0.05"/>
            <body name="foot_{s}" pos="0 0 -0.4">
              <joint name="ankle_y_{s}" axis="0 1 0"/>
              <joint name="ankle_x_{s}" axis="1 0 0" range="-0.5 0.5"/>
              <geom name="sole_{s}_a" fromto="-0.06 -0.035 0 0.12 -0.035 0" size="0.025"/>
              <geom name="sole_{s}_b" fromto="-0.06 0.035 0 0.12 0.035 0" size="0.025"/>
            </body>
          </body>
        </body>"""
ARM = """<body name="upper_arm_{s}" pos="0 {y} 0.06">
        <joint name="shoulder_x_{s}" axis="1 0 0" range="-1.2 1.2" stiffness="100" damping="2"/>
        <joint name="shoulder_y_{s}" axis="0 1 0" range="-1.5 1.5" stiffness="100" damping="2"/>
        <geom name="upper_arm_{s}" fromto="0 {a} -0.02 0 {b} -0.26" size="0.04"/>
        <body name="lower_arm_{s}" pos="0 {b} -0.3">
          <joint name="elbow_{s}" axis="0 1 0" range="-2.2 0.1" stiffness="30" damping="1"/>
          <geom name="lower_arm_{s}" fromto="0 0 -0.02 0 0 -0.24" size="0.032"/>
          <geom name="hand_{s}" type="sphere" pos="0 0 -0.32" size="0.04"/>
        </body>
      </body>"""


def humanoid_xml() -> str:
    """The standing figure: 12 bodies, nq = 25, nv = 24 (a free root and 18 hinges), about 35 kg, the soles' lowest
    points on the floor at qpos0 (torso at 1.115 m)."""
    legs = "".join(LEG.format(s=s, y=0.1 * k) for s, k in (("left", 1), ("right", -1)))
    arms = "".join(ARM.format(s=s, y=0.17 * k, a=0.02 * k, b=0.04 * k) for s, k in (("left", 1), ("right", -1)))
    return HUMANOID.format(legs=legs, arms=arms)


GRIPPER = """<mujoco model="parallel_gripper">
  <!-- rbody's own gripper (benchmarks/contact_sweep.py): two fingers (box pads 2 x 8 x 8 cm) on slide joints along
       x, each pushed inwards by its joint spring (springref {pre} m past the contact: a position servo of gain {k}
       N/m and damping {c} N s/m, squeezing with {squeeze} N), holding a free box of {mass} kg (8 x 5 x 5 cm) against
       gravity by friction {mu}: it holds when 2 mu squeeze > m g. -->
  <option timestep="0.002"/>
  <worldbody>
    <body name="finger_left" pos="-0.05 0 0.5">
      <joint name="slide_left" type="slide" axis="1 0 0" stiffness="{k}" springref="{pre}" damping="{c}"/>
      <geom name="pad_left" type="box" size="0.01 0.04 0.04" mass="0.2" friction="{mu}"/>
    </body>
    <body name="finger_right" pos="0.05 0 0.5">
      <joint name="slide_right" type="slide" axis="-1 0 0" stiffness="{k}" springref="{pre}" damping="{c}"/>
      <geom name="pad_right" type="box" size="0.01 0.04 0.04" mass="0.2" friction="{mu}"/>
    </body>
    <body name="object" pos="0 0 0.5">
      <freejoint name="object"/>
      <geom name="object" type="box" size="0.04 0.025 0.025" mass="{mass}" friction="{mu}"/>
    </body>
  </worldbody>
</mujoco>"""


def gripper_xml(k: float = 1000.0, pre: float = 0.01, c: float = 20.0, mu: float = 1.0, mass: float = 0.1) -> str:
    """The gripper: k [N/m], pre [m] (squeeze k pre [N]), c [N s/m], mu, the box's mass [kg]. nq = 9 (two slides and
    the box's free joint), the pads touching the box's faces at qpos0."""
    return GRIPPER.format(k=k, pre=pre, c=c, mu=mu, mass=mass, squeeze=k * pre)


STILL_TOLERANCE = 1e-3  # [m] the figure stands still when its torso stays this close to where it started
SLIP_TOLERANCE = 1e-4   # [m] the box is held when it slips less than this in 1 s
COST_DT, COST_T_END = 2e-3, 1.0


def moved(qpos: np.ndarray, column: int) -> float:
    """Largest displacement [m] from its start of the free joint whose position is qpos[:, column:column + 3]
    (qpos: (T, nq), the same order in rbody and MuJoCo)."""
    pos = qpos[:, column:column + 3]
    return float(np.max(np.linalg.norm(pos - pos[0], axis=1)))


def accuracy_note(message: str) -> str:
    """The gist of rbody's AccuracyWarning: the stiffest linearised rate and the step it asks for."""
    found = re.search(r"dt \* w = ([0-9.]+).*?(w = [0-9.]+ rad/s).*?(Use dt <= [0-9.e-]+ s)", message)
    return f"AccuracyWarning: dt w = {found[1]} ({found[2]}); {found[3]}" if found else message[:120]


def model_costs(name: str, xml: str, free_column: int, tolerance: float, repeats: int, quick: bool) -> list[str]:
    """Cost per step [us] (min / median / max) and the free body's largest displacement [m] over COST_T_END at
    COST_DT: rbody moreau, MuJoCo's defaults, MuJoCo's cheapest setting keeping the displacement within tolerance."""
    t_end = 0.2 if quick else COST_T_END
    steps = int(round(t_end / COST_DT))
    lines = []

    def us(seconds):
        v = np.array(seconds) / steps * 1e6
        return f"{v.min():.1f} / {np.median(v):.1f} / {v.max():.1f}"

    try:
        scene = from_mjcf(xml, t_end=t_end)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rbody.simulate(scene, dt=COST_DT, method="moreau")
        note = "; ".join(sorted({accuracy_note(str(w.message)) for w in caught}))
        seconds, (run,) = repeat(lambda: rbody_timed(scene, COST_DT, "moreau"), repeats, budget=30.0)
        lines.append(f"| {name} | rbody moreau | {COST_DT:g} | {us(seconds)} | {moved(run['qpos'], free_column):.2g} | "
                     f"{note or '-'} |")
        steps_run = math.ceil(t_end / COST_DT)
        seconds, _ = repeat(lambda: rbody_timed(scene, COST_DT, "moreau", save_every=steps_run), repeats, budget=30.0)
        lines.append(f"| {name} | rbody moreau, the last state only (save_every = all steps) | {COST_DT:g} | "
                     f"{us(seconds)} | - | the stepping without the observables of every sample |")
    except (ValueError, RuntimeError, ArithmeticError) as error:
        lines.append(f"| {name} | rbody moreau | {COST_DT:g} | refused | - | {type(error).__name__}: "
                     f"{str(error).splitlines()[0][:200]} |")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    results = []
    grid = [DEFAULTS] if quick else [DEFAULTS] + [s for s in _cost_settings() if s != DEFAULTS]
    for setting in grid:
        setting.apply(model, COST_DT)
        seconds, (qpos, _) = repeat(lambda: mujoco_rollout(model, data, steps, keyframe=None), repeats)
        displacement = moved(qpos, free_column) if np.all(np.isfinite(qpos)) else math.inf
        results.append((setting, seconds, displacement))
    default = results[0]
    lines.append(f"| {name} | MuJoCo defaults ({DEFAULTS.label}) | {COST_DT:g} | {us(default[1])} | "
                 f"{default[2]:.2g} | - |")
    held = [r for r in results if r[2] <= tolerance]
    if held:
        best = min(held, key=lambda r: min(r[1]))
        lines.append(f"| {name} | MuJoCo cheapest within {tolerance:g} m ({best[0].label}) | {COST_DT:g} | "
                     f"{us(best[1])} | {best[2]:.2g} | of {len(results)} settings, {len(held)} within |")
    else:
        lines.append(f"| {name} | MuJoCo: no setting within {tolerance:g} m | {COST_DT:g} | - | - | of "
                     f"{len(results)} settings |")
    least = min(results, key=lambda r: (r[2], min(r[1])))
    lines.append(f"| {name} | MuJoCo least displacement ({least[0].label}) | {COST_DT:g} | {us(least[1])} | "
                 f"{least[2]:.2g} | - |")
    return lines


def _cost_settings() -> list[MujocoSetting]:
    """MuJoCo's settings at COST_DT: solver, cone, impratio, noslip, and the time constants 0.02 and 2 COST_DT."""
    return [MujocoSetting(*v) for v in itertools.product(("Newton", "CG", "PGS"), CONES, (1.0, 10.0, 100.0), NOSLIPS,
                                                          (0.02, 2 * COST_DT))]


def costs(repeats: int, quick: bool) -> list[str]:
    lines = ["| model | engine, setting | dt [s] | cost per step [us] min / median / max | largest displacement of "
             "the free body [m] | note |", "|---|---|---|---|---|---|"]
    lines += model_costs("humanoid figure standing (torso)", humanoid_xml(), 0, STILL_TOLERANCE, repeats, quick)
    lines += model_costs("gripper holding a box (box slip)", gripper_xml(), 2, SLIP_TOLERANCE, repeats, quick)
    return lines


# ----- main --------------------------------------------------------------------------------------------------------

def header() -> list[str]:
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return [f"machine    {describe_machine()}; numba threads {numba.get_num_threads()}; load avg {load}",
            f"versions   python {platform.python_version()}  numpy {np.__version__}  numba {numba.__version__}  "
            f"mujoco {mujoco.__version__}  rbody {Path(rbody.__file__).parent}"]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a short run (two dts, a small grid, 0.5 s scenes)")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs per point (default 3, quick 1)")
    parser.add_argument("--figure", type=Path, default=None,
                        help="write the error-against-cost figure here (default docs/contact_sweep.png, none quick)")
    parser.add_argument("--csv", type=Path, default=None, help="write every point of the sweep here")
    parser.add_argument("--skip-sweep", action="store_true")
    parser.add_argument("--skip-costs", action="store_true")
    args = parser.parse_args(argv)
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else 3)
    if repeats < 1:
        raise ValueError(f"--repeats {repeats}: expected at least 1")
    started = time.perf_counter()
    print("\n".join(header()), flush=True)
    if not args.skip_sweep:
        print("\n1. MuJoCo's contact settings against the closed forms, rbody beside them (cost: wall time per "
              "simulated second, min over the repeats, spread (max - min)/min)", flush=True)
        rows = sweep(args.quick, repeats)
        print("\nPer error level: the cheapest run of each engine reaching it")
        print("\n".join(level_table(rows)))
        print("\nEach MuJoCo family's smallest error on the grid (its floor), rbody's beside it")
        print("\n".join(floor_table(rows)))
        print("\nPoints not run or failed:")
        print("\n".join(failures(rows)) or "- none")
        path = args.figure if args.figure is not None else (None if args.quick else ROOT / "docs" / "contact_sweep.png")
        if path is not None:
            figure(rows, path)
            print(f"\nfigure: {path}")
        if args.csv is not None:
            write_csv(rows, args.csv)
            print(f"points: {args.csv}")
    if not args.skip_costs:
        print(f"\n2. Cost per step, {0.2 if args.quick else COST_T_END:g} s at dt = {COST_DT:g} (min / median / max "
              f"over the repeats)", flush=True)
        print("\n".join(costs(repeats, args.quick)))
    print(f"\n({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
