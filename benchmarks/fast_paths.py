"""Is each family's hand-written kernel still worth keeping? Cost per step of the general engine against it.

    python benchmarks/fast_paths.py [--repeats 3]

The swinging rod, the compound pendulum, the pendulum chain and free rotation each run natively two ways
(rbody.scenes: engine_model(), the scene's own Layout on the general engine, and hand_model(), the family's
hand-written kernel); the family keeps its hand kernel as the fast path that native() runs only where it is
more than FAST_PATH_RATIO (1.5) times cheaper per step. For each family this prints the machine and versions,
then ns per step of both paths on the same scene, the same dt and the same number of steps: rk4 for every
family, verlet where it applies (the pendulums: one hinge, constant mass matrix), the splitting for free
rotation (on the engine's state it is the family's own flow plus the mapping of the state). Then the
constants this measurement supports beside those in the code:
pendulum.FAST_PATH, chain.HAND_KERNEL_MAX_LINKS, free_rotation.FAST_PATH. The two-body scene has no engine
path (its pair force is not a joint of a tree): its hand kernel is timed alone, for reference.

Every figure is the minimum over --repeats runs after one warm-up (which also compiles or loads the
kernels), the compiled loop alone (integrators.run_*) on preallocated arrays, one scene (batch of 1); the
two paths of a row are timed in turn within each repeat, so that a shared machine's load falls on both.
Benchmarks are not tests; the machine may be shared (the load average is printed): compare figures of
one run with each other.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numba  # noqa: E402

import rbody  # noqa: E402
from rbody.engine import integrators  # noqa: E402

# the modules (rbody.scenes exports factory functions of the same names)
pendulum, chain, free_rotation = (importlib.import_module(f"rbody.scenes.{name}")
                                  for name in ("pendulum", "chain", "free_rotation"))
from validation.machine import describe_machine  # noqa: E402

DT = 1e-3
FAST_PATH_RATIO = 1.5  # the hand kernel stays the fast path only where it is more than this much cheaper
CHAIN_LINKS = (1, 2, 4, 8, 12, 16, 20, 24, 28, 32)


def stepper(model, method: str, steps: int):
    """A no-argument callable running `steps` steps of `method` on a native model, the compiled loop alone."""
    out = np.empty((2,) + model.y0.shape)
    y0, params = np.ascontiguousarray(model.y0), np.ascontiguousarray(model.params)
    if method == "rk4":
        return lambda: integrators.run_rk4(model.rhs, y0, params, DT, steps, steps, out, finish=model.finish)
    if method == "verlet":
        return lambda: integrators.run_composed_verlet(model.accel, np.ones(1), y0, params, DT, steps, steps, out)
    if method == "splitting":
        step, weights = model.split["splitting"]
        return lambda: integrators.run_composed_flow(step, weights, y0, params, DT, steps, steps, out)
    raise ValueError(method)


def best_ns(runs: list, steps: int, repeats: int) -> list[float]:
    """ns per step of each callable: one warm-up each, then `repeats` rounds timing them in turn (so that a
    shared machine's load falls on all of them alike), the minimum of each."""
    for function in runs:
        function()
    times = [[] for _ in runs]
    for _ in range(repeats):
        for function, kept in zip(runs, times):
            start = time.perf_counter()
            function()
            kept.append(time.perf_counter() - start)
    return [min(kept) / steps * 1e9 for kept in times]


def compare(label: str, scene, method: str, steps: int, repeats: int) -> float:
    """Print one row (hand, engine, ratio) and return the hand kernel's advantage, engine / hand."""
    hand, engine = best_ns([stepper(scene.hand_model(), method, steps), stepper(scene.engine_model(), method, steps)],
                           steps, repeats)
    ratio = engine / hand
    verdict = "hand kernel" if ratio > FAST_PATH_RATIO else "engine"
    print(f"   {label:28s} {method:9s} {hand:10.0f} {engine:12.0f} {ratio:9.2f}x   {verdict}")
    return ratio


def commit() -> str:
    """The checkout's commit (the figures belong to that code), or '?' outside git."""
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).resolve().parents[1]).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    repeats = args.repeats
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"machine    {describe_machine()}; numba threads {numba.get_num_threads()}; load avg {load}")
    print(f"versions   python {platform.python_version()}  numpy {np.__version__}  numba {numba.__version__}  "
          f"rbody commit {commit()}")
    print(f"\nns per step, one scene, dt = {DT:g} s; ratio = engine / hand; the fast path is the hand kernel where the "
          f"ratio > {FAST_PATH_RATIO}")
    print(f"   {'scene':28s} {'method':9s} {'hand [ns]':>10s} {'engine [ns]':>12s} {'ratio':>10s}   runs on")

    rod = rbody.scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
    disc = rbody.scenes.compound_pendulum(rbody.Inertia.disc(2.0, 0.3, "y"), pivot=(0.3, 0.0, 0.0),
                                          axis="y", theta0=1.0, t_end=1.0)
    pendulum_ratios = [compare("swinging rod", rod, method, 100_000, repeats) for method in ("rk4", "verlet")]
    pendulum_ratios += [compare("compound pendulum (disc)", disc, method, 100_000, repeats)
                        for method in ("rk4", "verlet")]

    chain_ratios = {}
    for n in CHAIN_LINKS:
        scene = rbody.scenes.pendulum_chain(n, theta0=np.linspace(0.3, 0.6, n), t_end=1.0)
        chain_ratios[n] = compare(f"pendulum chain, {n} links", scene, "rk4", 20_000 if n <= 8 else 5_000, repeats)

    body = rbody.Inertia.box(2.0, [0.3, 0.2, 0.1]).translated([0.05, -0.02, 0.03])
    spin = rbody.scenes.free_rotation(body, omega0=[0.3, 4.0, 0.5], t_end=1.0)
    rotation_ratios = [compare("free rotation", spin, method, 50_000, repeats) for method in ("rk4", "splitting")]

    kepler = rbody.scenes.two_body(1.0, 0.5, separation=1.0, relative_velocity=1.2, t_end=1.0)
    for method in ("rk4", "verlet"):
        (hand,) = best_ns([stepper(kepler.native_model, method, 200_000)], 200_000, repeats)
        print(f"   {'two-body (no engine path)':28s} {method:9s} {hand:10.0f} {'-':>12s} {'-':>10s}   hand kernel")

    longest = 0  # the hand kernel up to the first chain where it is no longer > 1.5x cheaper
    for n in CHAIN_LINKS:
        if chain_ratios[n] <= FAST_PATH_RATIO:
            break
        longest = n
    print("\nconstants this run supports (in the code now):")
    print(f"   rbody/scenes/pendulum.py       FAST_PATH = {min(pendulum_ratios) > FAST_PATH_RATIO}   "
          f"({pendulum.FAST_PATH}; engine / hand {min(pendulum_ratios):.1f}x to {max(pendulum_ratios):.1f}x)")
    print(f"   rbody/scenes/chain.py          HAND_KERNEL_MAX_LINKS = {longest}   ({chain.HAND_KERNEL_MAX_LINKS}; "
          "every N measured up to it has engine / hand > 1.5)")
    print(f"   rbody/scenes/free_rotation.py  FAST_PATH = {rotation_ratios[0] > FAST_PATH_RATIO}   "
          f"({free_rotation.FAST_PATH}; rk4 engine / hand {rotation_ratios[0]:.1f}x)")
    print("   rbody/scenes/two_body.py       hand kernel only (no engine path: a tree holds no pair force)")


if __name__ == "__main__":
    main()
