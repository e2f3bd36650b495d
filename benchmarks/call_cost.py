"""The fixed cost of a run: one call that integrates a few steps, rbody against MuJoCo, in the same process.

    python benchmarks/call_cost.py [--repeats 7] [--calls 2000]

Prints the machine and versions, then, for the swinging rod (a hinge) and a 7-link 3-D arm of your own making
(hinges about alternating axes), the cost per call [us] of
- rbody.simulate(scene, dt, method="rk4") for 1 and 100 steps, called again with the same arguments (the
  prepared run is kept with the scene: rbody.prepare);
- rbody.prepare(...).run(), the prepared run alone; and .run(qpos0=...) from a new state (checked);
- the first simulate call with new arguments (prepare + run: every check, the stability estimate);
- MuJoCo's rollout of the same model (rbody.to_mjcf, RK4, contacts off) for 1 and 100 steps, from a state array,
  with a reused Rollout object (its best use) and through the module function.
Each figure: per-call time of a block of --calls calls, the minimum, median and maximum over --repeats blocks
after one warm-up block. Benchmarks are not tests; the load average is printed (the machine may be shared).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mujoco  # noqa: E402
from mujoco import rollout  # noqa: E402

import rbody  # noqa: E402
from rbody import Body, Inertia, Joint, Layout, Scene  # noqa: E402
from rbody.scenes import swinging_rod  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

DT = 1e-3


def arm(links: int = 7) -> Scene:
    """A 3-D arm: rods of 0.3 m hanging along -z, hinges alternately about y and x."""
    bodies, joints = [], []
    for i in range(links):
        parent = "world" if i == 0 else f"link{i - 1}"
        pos = (0.0, 0.0, 0.0) if i == 0 else (0.0, 0.0, -0.3)
        bodies.append(Body(f"link{i}", Inertia.box(1.0, [0.04, 0.04, 0.3]).translated([0, 0, -0.15]), parent=parent, pos=pos))
        joints.append(Joint(f"j{i}", "hinge", f"link{i}", axis=(0, 1, 0) if i % 2 == 0 else (1, 0, 0),
                            qpos0=0.3, damping=0.01))
    return Scene.from_layout(Layout(bodies=tuple(bodies), joints=tuple(joints)), t_end=1.0, name="arm7")


def per_call_us(call, calls: int, repeats: int) -> tuple[float, float, float]:
    """(min, median, max) over `repeats` blocks of `calls` calls of the time per call [us], after a warm-up block."""
    for _ in range(calls):
        call()
    blocks = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        blocks.append((time.perf_counter() - start) / calls * 1e6)
    return min(blocks), statistics.median(blocks), max(blocks)


def first_call_us(scene_factory, steps: int, repeats: int) -> tuple[float, float, float]:
    """simulate on a scene never run before (prepare's checks, stability estimate, native model, bound loop)."""
    times = []
    for _ in range(repeats):
        scene = scene_factory()
        start = time.perf_counter()
        rbody.simulate(scene, dt=DT, method="rk4", t_end=steps * DT)
        times.append((time.perf_counter() - start) * 1e6)
    return min(times), statistics.median(times), max(times)


def mujoco_calls(scene: Scene, steps: int):
    model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = DT
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0) if model.nkey else None
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros((1, mujoco.mj_stateSize(model, kind)))
    mujoco.mj_getState(model, data, state[0], kind)
    reused = rollout.Rollout(nthread=0)
    return (lambda: reused.rollout(model, data, state, nstep=steps)), (lambda: rollout.rollout(model, data, state,
                                                                                                 nstep=steps))


def row(label: str, figures: tuple[float, float, float], reference: float | None = None) -> str:
    ratio = f"   {figures[0] / reference:5.2f}x MuJoCo" if reference else ""
    return f"  {label:<48} {figures[0]:9.2f} {figures[1]:9.2f} {figures[2]:9.2f}{ratio}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--calls", type=int, default=2000)
    args = parser.parse_args()
    print(describe_machine())
    print(f"mujoco {mujoco.__version__}\n")
    factories = {"swinging rod (hinge)": lambda: swinging_rod(1.0, theta0=1.0, t_end=1.0),
                 "7-link 3-D arm (hinges)": arm}
    for name, factory in factories.items():
        scene = factory()
        print(f"{name}: per call [us]                            min    median       max")
        for steps in (1, 100):
            reused, module = mujoco_calls(scene, steps)
            mj = per_call_us(reused, args.calls, args.repeats)
            calls = max(args.calls // steps, 20)
            sim = per_call_us(lambda: rbody.simulate(scene, dt=DT, method="rk4", t_end=steps * DT), calls,
                              args.repeats)
            prepared = rbody.prepare(scene, dt=DT, method="rk4", t_end=steps * DT)
            run = per_call_us(prepared.run, calls, args.repeats)
            print(row(f"{steps} step(s): MuJoCo rollout (Rollout reused)", mj))
            print(row(f"{steps} step(s): MuJoCo rollout.rollout()", per_call_us(module, calls, args.repeats)))
            print(row(f"{steps} step(s): rbody.simulate, repeated", sim, mj[0]))
            print(row(f"{steps} step(s): rbody.prepare(...).run()", run, mj[0]))
            if hasattr(scene, "native_start"):
                qpos = np.asarray(scene.qpos0) * 0.5
                start = per_call_us(lambda: prepared.run(qpos0=qpos), max(calls // 10, 20), args.repeats)
                print(row(f"{steps} step(s): .run(qpos0=...), a new state", start, mj[0]))
            print(row(f"{steps} step(s): first simulate of a new scene", first_call_us(factory, steps, args.repeats)))
        print()


if __name__ == "__main__":
    main()
