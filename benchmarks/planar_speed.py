"""Cost of the planar fast path (rbody.engine.planar) against the 3-D general engine, rbody's hand-written
kernels and MuJoCo's RK4, all in one run.

    python benchmarks/planar_speed.py [--repeats 3] [--batch 100000]

Prints the machine and versions, then
1. rk4, ns per step, one scene: the swinging rod (one hinge) and N-link chains N = 2, 8, 32: the planar path
   (the kernels TreeScene.native() now picks), the 3-D engine's tree_rhs on the same tree, the hand-written
   kernel (pendulum_rhs, chain_rhs) and MuJoCo RK4 (mujoco.rollout, contacts and constraints disabled, the
   model rbody.to_mjcf writes), each the compiled loop alone; and the rod and the 8-chain through
   rbody.simulate (whole call, observables not evaluated);
2. a batch of double pendulums (default 10^5) in one rk4 call: ns per pendulum-step, planar path, 3-D engine,
   hand chain_rhs, through the compiled loop and through rbody.simulate.
Every figure is the minimum over --repeats runs after a warm-up. Section 1 times the CPU time of this process
(time.process_time: one thread runs a single scene), which a shared machine inflates far less than wall time;
section 2 gives both wall time (all numba threads) and CPU time. Benchmarks are not tests; the machine may be
shared (the load average is printed): compare the figures of one run with each other.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import mujoco  # noqa: E402
import numba  # noqa: E402
from mujoco import rollout  # noqa: E402

import rbody  # noqa: E402
from rbody import Scene  # noqa: E402
from rbody.engine import integrators  # noqa: E402
from rbody.engine import multibody as mb  # noqa: E402
from rbody.engine.planar import planar_rhs  # noqa: E402
from rbody.scenes.pendulum import pendulum_rhs  # noqa: E402
from multibody_speed import DT, chain, mujoco_model  # noqa: E402
from multibody_speed import best as best_wall_or, print_header  # noqa: E402


def best(function, repeats: int, clock=time.process_time) -> float:
    """Minimum time [s] of function() on `clock` (default: CPU time of this process) over `repeats` runs."""
    return best_wall_or(function, repeats, clock)


def mujoco_step_ns(scene, steps: int, repeats: int) -> float:
    """ns per MuJoCo RK4 step (mujoco.rollout, one state), CPU time of this process."""
    model, data = mujoco_model(scene)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, state, kind)
    return best(lambda: rollout.rollout(model, data, state[None], nstep=steps), repeats) / steps * 1e9


def loop_ns(rhs, y0, params, steps: int, repeats: int, clock=time.process_time) -> float:
    """ns per rk4 step of the whole batch (y0 (B, n), params (B, p)), the compiled loop alone."""
    y0, params = np.ascontiguousarray(y0), np.ascontiguousarray(params)
    out = np.empty((2,) + y0.shape)
    seconds = best(lambda: integrators.run_rk4(rhs, y0, params, DT, steps, steps, out), repeats, clock)
    return seconds / steps * 1e9


def three_d(tree) -> tuple[np.ndarray, np.ndarray]:
    """y0, params of the 3-D engine's tree_rhs for a TreeScene without ball or free joints."""
    qpos0, qvel0 = tree._state0()
    return np.concatenate([qpos0, qvel0], axis=1), np.tile(np.asarray(tree.multibody.params), (qpos0.shape[0], 1))


def simulate_ns(scene, steps: int, repeats: int) -> float:
    """ns per step of a whole rbody.simulate call (observables are computed lazily: not included)."""
    return best(lambda: rbody.simulate(scene, dt=DT, t_end=steps * DT, save_every=steps, method="rk4"),
                repeats) / steps * 1e9


def section_steps(repeats: int) -> None:
    print(f"\n1. rk4, ns per step, one scene (dt = {DT} s), compiled loop alone")
    print("   scene        planar   3-D engine   hand kernel   MuJoCo RK4   planar/hand   3-D/planar   MuJoCo/planar")
    rod = rbody.scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
    rod_tree = Scene.from_layout(rod.layout, t_end=1.0)
    assert rod_tree.native_model.rhs is planar_rhs
    model = rod_tree.native_model
    planar = loop_ns(model.rhs, model.y0, model.params, 200_000, repeats)
    general = loop_ns(mb.tree_rhs, *three_d(rod_tree), 50_000, repeats)
    assert rod.hand_model().rhs is pendulum_rhs
    hand_model = rod.hand_model()
    hand = loop_ns(hand_model.rhs, hand_model.y0, hand_model.params, 200_000, repeats)
    theirs = mujoco_step_ns(rod, 50_000, repeats)
    print(f"   rod        {planar:8.0f}   {general:10.0f}   {hand:11.0f}   {theirs:10.0f}   {planar / hand:11.2f}   "
          f"{general / planar:10.2f}   {theirs / planar:13.2f}   (targets: planar/hand <= 2)")
    for n in (2, 8, 32):
        scene = chain(n)
        tree = Scene.from_layout(scene.layout, t_end=1.0)
        assert tree.native_model.rhs is planar_rhs
        steps = 40_000 if n < 32 else 10_000
        model = tree.native_model
        planar = loop_ns(model.rhs, model.y0, model.params, steps, repeats)
        general = loop_ns(mb.tree_rhs, *three_d(tree), steps // 4, repeats)
        kernel = scene.hand_model()  # chain_rhs, whatever native() picks
        hand = loop_ns(kernel.rhs, kernel.y0, kernel.params, steps, repeats)
        theirs = mujoco_step_ns(scene, steps, repeats)
        print(f"   chain {n:2d}   {planar:8.0f}   {general:10.0f}   {hand:11.0f}   {theirs:10.0f}   {planar / hand:11.2f}"
              f"   {general / planar:10.2f}   {theirs / planar:13.2f}   (target MuJoCo/planar >= 5)")
    print("   through rbody.simulate (whole call, 20000 steps, one saved sample):")
    for name, scene in (("rod", rod_tree), ("chain 8", Scene.from_layout(chain(8).layout, t_end=1.0))):
        print(f"   {name:8s} {simulate_ns(scene, 20_000, repeats):8.0f} ns per step")


def section_batch(repeats: int, count: int) -> None:
    print(f"\n2. {count} double pendulums in one rk4 batch, ns per pendulum-step (target <= 50), "
          f"{numba.get_num_threads()} threads")
    rng = np.random.default_rng(1)
    theta = rng.uniform(-1, 1, (count, 2))
    scene = rbody.scenes.pendulum_chain(2, theta0=theta, t_end=1.0)
    tree = Scene.from_layout(scene.item(0).layout, t_end=1.0, qpos0=np.column_stack([theta[:, 0], np.diff(theta)[:, 0]]))
    model = tree.native_model
    assert model.rhs is planar_rhs
    hand = scene.hand_model()
    wall = time.perf_counter
    figures = {}
    for label, clock in (("wall", wall), ("CPU", time.process_time)):
        figures[f"planar, compiled loop ({label})"] = loop_ns(model.rhs, model.y0, model.params, 10, repeats, clock) / count
        figures[f"3-D engine, compiled loop ({label})"] = loop_ns(mb.tree_rhs, *three_d(tree), 4, repeats, clock) / count
        figures[f"hand chain_rhs, compiled loop ({label})"] = loop_ns(hand.rhs, hand.y0, hand.params, 10, repeats,
                                                                      clock) / count
        figures[f"planar, rbody.simulate ({label})"] = best(
            lambda: rbody.simulate(tree, dt=DT, t_end=10 * DT, save_every=10, method="rk4"), repeats,
            clock) / 10 * 1e9 / count
    for name, value in figures.items():
        print(f"   {name:42s} {value:7.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--batch", type=int, default=100_000)
    args = parser.parse_args()
    print_header()
    section_steps(args.repeats)
    section_batch(args.repeats, args.batch)


if __name__ == "__main__":
    main()
