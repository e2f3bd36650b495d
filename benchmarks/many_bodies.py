"""The cost of a contact step as the bodies grow in number: a layer of side x side spheres resting on a floor, each
apart from the others, rbody's compiled Moreau-Jean loop beside MuJoCo's step on the same MJCF text.

    PYTHONPATH=$PWD python benchmarks/many_bodies.py [--sides 4 8 12] [--steps 500] [--repeats 5]

Prints the machine, its load and the versions, then per layer: its bodies, dofs and constraint rows (MuJoCo's
rules make every two spheres a contact pair, each a candidate of 3 rows); rbody's cost per step [us] (min / median
/ max over --repeats runs of --steps steps, stepping.moreau_loop called directly after one untimed run) and its
spheres' largest depth below the floor over the run [m]; MuJoCo's (its defaults, Euler, mujoco.rollout on one
thread) and its spheres' largest depth; the ratio of the two minima; the seconds rbody takes to load the MJCF text
(from_mjcf) and to prepare its run (prepare(): the stability check and the memory estimate among it), and MuJoCo to
compile the same text. Both at dt = 1e-2 s from the spheres' resting heights.
The step's cost grows with the bodies through its dofs (M factored along the tree, rbody.engine.constraints.
tree_factor; each contact's rows on their support beyond 64 dofs, but formed over every dof), its contacts (each its
own island, rbody.engine.constraints.islands) and its contact pairs (the broad phase's pass over them, and the row
arrays sized by every candidate: quadratic in the bodies).
Benchmarks are not tests: the machine may be shared (the load average is printed); compare figures of one run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DT = 1e-2
RADIUS = 0.1


def rbody_layer(side: int, steps: int, repeats: int) -> dict:
    """rbody's seconds per run, sizes, and the largest depth below the floor [m] over the run."""
    import rbody
    from contact_step import layer_xml, timed_loop

    start = time.perf_counter()
    scene = rbody.from_mjcf(layer_xml(side, RADIUS), t_end=steps * DT)
    loaded = time.perf_counter()
    once, out, table = timed_loop(scene, DT, steps, f"layer {side}")  # prepare(): the stability check among it
    prepared = time.perf_counter()
    once()
    seconds = [once() for _ in range(repeats)]
    heights = out[:, 2:7 * side * side:7]  # each free joint's z (qpos: 3 positions, 4 quaternion numbers a body)
    return {"seconds": seconds, "depth": float(max(0.0, np.max(RADIUS - heights))), "nv": scene.multibody.nv,
            "rows": table.rows, "load": loaded - start, "prepare": prepared - loaded}


def mujoco_layer(side: int, steps: int, repeats: int) -> dict:
    """MuJoCo's seconds per run (its defaults) and the largest depth below the floor [m] over the run."""
    import mujoco
    from contact_step import layer_xml
    from mujoco import rollout

    start = time.perf_counter()
    model = mujoco.MjModel.from_xml_string(layer_xml(side, RADIUS))
    model.opt.timestep = DT
    data = mujoco.MjData(model)
    loaded = time.perf_counter() - start
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, initial, kind)
    states = np.empty((1, steps, initial.size))
    runner = rollout.Rollout(nthread=0)
    runner.rollout(model, data, initial[None], nstep=steps, state=states)
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        runner.rollout(model, data, initial[None], nstep=steps, state=states)
        seconds.append(time.perf_counter() - start)
    qpos = states[0, :, 1:1 + model.nq]  # (the full physics state: time first)
    heights = qpos[:, 2::7]
    return {"seconds": seconds, "depth": float(max(0.0, np.max(RADIUS - heights))), "load": loaded}


def _us(seconds, steps: int) -> str:
    v = np.array(seconds) / steps * 1e6
    return f"{v.min():.1f} / {np.median(v):.1f} / {v.max():.1f}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sides", type=int, nargs="+", default=[4, 8, 12])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.steps < 1 or min(args.sides) < 1:
        raise ValueError(f"sides={args.sides}, steps={args.steps}, repeats={args.repeats}: expected positive counts")
    import rbody  # noqa: F401  (first: the checkout on PYTHONPATH, before contact_sweep puts this one first)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import contact_sweep as sweep
    import mujoco

    for line in sweep.header():
        print(line)
    print(f"dt {DT} s, {args.steps} steps a run, {args.repeats} runs; rbody: stepping.moreau_loop; MuJoCo "
          f"{mujoco.__version__}: its defaults (Euler), mujoco.rollout, one thread")
    print()
    print("| spheres | dofs | rbody rows (every candidate) | rbody [us/step] min / median / max | rbody depth [m] | "
          "MuJoCo [us/step] | MuJoCo depth [m] | rbody / MuJoCo (minima) | rbody load, prepare [s] | MuJoCo load [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for side in args.sides:
        mine = rbody_layer(side, args.steps, args.repeats)
        peer = mujoco_layer(side, args.steps, args.repeats)
        print(f"| {side * side} | {mine['nv']} | {mine['rows']} | {_us(mine['seconds'], args.steps)} | "
              f"{mine['depth']:.1e} | {_us(peer['seconds'], args.steps)} | {peer['depth']:.1e} | "
              f"{min(mine['seconds']) / min(peer['seconds']):.1f} | {mine['load']:.3g}, {mine['prepare']:.3g} | "
              f"{peer['load']:.3g} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
