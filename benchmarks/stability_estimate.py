"""Cost of the stability estimate (rbody.engine.stability.fastest_rate) on big 3-D trees, against the tree's size.

    python benchmarks/stability_estimate.py [--sizes 100 300 1000] [--dense-up-to 300]

A tree of N bodies joined by ball joints (3-D, not planar), each hung from a random earlier body (a fixed seed),
with uneven rods and inertias: its state holds 10 N numbers (qpos 4 N, qvel 3 N, rotation vectors 3 N). For each
N it prints the seconds and the peak memory (tracemalloc) of the estimate as simulate makes it (Arnoldi's iteration
on Jacobian-vector products, krylov_rate, above DENSE_STATE_LIMIT numbers of state), the number of right-hand-side
evaluations it took, the rate found, the seconds of a whole simulate call of one rk4 step on a fresh scene
(its checks: work estimate, precision, stability, accuracy; then the step and the observables), and, up to
--dense-up-to bodies, the dense Jacobian's spectral radius and its
cost (the estimate before issue 23: 2n evaluations and a cubic eigenproblem) for comparison. Then the cost per
element of the free rotation's own estimate (rbody.scenes.free_rotation.rotation_rates: its exact motion sampled
over a period, Euler's equations linearised) on a batch of --rotations random spins.
Prints the machine and versions first. Not a test: run it on an idle machine and compare figures of one run.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numba  # noqa: E402
import scipy  # noqa: E402

from rbody import Body, Inertia, Joint, Layout, Scene, scenes, simulate  # noqa: E402
from rbody.engine import integrators, stability  # noqa: E402
from validation.machine import describe_machine  # noqa: E402


def ball_tree(bodies: int, seed: int = 1) -> Scene:
    """N bodies on ball joints, body k hung from a random earlier one 0.3 m below it, slightly tilted."""
    rng = np.random.default_rng(seed)
    parts, joints = [], []
    for k in range(bodies):
        mass = rng.uniform(0.5, 2.0)
        moments = rng.uniform(0.03, 0.05, 3)  # any three in [0.03, 0.05] obey the triangle inequality
        parent = "world" if k == 0 else f"b{int(rng.integers(0, k))}"
        offset = (rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), -0.3)
        parts.append(Body(f"b{k}", Inertia(mass, (0.0, 0.0, -0.15), np.diag(moments)), parent=parent,
                          pos=offset if k else (0.0, 0.0, 0.0)))
        joints.append(Joint(f"j{k}", "ball", f"b{k}"))
    return Scene.from_layout(Layout(bodies=tuple(parts), joints=tuple(joints)), t_end=1.0)


def counted(rhs):
    """How many times fastest_rate evaluates the rhs: Jacobian-vector products x 2 (central differences)."""
    calls = [0]

    def jvp(*args):
        calls[0] += 2
        return _ORIGINAL_JVP(*args)
    return calls, jvp


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000])
    parser.add_argument("--dense-up-to", type=int, default=300)
    parser.add_argument("--rotations", type=int, default=1000)
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine {describe_machine()}; numba threads {numba.get_num_threads()}; load avg {load:.2f}")
    print(f"numpy {np.__version__}, scipy {scipy.__version__}, numba {numba.__version__}; "
          f"dense linearisation up to {stability.DENSE_STATE_LIMIT} numbers of state")
    ball_tree(3)  # compile the engine's functions outside the timings
    stability.fastest_rate(ball_tree(12), "rk4")
    simulate(ball_tree(12), dt=1e-3, t_end=1e-3, method="rk4")
    print(f"{'bodies':>7} {'state':>7} {'seconds':>8} {'peak MB':>8} {'evals':>6} {'rate [1/s]':>11} {'simulate s':>10}"
          f"   {'dense rate':>11} {'dense s':>8} {'dense MB':>9}")
    for size in args.sizes:
        scene = ball_tree(size)
        model = scene.native_model
        calls, jvp = counted(model.rhs)
        stability._jvp = jvp
        try:
            tracemalloc.start()
            start = time.perf_counter()
            rate = float(stability.fastest_rate(scene, "rk4")[0])
            seconds = time.perf_counter() - start
            peak = tracemalloc.get_traced_memory()[1] / 1e6
            tracemalloc.stop()
        finally:
            stability._jvp = _ORIGINAL_JVP
        start = time.perf_counter()
        simulate(ball_tree(size), dt=1e-3, t_end=1e-3, method="rk4")
        whole = time.perf_counter() - start
        dense = ""
        if size <= args.dense_up_to:
            y = np.ascontiguousarray(model.y0)
            n = y.shape[1]
            tracemalloc.start()
            start = time.perf_counter()
            jacobian = np.empty((1, n, n))
            stability._jacobians(integrators.pointer_function(model.rhs), y, np.ascontiguousarray(model.params),
                                 stability.JACOBIAN_STEP, jacobian)
            dense_rate = float(np.max(np.abs(np.linalg.eigvals(jacobian[0]))))
            dense_seconds = time.perf_counter() - start
            dense_peak = tracemalloc.get_traced_memory()[1] / 1e6
            tracemalloc.stop()
            dense = f"{dense_rate:11.6g} {dense_seconds:8.3f} {dense_peak:9.1f}"
        print(f"{size:7d} {model.y0.shape[1]:7d} {seconds:8.3f} {peak:8.1f} {calls[0]:6d} {rate:11.6g} {whole:10.3f}   "
              f"{dense}", flush=True)
    spins = np.random.default_rng(2).normal(size=(args.rotations, 3)) * 3.0
    rotations = scenes.free_rotation(Inertia(1.0, (0.1, 0.0, 0.0), np.diag([1.0, 2.0, 2.5])), omega0=spins, t_end=5.0)
    rotations._tops  # the exact motions, built with the scene's first closed-form call, outside the timing
    for method in ("rk4", "splitting"):
        start = time.perf_counter()
        stability.fastest_rate(rotations, method)
        seconds = time.perf_counter() - start
        print(f"free rotation, batch of {args.rotations}, {method}: {1e3 * seconds / args.rotations:.3f} ms per element")


_ORIGINAL_JVP = stability._jvp

if __name__ == "__main__":
    main()
