"""The engine-core issue's speed goals, each measured beside MuJoCo (and Pinocchio) in one run.

    python benchmarks/engine_core_speed.py [--repeats 7] [--sections steps,aba,batch,first]

Prints the machine, its load and the versions, then
1. steps: rk4, us per step of one scene, rbody's compiled loop (the model rbody.from_mjcf reads) against MuJoCo's
   RK4 (mujoco.rollout, one state, contacts and constraints disabled, the same MJCF text), on the models of
   benchmarks/robots.py: a 27-dof humanoid, random 3-D chains of 8 and 32 links, a 7-dof arm, a hand on an arm
   (30 dof), two arms with hands (60 dof). Goal: MuJoCo / rbody >= 3.
2. aba: one forward-dynamics evaluation, us: rbody's right-hand side (tree_rhs: kinematics, passive forces and
   the articulated-body algorithm) per evaluation inside a compiled loop over 256 states, against Pinocchio's
   pin.aba per call through its Python binding (pin.buildModelFromMJCF of the same file), with the largest
   difference of the two accelerations on hinge-only models (pin.aba given rbody's passive forces as tau).
   Goal: Pinocchio / rbody >= 3.
3. batch: ns per element-step of an rk4 batch on all numba threads against MuJoCo's rollout of the same batch
   on as many threads (one MjData per thread): 10^5 double pendulums (goal >= 25x) and 1,024 copies of the 7-dof
   arm (goal >= 3x).
4. first: seconds from `import rbody` to the first trajectory in a fresh process, with an empty numba cache
   (NUMBA_CACHE_DIR set to a new folder) and again warm: a new 3-D tree (3 links, hinges about skew axes) and a
   built-in scene (the swinging rod); the numba compilations of the cold runs, longest first (a compile-event
   listener, numba.core.event). Goals: new tree < 8 s, built-in scene < 3 s, warm < 1 s. Then a scene with
   contacts (a sphere thrown sliding on a plane, the constraint layer's time-stepping), warm only: a second fresh
   process on the caller's numba cache.

Timing: rbody and its peer are timed alternately, `--repeats` times each after a warm-up; a figure is the
minimum and the spread is (median - min) / min over the repeats. The machine may be shared (the load average is
printed before and after): compare the figures of one run with each other, not with another run's.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import mujoco  # noqa: E402
import numba  # noqa: E402
from mujoco import rollout  # noqa: E402
from numba import njit  # noqa: E402

import rbody  # noqa: E402
from rbody.engine import integrators  # noqa: E402
from rbody.engine import multibody as mb  # noqa: E402
from robots import MODELS, arm  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

DT = 1e-3


# ----- timing ---------------------------------------------------------------------------------------------

def alternate(functions: dict, repeats: int) -> dict:
    """{name: (min, spread)} of the wall time [s] of each function, called in turn `repeats` times after a
    warm-up each (alternating, so that a change in the machine's load touches all of them alike)."""
    for f in functions.values():
        f()
    times = {name: [] for name in functions}
    for _ in range(repeats):
        for name, f in functions.items():
            start = time.perf_counter()
            f()
            times[name].append(time.perf_counter() - start)
    return {name: (min(t), (float(np.median(t)) - min(t)) / min(t)) for name, t in times.items()}


def figure(value: float, spread: float, unit: float = 1e6, width: int = 8) -> str:
    return f"{value * unit:{width}.2f} (+{100 * spread:3.0f}%)"


def load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def print_header() -> None:
    import pinocchio

    print(f"machine    {describe_machine()}; numba threads {numba.get_num_threads()}; load avg {load()}")
    print(f"versions   python {platform.python_version()}  numpy {np.__version__}  numba {numba.__version__}  "
          f"mujoco {mujoco.__version__}  pinocchio {pinocchio.__version__}")


# ----- the peers --------------------------------------------------------------------------------------------

def mujoco_rollout(xml: str, batch_states: np.ndarray | None = None, threads: int = 1):
    """(run(nstep), model): MuJoCo RK4 from the model's initial state (or from each row of batch_states, qpos and
    qvel), contacts and constraints off, through mujoco.rollout on `threads` threads."""
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = DT
    datas = [mujoco.MjData(model) for _ in range(threads)]
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, datas[0], state, kind)
    if batch_states is None:
        initial = state[None]
    else:
        initial = np.tile(state, (batch_states.shape[0], 1))
        initial[:, 1:1 + model.nq + model.nv] = batch_states  # FULLPHYSICS: time, qpos, qvel, ...
    outputs = {}

    def run(nstep: int):
        if nstep not in outputs:
            outputs[nstep] = np.empty((initial.shape[0], nstep, initial.shape[1]))
        rollout.rollout(model, datas if threads > 1 else datas[0], initial, nstep=nstep, state=outputs[nstep],
                        skip_checks=False)
    return run, model


def rbody_loop(native, nstep: int):
    """run(): rk4 over nstep steps of a native model's batch, the compiled loop alone (saving the last state)."""
    bound = integrators.bind_rk4(native.rhs, native.y0.shape[0], DT, nstep, nstep, finish=native.finish,
                                 lanes=native.rhs_lanes)  # as simulate binds it
    y0, params = np.ascontiguousarray(native.y0), np.ascontiguousarray(native.params)
    out = np.empty((2,) + y0.shape)
    return lambda: bound(y0, params, out)


# ----- 1. steps ---------------------------------------------------------------------------------------------

def section_steps(repeats: int) -> None:
    print("\n1. rk4, us per step of one scene (dt = 1e-3 s); rbody: the compiled loop; MuJoCo: rollout, one thread")
    print(f"   {'model':30s} {'nv':>3s}   {'rbody':>15s}   {'MuJoCo RK4':>15s}   MuJoCo/rbody (goal >= 3)")
    for name, make in MODELS.items():
        xml = make()
        scene = rbody.from_mjcf(xml, t_end=1.0)
        native = scene.native_model
        nv = scene.multibody.nv
        nstep = max(200, int(20000 / nv))
        ours = rbody_loop(native, nstep)
        theirs, _ = mujoco_rollout(xml)
        t = alternate({"rbody": ours, "mujoco": lambda: theirs(nstep)}, repeats)
        (a, sa), (b, sb) = t["rbody"], t["mujoco"]
        print(f"   {name:30s} {nv:3d}   {figure(a / nstep, sa)}   {figure(b / nstep, sb)}   {b / a:6.2f}")


# ----- 2. one evaluation against pin.aba --------------------------------------------------------------------

@njit  # not cached: numba's cache would keep a tree_rhs compiled before an edit of the engine
def _evaluations(rhs_states, p, out, repeat):
    for _ in range(repeat):
        for b in range(rhs_states.shape[0]):
            mb.tree_rhs(rhs_states[b], p, out[b])


def section_aba(repeats: int) -> None:
    import pinocchio as pin

    print("\n2. forward dynamics, us per evaluation: rbody tree_rhs in a compiled loop over 256 states; "
          "pin.aba per call through its binding")
    print(f"   {'model':30s} {'nv':>3s}   {'rbody':>15s}   {'pin.aba':>15s}   pin/rbody (goal >= 3)   max |qacc diff|")
    rng = np.random.default_rng(0)
    for name, make in MODELS.items():
        xml = make()
        scene = rbody.from_mjcf(xml, t_end=1.0)
        model = scene.multibody
        native = scene.native_model
        count = 256
        q = np.tile(model.qpos0, (count, 1))
        scalar = [k in ("hinge", "slide") for k in model.arrays.joint_kinds]
        for j, (kind, qa) in enumerate(zip(model.arrays.joint_kinds, model.arrays.qposadr)):
            if scalar[j]:
                q[:, qa] += rng.uniform(-1, 1, count)
            elif kind == "free":
                quat = rng.normal(size=(count, 4))
                q[:, qa + 3:qa + 7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        v = rng.uniform(-1, 1, (count, model.nv))
        y = np.zeros((count, native.y0.shape[1]))
        y[:, :model.nq], y[:, model.nq:model.nq + model.nv] = q, v
        p = np.ascontiguousarray(native.params[0])
        out = np.empty_like(y)
        ours = lambda: _evaluations(y, p, out, 20)  # noqa: E731

        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "model.xml")
            Path(path).write_text(xml)
            pm = pin.buildModelFromMJCF(path)
        pd = pm.createData()
        qp = q.copy()
        for j, kind in enumerate(model.arrays.joint_kinds):  # pin's free joint: (x, y, z, qx, qy, qz, qw), v local
            if kind == "free":
                qa = model.arrays.qposadr[j]
                qp[:, qa + 3:qa + 7] = q[:, [qa + 4, qa + 5, qa + 6, qa + 3]]
        tau = model.passive_forces(q, v)
        rows = [(np.ascontiguousarray(qp[i]), np.ascontiguousarray(v[i]), np.ascontiguousarray(tau[i]))
                for i in range(count)]

        def theirs():
            for qi, vi, ti in rows:
                pin.aba(pm, pd, qi, vi, ti)

        t = alternate({"rbody": ours, "pin": theirs}, repeats)
        (a, sa), (b, sb) = t["rbody"], t["pin"]
        a, b = a / (20 * count), b / count
        difference = "-"
        if all(scalar):
            theirs_qacc = np.array([pin.aba(pm, pd, qi, vi, ti).copy() for qi, vi, ti in rows])
            difference = f"{np.max(np.abs(theirs_qacc - out[:, model.nq:model.nq + model.nv])):.1e}"
        print(f"   {name:30s} {model.nv:3d}   {figure(a, sa)}   {figure(b, sb)}   {b / a:8.2f}              "
              f"{difference}")


# ----- 3. batches -------------------------------------------------------------------------------------------

def section_batch(repeats: int) -> None:
    threads = numba.get_num_threads()
    print(f"\n3. rk4 batches, ns per element-step, {threads} threads each (rbody: numba threads; MuJoCo: rollout with "
          f"{threads} MjData)")
    rng = np.random.default_rng(1)
    count = 100_000
    theta = rng.uniform(-1, 1, (count, 2))
    pendulum = rbody.scenes.pendulum_chain(2, theta0=theta, t_end=1.0)
    tree = rbody.Scene.from_layout(pendulum.item(0).layout, t_end=1.0,
                                   qpos0=np.column_stack([theta[:, 0], theta[:, 1] - theta[:, 0]]))
    xml_pendulum = rbody.to_mjcf(pendulum.item(0), dt=DT, integrator="RK4")
    arm_xml = arm(7)
    arm_scene = rbody.from_mjcf(arm_xml, t_end=1.0)
    arms = 1024
    arm_q = arm_scene.multibody.qpos0 + rng.uniform(-1, 1, (arms, 7))
    arm_batch = rbody.Scene.from_layout(arm_scene.layout, t_end=1.0, qpos0=arm_q)
    cases = (("10^5 double pendulums", tree, xml_pendulum, 10, 25),
             ("1,024 seven-dof arms", arm_batch, arm_xml, 20, 3))
    print(f"   {'batch':25s}   {'rbody':>15s}   {'MuJoCo rollout':>15s}   MuJoCo/rbody   goal")
    for name, scene, xml, nstep, goal in cases:
        native = scene.native_model
        ours = rbody_loop(native, nstep)
        nq = native.y0.shape[1] // 2 if scene.multibody.nrot == 0 else None
        states = np.ascontiguousarray(native.y0[:, :2 * nq])
        theirs, _ = mujoco_rollout(xml, states, threads)
        t = alternate({"rbody": ours, "mujoco": lambda: theirs(nstep)}, repeats)
        (a, sa), (b, sb) = t["rbody"], t["mujoco"]
        per = 1e9 / (nstep * native.y0.shape[0])
        print(f"   {name:25s}   {figure(a, sa, per)}   {figure(b, sb, per)}   {b / a:10.1f}   >= {goal}")


# ----- 4. first result ----------------------------------------------------------------------------------------

FIRST = textwrap.dedent("""
    import json, sys, time
    start = time.perf_counter()
    from numba.core import event
    compiles = []

    class Listener(event.Listener):
        def on_start(self, e):
            self.begin = getattr(self, "begin", {}); self.begin[id(e.data["dispatcher"])] = time.perf_counter()
        def on_end(self, e):
            d = e.data["dispatcher"]
            compiles.append((getattr(d, "__qualname__", str(d)), time.perf_counter() - self.begin.get(id(d), 0)))

    event.register("numba:compile", Listener())
    import numpy as np
    import rbody
    imported = time.perf_counter() - start
    if sys.argv[1] == "tree":
        from rbody import Body, Inertia, Joint, Layout
        bodies, joints = [], []
        for i in range(3):
            bodies.append(Body(f"b{i}", Inertia(1.0, np.array([0.0, 0.0, -0.2]), np.diag([0.02, 0.03, 0.01])),
                               parent="world" if i == 0 else f"b{i - 1}", pos=(0.0, 0.0, 0.0 if i == 0 else -0.4)))
            joints.append(Joint(f"j{i}", "hinge", f"b{i}", axis=(1.0, 0.3 * i, 0.2), qpos0=0.3))
        scene = rbody.Scene.from_layout(Layout(bodies=tuple(bodies), joints=tuple(joints)), t_end=0.01)
    elif sys.argv[1] == "contact":  # a sphere thrown sliding on a plane: the constraint layer's time-stepping
        from rbody import Body, Contact, Inertia, Joint, Layout, Shape
        ball = Body("ball", Inertia.solid_sphere(1.0, 0.1), shapes=(Shape("s", "sphere", (0.1,)),), pos=(0, 0, 0.1))
        layout = Layout(bodies=(ball,), joints=(Joint("free", "free", "ball"),),
                        fixed=(Shape("floor", "plane", (0, 0)),), contacts=(Contact("floor", "s", friction=0.3),))
        scene = rbody.Scene.from_layout(layout, t_end=0.1, qvel0=[2.0, 0, 0, 0, 0, 0])
    else:
        scene = rbody.scenes.swinging_rod(1.0, theta0=1.0, t_end=0.01)
    if sys.argv[1] == "contact":
        rbody.simulate(scene, dt=1e-2)["ball.com"]
    else:
        run = rbody.simulate(scene, dt=1e-3, method="rk4")
        run["qpos" if sys.argv[1] == "tree" else "theta"]
    total = time.perf_counter() - start
    print(json.dumps({"import": imported, "total": total, "compiles": sorted(compiles, key=lambda c: -c[1])[:8]}))
""")


def first_result(kind: str, cache: str | None) -> dict:
    """The FIRST script's figures in a fresh process with the numba cache `cache` (None: the caller's own)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT)) if cache is None else dict(os.environ, NUMBA_CACHE_DIR=cache,
                                                                              PYTHONPATH=str(ROOT))
    result = subprocess.run([sys.executable, "-c", FIRST, kind], env=env, capture_output=True, text=True, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def section_first() -> None:
    print("\n4. first result: seconds from `import rbody` to the first trajectory, fresh processes")
    for kind, label, goal in (("tree", "a new 3-D tree (3 hinges)", 8.0), ("scene", "the swinging rod", 3.0)):
        with tempfile.TemporaryDirectory() as cache:
            cold = first_result(kind, cache)
            warm = first_result(kind, cache)
        print(f"   {label:28s} empty cache {cold['total']:6.2f} s (import {cold['import']:.2f} s; goal < {goal:g})   "
              f"warm {warm['total']:5.2f} s (goal < 1)")
        print("      longest compilations: " + ", ".join(f"{n.split('.')[-1]} {s:.2f} s" for n, s in cold["compiles"][:6]))
    # a scene with contacts, warm only (from an empty cache the constraint layer compiles for minutes): the caller's
    # cache, filled by a first process where it is not yet, then timed in a second
    first_result("contact", None)
    warm = first_result("contact", None)
    print(f"   {'a sphere rolling (contacts)':28s} warm {warm['total']:5.2f} s (import {warm['import']:.2f} s); "
          f"compilations: " + (", ".join(f"{n.split('.')[-1]} {s:.2f} s" for n, s in warm["compiles"][:6])
                                         or "none"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--sections", default="steps,aba,batch,first")
    args = parser.parse_args()
    print_header()
    sections = args.sections.split(",")
    if "steps" in sections:
        section_steps(args.repeats)
    if "aba" in sections:
        section_aba(args.repeats)
    if "batch" in sections:
        section_batch(args.repeats)
    if "first" in sections:
        section_first()
    print(f"\nload avg after: {load()}")


if __name__ == "__main__":
    main()
