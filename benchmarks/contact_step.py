"""The cost of one contact step: rbody's compiled Moreau-Jean loop against MuJoCo's step, scene by scene, with the
heap allocations of rbody's step (the overhead that does no arithmetic).

    PYTHONPATH=$PWD python benchmarks/contact_step.py [--repeats 7] [--steps 2000] [--other CHECKOUT]

Prints the machine, its load and the versions, then per scene: rbody's cost per step [us] (min / median / max over
--repeats runs of --steps steps: stepping.moreau_loop called directly, every state kept, after one untimed warm-up
run), its heap allocations per step (numba's runtime counters), and MuJoCo's cost per step on the same scene
(rbody.to_mjcf for the sweep's scenes, the MJCF text itself for the figure and the gripper; its defaults, Euler,
mujoco.rollout on one thread, every state kept) at the same dt, and the ratio of the two minima.
Scenes: the contact sweep's (benchmarks/contact_sweep.py) sphere thrown sliding on a plane, box at rest on an
incline, stack of five boxes, at dt = 1e-2 s, and the stack again at the sweep's coarsest step, 0.1 s ("stack_0.1",
where rbody rests to round-off and MuJoCo's defaults, their time constant run as 2 dt, let it sink: a cost only);
its standing humanoid figure and parallel gripper at dt = 2e-3 s; "layer", 64 spheres at rest on a floor side by side
(an 8 x 8 grid, 384 dofs, 64 contacts, each apart from the others: the cost of many bodies) at dt = 1e-2 s.
--other CHECKOUT: rbody's figures also for that checkout of the repository (a subprocess with it first on the path,
its own numba cache), the two measured in alternation, repeat by repeat, and the ratio of their minima printed.
Benchmarks are not tests: the machine may be shared (the load average is printed); compare figures of one run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("sphere", "incline", "stack", "stack_0.1", "figure", "gripper", "layer")
DT = {"sphere": 1e-2, "incline": 1e-2, "stack": 1e-2, "stack_0.1": 0.1, "figure": 2e-3, "gripper": 2e-3, "layer": 1e-2}
LAYER_SIDE = 8  # the layer's spheres per side


def layer_xml(side: int = LAYER_SIDE, radius: float = 0.1) -> str:
    """side x side spheres of 1 kg resting on a floor, 3 radii apart (MJCF; MuJoCo's defaults)."""
    bodies = "".join(f'<body name="s{i}" pos="{3 * radius * (i % side)} {3 * radius * (i // side)} {radius}">'
                     f'<freejoint/><geom type="sphere" size="{radius}" mass="1"/></body>' for i in range(side * side))
    return f'<mujoco><worldbody><geom type="plane" size="10 10 0.1"/>{bodies}</worldbody></mujoco>'


def _scene(name: str):
    """(rbody Scene, MJCF text for MuJoCo) of the named scene."""
    import contact_sweep as sweep
    import rbody

    if name in ("figure", "gripper", "layer"):
        xml = {"figure": sweep.humanoid_xml, "gripper": sweep.gripper_xml, "layer": layer_xml}[name]()
        return rbody.from_mjcf(xml, t_end=1.0), xml
    scene = getattr(sweep, f"{name.split('_')[0]}_scene")(1.0)  # (stack_0.1: the stack, at its own dt)
    return scene, rbody.to_mjcf(scene, integrator="Euler", solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001))


def timed_loop(scene, dt: float, steps: int, name: str):
    """(once, out, table): once() runs stepping.moreau_loop over `steps` steps of the scene from its start, every
    state into out (steps + 1, n), and returns its seconds (SimulationError where a step fails)."""
    import rbody
    from rbody.engine.constraints import stepping

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the figure's AccuracyWarning (its stiffest mode): not measured here
        model = rbody.prepare(scene, dt=dt, method="moreau").model
    table = model.constraints
    run = stepping.MoreauRun(table, np.asarray(model.params)[0], name, "moreau")
    y0 = np.array(np.asarray(model.y0)[0], dtype=np.float64)
    out = np.empty((steps + 1, y0.size))

    def once() -> float:
        problem_rows = np.zeros(table.rows + 1, dtype=np.int64)
        start = time.perf_counter()
        failed = stepping.moreau_loop(run.p, y0, dt, steps, 1, out, stepping.EXACT_ROWS, stepping.PGS_SWEEPS,
                                      stepping.STEP_TOLERANCE, problem_rows, run.mode)[0]
        seconds = time.perf_counter() - start
        if failed >= 0:
            raise rbody.SimulationError(f"{name}: step {failed} failed")
        return seconds

    return once, out, table


def rbody_costs(steps: int, repeats: int, scenes=SCENES) -> dict:
    """{scene: {"seconds": [per run], "allocations": per step}}: moreau_loop over `steps` steps, `repeats` runs."""
    from numba.core.runtime import _nrt_python, rtsys

    results = {}
    for name in scenes:
        scene, _xml = _scene(name)
        once, _out, _table = timed_loop(scene, DT[name], steps, name)
        once()  # compiles, or loads the cache
        _nrt_python.memsys_enable_stats()  # numba's counters of its runtime's allocations
        before = rtsys.get_allocation_stats().alloc
        seconds = [once() for _ in range(repeats)]
        allocations = (rtsys.get_allocation_stats().alloc - before) / (repeats * steps)
        results[name] = {"seconds": seconds, "allocations": allocations}
    return results


def mujoco_costs(steps: int, repeats: int) -> dict:
    """{scene: [seconds per run]}: mujoco.rollout of the same scene at its defaults, `steps` steps, one thread."""
    import mujoco
    from mujoco import rollout

    results = {}
    for name in SCENES:
        _scene_, xml = _scene(name)
        model = mujoco.MjModel.from_xml_string(xml)
        model.opt.timestep = DT[name]
        data = mujoco.MjData(model)
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, 0)
        kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
        initial = np.empty(mujoco.mj_stateSize(model, kind))
        mujoco.mj_getState(model, data, initial, kind)
        states = np.empty((1, steps, initial.size))
        runner = rollout.Rollout(nthread=0)
        runner.rollout(model, data, initial[None], nstep=steps, state=states)  # warm-up
        seconds = []
        for _ in range(repeats):
            start = time.perf_counter()
            runner.rollout(model, data, initial[None], nstep=steps, state=states)
            seconds.append(time.perf_counter() - start)
        results[name] = seconds
    return results


def _other(checkout: Path, steps: int) -> dict:
    """rbody_costs of one run in a subprocess with `checkout` first on the path (its numba cache its own)."""
    env = {name: value for name, value in os.environ.items() if name != "NUMBA_CACHE_DIR"}  # its own cache:
    env["PYTHONPATH"] = str(checkout)                                                        # its __pycache__
    code = "\n".join([
        "import sys, json",
        f"sys.path.insert(0, {str(checkout)!r})",
        "import rbody  # before contact_sweep, which puts this file's checkout first on the path",
        f"if not rbody.__file__.startswith({str(checkout)!r}):",
        "    raise SystemExit(f'rbody imported from {rbody.__file__}, not from the checkout given')",
        f"sys.path.insert(1, {str(ROOT / 'benchmarks')!r})",
        f"sys.path.append({str(ROOT / 'tests' / 'rbody' / 'engine')!r})",
        "import contact_step",
        f"print(json.dumps(contact_step.rbody_costs({steps}, 1)))"])
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the run of {checkout} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _us(seconds, steps: int) -> str:
    v = np.array(seconds) / steps * 1e6
    return f"{v.min():.2f} / {np.median(v):.2f} / {v.max():.2f}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--other", type=Path, default=None, help="another checkout of rbody, measured alongside")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.steps < 1:
        raise ValueError(f"repeats={args.repeats}, steps={args.steps}: expected positive counts")
    if args.other is not None and not (args.other / "rbody" / "__init__.py").is_file():
        raise ValueError(f"other={str(args.other)!r}: not a checkout of rbody (no rbody/__init__.py there)")
    sys.path.insert(0, str(ROOT / "benchmarks"))
    sys.path.append(str(ROOT / "tests" / "rbody" / "engine"))
    import contact_sweep as sweep
    import mujoco

    for line in sweep.header():
        print(line)
    print(f"steps per run {args.steps}, repeats {args.repeats}; rbody: stepping.moreau_loop, every state kept; "
          "MuJoCo: its defaults (Euler), mujoco.rollout, one thread, every state kept")
    mine = rbody_costs(args.steps, args.repeats)
    peer = mujoco_costs(args.steps, args.repeats)
    other = None
    if args.other is not None:
        other = {name: {"seconds": [], "allocations": 0.0} for name in SCENES}
        for _ in range(args.repeats):  # in alternation with this checkout's runs (each a run of every scene)
            for name, value in _other(args.other, args.steps).items():
                other[name]["seconds"].extend(value["seconds"])
                other[name]["allocations"] = value["allocations"]
            for name, value in rbody_costs(args.steps, 1).items():
                mine[name]["seconds"].extend(value["seconds"])
    print()
    head = "| scene | dt [s] | rbody [us/step] min / median / max | rbody allocations per step |"
    rule = "|---|---|---|---|"
    if other is not None:
        head += f" {args.other} [us/step] | its allocations per step | this / other (minima) |"
        rule += "---|---|---|"
    head += f" MuJoCo {mujoco.__version__} defaults [us/step] | rbody / MuJoCo (minima) |"
    rule += "---|---|"
    print(head)
    print(rule)
    for name in SCENES:
        row = (f"| {name} | {DT[name]:g} | {_us(mine[name]['seconds'], args.steps)} | "
               f"{mine[name]['allocations']:.1f} |")
        if other is not None:
            row += (f" {_us(other[name]['seconds'], args.steps)} | {other[name]['allocations']:.1f} | "
                    f"{min(mine[name]['seconds']) / min(other[name]['seconds']):.2f} |")
        row += f" {_us(peer[name], args.steps)} | {min(mine[name]['seconds']) / min(peer[name]):.2f} |"
        print(row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
