"""Wall time of the exact event-driven pi count (the chapter's section 5.2.2).

    python benchmarks/pi_collisions.py [--full] [--convention galperin|chapter]

For each number of digits N: one warm-up, then the minimum of 3 wall times of
`pi_collisions(N)`, which builds the scene and runs every impact to the end in the compiled
event loop (no sampling, no event arrays), then the count, the exact count and whether they agree.
Then the same for simulate(scene, dt = t_end/1000) with every impact recorded (digits <= 6).
--full adds N = 8 (about 3 x 10^8 impacts).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time

import numba
import numpy as np

from rbody import simulate
from rbody.scenes import pi_collisions
from validation.machine import cpu_model


def best_of(function, repeats: int = 3) -> tuple[float, object]:
    function()  # warm-up (compiles or loads the numba cache)
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also digits 8 (about 3e8 impacts)")
    parser.add_argument("--convention", default="galperin", choices=("galperin", "chapter"))
    args = parser.parse_args()

    print(f"machine: {platform.platform()}; CPU: {cpu_model()}; {platform.machine()}, "
          f"{__import__('os').cpu_count()} logical CPUs")
    print(f"python {sys.version.split()[0]}, numpy {np.__version__}, numba {numba.__version__}")
    print(f"convention: {args.convention}; wall time = min of 3 after one warm-up\n")

    print(f"{'digits':>6} {'impacts':>12} {'count':>11} {'expected':>11} {'exact':>6} {'time [s]':>9} {'ns/impact':>10}")
    for digits in (5, 6, 7, 8) if args.full else (5, 6, 7):
        elapsed, scene = best_of(lambda: pi_collisions(digits, convention=args.convention))
        impacts = scene.counts()["total"]
        count, expected = scene.count(), scene.expected_collisions
        print(f"{digits:>6} {impacts:>12} {count:>11} {expected:>11} {str(count == expected):>6} "
              f"{elapsed:>9.3f} {elapsed / impacts * 1e9:>10.1f}")

    print("\nsimulate(scene, dt=t_end/1000), every impact recorded:")
    print(f"{'digits':>6} {'impacts':>12} {'time [s]':>9} {'ns/impact':>10}")
    for digits in (5, 6):
        scene = pi_collisions(digits, convention=args.convention)
        dt = scene.t_end / 1000
        elapsed, traj = best_of(lambda: simulate(scene, dt=dt))
        impacts = traj.meta["event_count"]
        assert traj.meta["events_recorded"]
        print(f"{digits:>6} {impacts:>12} {elapsed:>9.3f} {elapsed / impacts * 1e9:>10.1f}")


if __name__ == "__main__":
    main()
