"""Cost of a step of rbody's native engine on the chapter's swinging rod.

    python benchmarks/engine_speed.py [--steps 10000000] [--rod-steps 4194304] [--repeats 5]

Prints the machine and package versions, then for verlet, rk4, yoshida6 and gauss6:
- one rod, a long run (--steps steps, saving only every 10^5th state): ns per step;
- batches of 1, 64, 1024 and 16384 rods (about --rod-steps rod-steps per run): ns per rod-step.
Each figure is the minimum over --repeats runs after one warm-up run (which also loads or compiles
the kernels), timed two ways: simulate() as a user calls it (building the native model, the loop,
the observables and the Trajectory) and the compiled loop alone on preallocated arrays; both in wall
time, and the loop also in CPU time summed over its threads (process time), which other processes on
a shared machine do not inflate. Benchmarks are not tests: this measures and reports; the load
average is printed because the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numba  # noqa: E402

from rbody import simulate  # noqa: E402
from rbody.engine import integrators  # noqa: E402
from rbody.scenes import swinging_rod  # noqa: E402

METHODS = ("verlet", "rk4", "yoshida6", "gauss6")
BATCHES = (1, 64, 1024, 16384)
DT = 1e-3
SINGLE_TARGET_NS = 200.0
BATCH_TARGET_NS = 20.0


def machine() -> list[str]:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "n/a"
    return [
        f"platform   {platform.platform()}",
        f"cpu        {cpu}; {os.cpu_count()} logical cores, {usable} usable; numba threads {numba.get_num_threads()}",
        f"python     {platform.python_version()}  numpy {np.__version__}  numba {numba.__version__}",
        f"load avg   {load} (1, 5, 15 min)",
    ]


def kernel_call(method: str, model, nsteps: int, save_every: int):
    """The compiled loop alone, on preallocated arrays: returns a no-argument callable."""
    y0 = np.ascontiguousarray(model.y0)
    params = np.ascontiguousarray(model.params)
    out = np.empty((nsteps // save_every + 1,) + y0.shape)
    size = integrators.chunk_size(y0.shape[0])
    if method in ("verlet", "yoshida6"):
        accel = integrators.pointer_function(model.accel)
        weights = np.ones(1) if method == "verlet" else integrators.YOSHIDA6
        return lambda: integrators._composed_verlet_loop(accel, weights, y0, params, DT, nsteps, save_every, out, size)
    rhs = integrators.pointer_function(model.rhs)
    finish, finishing = integrators.finish_pointer(model.finish)  # the rod has none: the loops skip the call
    if method == "rk4":
        return lambda: integrators._rk4_loop(rhs, finish, finishing, y0, params, DT, nsteps, save_every, out, size)
    if method == "gauss6":
        a, b = integrators.GAUSS6_A, integrators.GAUSS6_B
        second, later = integrators.gauss_starting_guess(a)
        return lambda: integrators._gauss_loop(rhs, finish, finishing, a, b, second, later, y0, params, DT, nsteps,
                                               save_every, out, size)
    raise ValueError(method)


def best_of(call, repeats: int) -> tuple[float, float]:
    """Minimum wall and CPU (all threads) seconds of call() over `repeats` runs after a warm-up."""
    call()  # warm-up: loads (or compiles) the kernel, touches the memory
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        call()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return min(wall), min(cpu)


def measure(method: str, rods: int, nsteps: int, save_every: int, repeats: int) -> tuple[float, float, float]:
    """simulate wall, kernel wall, kernel CPU: nanoseconds per rod-step."""
    theta0 = np.linspace(0.1, 3.0, rods) if rods > 1 else 1.0
    scene = swinging_rod(1.0, theta0=theta0, t_end=nsteps * DT)
    user, _ = best_of(lambda: simulate(scene, dt=DT, method=method, save_every=save_every), repeats)
    raw, raw_cpu = best_of(kernel_call(method, scene.native(), nsteps, save_every), repeats)
    per = 1e9 / (rods * nsteps)
    return user * per, raw * per, raw_cpu * per


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=10**7, help="steps of the single-rod run")
    parser.add_argument("--rod-steps", type=int, default=2**22, help="rods x steps of each batched run")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    print("\n".join(machine()))
    print(f"\nswinging rod, theta0 = 1, dt = {DT} s; minimum of {args.repeats} runs after one warm-up\n")
    print(f"single rod, {args.steps:.0e} steps, saving every 10^5th: ns per step (target < {SINGLE_TARGET_NS:g})")
    print(f"  {'method':<10}{'simulate':>12}{'kernel':>12}{'kernel cpu':>12}")
    for method in METHODS:
        user, raw, cpu = measure(method, 1, args.steps, 10**5, args.repeats)
        print(f"  {method:<10}{user:12.1f}{raw:12.1f}{cpu:12.1f}")

    print(f"\nbatched, ~{args.rod_steps:.1e} rod-steps per run, saving only the end: ns per rod-step "
          f"(target < {BATCH_TARGET_NS:g} at 1024 rods and above)")
    print("  (simulate and kernel: wall time; cpu: CPU time of the kernel summed over its threads)")
    print(f"  {'method':<10}" + "".join(f"{f'{rods} rods':>27}" for rods in BATCHES))
    print(f"  {'':<10}" + "".join(f"{'simulate':>10}{'kernel':>9}{'cpu':>8}" for _ in BATCHES))
    for method in METHODS:
        row = []
        for rods in BATCHES:
            nsteps = max(args.rod_steps // rods, 64)
            user, raw, cpu = measure(method, rods, nsteps, nsteps, args.repeats)
            row.append(f"{user:10.1f}{raw:9.1f}{cpu:8.1f}")
        print(f"  {method:<10}" + "".join(row))
    print(f"\nthreading layer: {numba.threading_layer()}")


if __name__ == "__main__":
    main()
