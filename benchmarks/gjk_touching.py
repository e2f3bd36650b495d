"""The convex narrow phase (rbody.engine.contacts.convex.signed_distance) on geoms brought to touching: how often
GJK/EPA ends within its tolerance, the duality gaps it reports where it does not, its iterations and its cost.

    python benchmarks/gjk_touching.py [--poses 400] [--regime touching|near] [--seed 1] [--repeats 5]
                                      [--other CHECKOUT]

Six geoms (a sphere, a capsule, an ellipsoid, a cylinder, a box and the hull of 30 random points, all about 0.1 m)
in --poses random poses per ordered pair of kinds, geom b moved along a random direction by bisection (60 halvings)
until the signed distance is a target drawn log-uniformly: `touching` from 1e-15 to 1e-9 m, a quarter of them
overlapping by as much (the regime of a contact the step holds at zero), `near` from 1e-10 to 1e-2 m, a fifth
overlapping. Per class of pair (polytope: both of sphere, capsule, box, mesh; curved: an ellipsoid or a cylinder):
the poses, how many ended CONVERGED, STALLED or otherwise, the largest and the median gap of those that did not
converge, the mean GJK iterations, and the cost of a call (us: every pose once in a compiled loop, --repeats
times, min and median). The poses are found by this checkout; with --other, the same poses (written to a
temporary file) are run by OTHER_CHECKOUT's code too (a git worktree of another commit, in its own process) and
printed beside.

Prints the machine and versions. Benchmarks are not tests: the machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
if "RBODY_ROOT" in os.environ:  # --other's child process: the other checkout's rbody
    sys.path.insert(0, os.environ["RBODY_ROOT"])
elif __name__ == "__main__":
    sys.path.insert(0, str(HERE.parents[1]))

KINDS = ("sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")
CURVED = {"ellipsoid", "cylinder"}
REGIMES = {"touching": (-15.0, -9.0, 0.25), "near": (-10.0, -2.0, 0.2)}  # log10 range [m], overlapping share


def shapes() -> list[tuple]:
    """(kind code, size (3,) [m], hull) of the six geoms."""
    from rbody.engine.contacts.convex import BOX, CAPSULE, CYLINDER, ELLIPSOID, MESH, SPHERE, pack_hull
    hull = pack_hull(np.random.default_rng(17).normal(size=(30, 3)) * [0.12, 0.1, 0.08])
    none = np.empty(0)
    return [(SPHERE, np.array([0.1, 0.0, 0.0]), none), (CAPSULE, np.array([0.06, 0.12, 0.0]), none),
            (ELLIPSOID, np.array([0.12, 0.08, 0.05]), none), (CYLINDER, np.array([0.08, 0.1, 0.0]), none),
            (BOX, np.array([0.1, 0.06, 0.08]), none), (MESH, np.zeros(3), hull)]


def poses(count: int, regime: str, seed: int) -> dict[str, np.ndarray]:
    """count poses per ordered pair of kinds: kinds (P, 2), positions (P, 2, 3) [m], rotations (P, 2, 3, 3)."""
    from rbody.engine.contacts.convex import INFO, signed_distance
    from rbody.motion import quat_to_matrix
    low, high, overlapping = REGIMES[regime]
    geoms = shapes()
    rng = np.random.default_rng(seed)
    normal, xa, xb, guess = np.empty(3), np.empty(3), np.empty(3), np.zeros(3)
    info = np.zeros(INFO)
    kinds, positions, rotations = [], [], []
    for i in range(len(geoms)):
        for j in range(len(geoms)):
            for _ in range(count):
                Ra, Rb = quat_to_matrix(rng.normal(size=4)), quat_to_matrix(rng.normal(size=4))
                u = rng.normal(size=3)
                u /= np.linalg.norm(u)
                target = 10.0 ** rng.uniform(low, high) * (-1.0 if rng.random() < overlapping else 1.0)
                pa = np.array([0.01, -0.02, 0.03])
                lo, hi = 0.0, 0.6  # along u: lo overlapping, hi apart
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    info[4:] = -1.0
                    d = signed_distance(geoms[i][0], pa, Ra, geoms[i][1], geoms[i][2], geoms[j][0], pa + mid * u,
                                        Rb, geoms[j][1], geoms[j][2], guess, normal, xa, xb, info)
                    lo, hi = (mid, hi) if d < target else (lo, mid)
                kinds.append((i, j))
                positions.append((pa, pa + hi * u))
                rotations.append((Ra, Rb))
    return {"kinds": np.array(kinds), "positions": np.array(positions), "rotations": np.array(rotations)}


def measure(table: dict[str, np.ndarray], repeats: int) -> dict:
    """Per class (polytope, curved): poses, converged, stalled, other, the gaps [m] of those not converged, the
    mean GJK iterations, and the us a call (min and median over the repeats)."""
    from numba import njit

    from rbody.engine.contacts.convex import CONVERGED, INFO, STALLED, signed_distance
    geoms = shapes()
    kind = np.array([g[0] for g in geoms])
    sizes = np.array([g[1] for g in geoms])
    hull = geoms[5][2]

    @njit(cache=False)
    def run_all(pairs, positions, rotations, out):
        normal, xa, xb, guess = np.empty(3), np.empty(3), np.empty(3), np.zeros(3)
        info = np.zeros(INFO)
        empty = np.empty(0)
        for t in range(pairs.shape[0]):
            i, j = pairs[t, 0], pairs[t, 1]
            info[4] = -1.0
            info[5] = -1.0
            signed_distance(kind[i], positions[t, 0], rotations[t, 0], sizes[i], hull if i == 5 else empty,
                            kind[j], positions[t, 1], rotations[t, 1], sizes[j], hull if j == 5 else empty, guess,
                            normal, xa, xb, info)
            out[t, 0], out[t, 1], out[t, 2] = info[0], info[1], info[3]

    pairs, positions, rotations = table["kinds"], table["positions"], table["rotations"]
    out = np.empty((pairs.shape[0], 3))
    run_all(pairs, positions, rotations, out)  # compiles
    costs = []
    for _ in range(repeats):
        start = time.perf_counter()
        run_all(pairs, positions, rotations, out)
        costs.append((time.perf_counter() - start) / pairs.shape[0] * 1e6)
    curved = np.array([KINDS[i] in CURVED or KINDS[j] in CURVED for i, j in pairs])
    result = {"cost_min": min(costs), "cost_median": float(np.median(costs))}
    for name, mask in (("polytope", ~curved), ("curved", curved)):
        status, iterations, gaps = out[mask, 0], out[mask, 1], out[mask, 2]
        open_gaps = gaps[status != CONVERGED]
        result[name] = {"poses": int(mask.sum()), "converged": int(np.sum(status == CONVERGED)),
                        "stalled": int(np.sum(status == STALLED)),
                        "other": int(np.sum((status != CONVERGED) & (status != STALLED))),
                        "gap_max": float(open_gaps.max()) if open_gaps.size else 0.0,
                        "gap_median": float(np.median(open_gaps)) if open_gaps.size else 0.0,
                        "iterations": float(iterations.mean())}
    return result


def _other(checkout: Path, table: dict[str, np.ndarray], repeats: int) -> dict:
    """measure() run by another checkout's code in its own process, on the same poses."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "poses.npz"
        np.savez(path, **table)
        env = dict(os.environ, RBODY_ROOT=str(checkout))
        done = subprocess.run([sys.executable, str(HERE), "--measure-file", str(path), "--repeats", str(repeats)],
                              env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _rows(label: str, result: dict) -> list[str]:
    rows = []
    for name in ("polytope", "curved"):
        r = result[name]
        rows.append(f"| {label} | {name} | {r['poses']} | {r['converged']} | {r['stalled']} | {r['other']} | "
                    f"{r['gap_max']:.2g} | {r['gap_median']:.2g} | {r['iterations']:.1f} |")
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--poses", type=int, default=400, help="poses per ordered pair of kinds")
    parser.add_argument("--regime", choices=sorted(REGIMES), default="touching")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--other", type=Path, help="another checkout, run on the same poses")
    parser.add_argument("--measure-file", type=Path, help=argparse.SUPPRESS)  # --other's child
    args = parser.parse_args(argv)
    if args.poses < 1 or args.repeats < 1:
        raise ValueError(f"poses={args.poses}, repeats={args.repeats}: each must be at least 1")
    if args.measure_file is not None:
        with np.load(args.measure_file) as saved:
            print(json.dumps(measure({key: saved[key] for key in saved.files}, args.repeats)))
        return
    if args.other is not None and not (args.other / "rbody" / "engine" / "contacts" / "convex.py").is_file():
        raise ValueError(f"other={str(args.other)!r}: not a checkout of rbody (no rbody/engine/contacts/convex.py)")
    import numba
    print(f"{platform.processor() or platform.machine()}, {platform.system()} {platform.release()}; numpy "
          f"{np.__version__}, numba {numba.__version__}; {args.poses} poses per pair, regime {args.regime}, "
          f"seed {args.seed}")
    table = poses(args.poses, args.regime, args.seed)
    results = {"this checkout": measure(table, args.repeats)}
    if args.other is not None:
        results[str(args.other)] = _other(args.other, table, args.repeats)
    print("| code | pairs | poses | converged | stalled | other | largest open gap [m] | median open gap [m] | "
          "GJK iterations |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, result in results.items():
        print("\n".join(_rows(label, result)))
    for label, result in results.items():
        print(f"{label}: {result['cost_min']:.2f} us a call (min of {args.repeats}), median "
              f"{result['cost_median']:.2f}")


if __name__ == "__main__":
    main()
