"""Is the rolling scenes' hand kernel (rolling_rhs) worth keeping as a fast path beside the general engine?

    python benchmarks/rolling_fast_path.py [--repeats 5] [--steps 200000]

DESIGN.md keeps a hand-written kernel as a fast path only where it is measurably more than 1.5x cheaper per
step than the general engine. This prints, for the rolling disc (one body, one roll joint) and the
four-body race (one tree of four roll joints, against the kernel's batch of four), ns per step of the
compiled loop alone (rbody.engine.integrators, the scene's native model as simulate builds it), rk4 and
verlet, engine / kernel and their ratio, in one run (compare figures of one run with each other: the
machine may be shared, the load average is printed). Each figure is the minimum over --repeats runs after
a warm-up. The verdict goes into rbody.scenes.rolling.FAST_PATH by hand, with the figures.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rbody.engine import integrators  # noqa: E402
from rbody.scenes import rolling, rolling_race  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from multibody_speed import best  # noqa: E402  (min wall time over repeats after a warm-up)

DT = 1e-3
FAST_PATH_RATIO = 1.5  # DESIGN.md: keep a hand kernel only where it is more than this much cheaper per step




def step_ns(model, method: str, steps: int, repeats: int) -> float:
    """ns per step of the scene's native model (its whole batch), the compiled loop alone."""
    out = np.empty((2,) + model.y0.shape)
    if method == "rk4":
        def go():
            integrators.run_rk4(model.rhs, model.y0, model.params, DT, steps, steps, out, finish=model.finish)
    else:
        weights = np.array([1.0])

        def go():
            integrators.run_composed_verlet(model.accel, weights, model.y0, model.params, DT, steps, steps, out)
    return best(go, repeats) / steps * 1e9


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--steps", type=int, default=200_000)
    args = parser.parse_args(argv)
    import numba

    print(f"{describe_machine()}; numpy {np.__version__}, numba {numba.__version__}")
    print(f"load average {os.getloadavg()}")
    scenes = {"rolling disc": rolling("disc", radius=0.1, incline=0.5, t_end=1.0),
              "race of 4": rolling_race(("disc", "hollow_cylinder", "solid_sphere", "spherical_shell"),
                                        radius=0.1, incline=0.3, length=1.0)}
    print(f"{'scene':14s} {'method':7s} {'engine ns/step':>15s} {'kernel ns/step':>15s} {'ratio':>7s}")
    ratios = []
    for label, scene in scenes.items():
        engine, kernel = scene.engine_native(), scene.kernel_native()
        for method in ("rk4", "verlet"):
            e = step_ns(engine, method, args.steps, args.repeats)
            k = step_ns(kernel, method, args.steps, args.repeats)
            ratios.append(e / k)
            print(f"{label:14s} {method:7s} {e:15.1f} {k:15.1f} {e / k:7.2f}")
    verdict = min(ratios) > FAST_PATH_RATIO
    print(f"kernel cheaper than the engine by {min(ratios):.2f}x to {max(ratios):.2f}x: FAST_PATH = {verdict} "
          f"(keep the kernel as a fast path only above {FAST_PATH_RATIO}x)")


if __name__ == "__main__":
    main()
