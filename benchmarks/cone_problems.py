"""The contact step's problems, captured from a run and timed alone: a suite on which a change of the cone
solver's schedule (rbody.engine.constraints.stepping.cone_solve) is judged on the same problems, not on whole runs
whose hard steps are chaotic in cost (a landing quadruped's trajectories part at round-off, and which side of a
round-off difference a step falls on can change its cost five times).

    python benchmarks/cone_problems.py capture MODEL.xml OUT.npz [--steps 1000] [--lift 0.0105] [--keep 24]
    python benchmarks/cone_problems.py time PROBLEMS.npz [--repeats 5]
    python benchmarks/cone_problems.py compare PROBLEMS.npz OTHER_CHECKOUT [--repeats 5]
    python benchmarks/cone_problems.py census MODEL.xml [--steps 1000] [--lift 0.0105] [--runs 2] [--other CHECKOUT]

capture: runs MODEL.xml (a user's MJCF with contacts; its free body raised by --lift [m] to land) natively with its
own integrator at its own step, timing each step. The --keep slowest steps, and --keep steps spread over the run
(the common ones, so that a change that slows them shows), are taken again from the state before them through
the step's own code run in Python (moreau_step.py_func, the solver itself compiled), which records its contact
problem as it calls solve_cones (cone_solve, with its start from rest where the warm start fails): the problem,
its start, tolerance and budget, kept in OUT.npz (written to a temporary name, then renamed). The replay forms W
and b by Python's loops and numpy's products, not the compiled step's, so its problem can differ from the native
one at round-off; each replayed step's state is compared with the native step's (replay_dy, 0 where they agree
bit for bit). A hard step's cost can hang on such a difference (the ANYmal C's landing step: 72 ms native, 165 ms
replayed, on the same code), so a change judged on the suite is checked on a whole run too.

time: each kept problem solved --repeats times from its start as this checkout's step solves it, after one call
that compiles: per problem the minimum, median and maximum [ms] and the residual reached, then the totals.

compare: `time` run in turn by this checkout and by OTHER_CHECKOUT's (a git worktree of another commit, each in
its own process, alternating --repeats times so that the machine's drift falls on both; each process solves each
problem WITHIN times), and per problem the ratio of their minima and both residuals.

census: the whole run's cost and exactness, step by step, which the suite cannot show (a change of the schedule
moves which steps are hard and where each ends): MODEL.xml run natively --runs times, each step timed (the
compiled moreau_step alone) and its residual kept; per step the minimum over the runs. It prints the sum of those
minima, each run's mean, the quantiles, the steps above 1 and 5 ms, and the steps accepted with a residual above
ROUND_GOAL (1e-13 [m/s], the rounds' goal of 1e-3 of the step's tolerance at a scale of 1), each with its
residual, and the ten slowest steps. With --other, the same from OTHER_CHECKOUT beside it, the two alternating
run by run in their own processes.

Prints the machine and versions. Benchmarks are not tests: the machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
if __name__ == "__main__" and "RBODY_ROOT" not in os.environ:
    sys.path.insert(0, str(HERE.parents[1]))
elif "RBODY_ROOT" in os.environ:  # compare's child process: the other checkout's rbody
    sys.path.insert(0, os.environ["RBODY_ROOT"])

WITHIN = 3  # compare: the times each process solves each problem (its first solve of a problem can cost 4 times
# the next: 23 against 6 us on a step the warm start solves)
FIELDS = ("W", "b", "lo", "hi", "role", "mu", "lam", "tolerance", "sweeps")
ROUND_GOAL = 1e-13  # census: a step accepted above this residual [m/s] is reported


def _native_run(path: Path, steps: int, lift: float):
    """The model's scene (its free body raised by `lift` [m]), its step [s], a function that takes one step of
    moreau_step (or its py_func) from a state (y, P, end_geometry, problem_rows) in place, and the first state."""
    import mujoco

    import rbody
    from rbody.engine.constraints import stepping
    from rbody.engine.constraints.jacobians import row_count

    if not path.is_file():
        raise ValueError(f"model={str(path)!r}: no such file")
    if lift != 0.0:
        mj = mujoco.MjModel.from_xml_path(str(path))
        if mj.njnt == 0 or mj.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE:
            raise ValueError(f"lift={lift}: {path.name}'s first joint is not a free joint, nothing to raise")
    scene = rbody.from_mjcf(path, overlapping_geoms="sum")
    if lift != 0.0:
        qpos0 = np.array(scene.qpos0, dtype=float)
        qpos0[2] += lift
        scene = rbody.from_mjcf(path, overlapping_geoms="sum", qpos0=qpos0)
    dt = scene.timestep
    prepared = rbody.prepare(scene, dt=dt, method=scene.file_method, t_end=steps * dt)
    run = stepping.MoreauRun(prepared.model.constraints, prepared.params[0], path.name, scene.file_method)
    p = run.p

    arena = stepping.step_arena(p) if hasattr(stepping, "step_arena") else ()  # (a checkout before 2026-12-01: none)

    def step(step_function, state):
        y, P, end_geometry, problem_rows = state
        return step_function(p, y, dt, P, stepping.EXACT_ROWS, stepping.PGS_SWEEPS, stepping.STEP_TOLERANCE,
                             problem_rows, run.mode, end_geometry, *arena)

    first = (np.array(prepared.y0[0]), np.zeros(row_count(p)),
             np.zeros(_kept_size(p)),
             np.zeros(row_count(p) + 1, dtype=np.int64))  # (a checkout before its step listed its problem's rows
    # took a dense flag per row here: this array serves it as well)
    return scene, dt, step, first


def capture(path: Path, out: Path, steps: int, lift: float, keep: int) -> None:
    """Run the model `steps` steps natively and keep the problems of its `keep` slowest steps and of `keep` steps
    spread over the run in `out`."""
    import heapq

    import rbody
    from rbody.engine.constraints import stepping

    if steps < 1 or keep < 1:
        raise ValueError(f"steps={steps} and keep={keep}: expected positive counts")
    if out.suffix != ".npz":
        raise ValueError(f"out={str(out)!r}: expected a file name ending in .npz")
    scene, dt, step, state = _native_run(path, steps, lift)
    step(stepping.moreau_step, tuple(a.copy() for a in state))  # compiles
    spread = set(np.linspace(0, steps - 1, min(keep, steps)).astype(int).tolist())
    slowest: list = []  # a heap of (seconds, step, its states) of the slowest steps
    chosen = {}
    for k in range(steps):  # moreau_loop's steps one by one (MoreauRun._stepwise), the states of each kept
        before = tuple(a.copy() for a in state)
        start = time.perf_counter()
        status, residual, _rows = step(stepping.moreau_step, state)
        seconds = time.perf_counter() - start
        if status != 0:
            raise rbody.SimulationError(f"{path.name}: step {k} (t = {k * dt:g} s) left the residual {residual:.3g}")
        states = before + (state[0].copy(),)  # and the state after it, to check the replay against
        if k in spread:
            chosen[k] = (seconds, states, False)
        heapq.heappush(slowest, (seconds, k, states))
        if len(slowest) > keep:
            heapq.heappop(slowest)
        if k % 100 == 0:
            print(f"  step {k} of {steps}", file=sys.stderr, flush=True)
    for seconds, k, states in slowest:
        chosen[k] = (seconds, states, True)
    problems: list[dict] = []
    solve = stepping.solve_cones

    def recorded(W, b, lo, hi, role, mu, lam, tolerance, sweeps):
        problems.append(dict(W=W.copy(), b=b.copy(), lo=lo.copy(), hi=hi.copy(), role=role.copy(), mu=mu.copy(),
                             lam=lam.copy(), tolerance=tolerance, sweeps=sweeps, step=k, slow=slow,
                             step_ms=1e3 * seconds, rows=int(b.size), replay_dy=np.nan))
        return solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps)

    # the kept steps again, in Python from the same state: their problems recorded (the step's solve, and its solve
    # island by island, in Python too, so that they call the recording solve_cones)
    compiled = {name: getattr(stepping, name) for name in ("solve_problem", "_solve_islands")
                if hasattr(stepping, name)}  # (a checkout before them calls solve_cones in moreau_step itself)
    stepping.solve_cones = recorded
    for name, function in compiled.items():
        setattr(stepping, name, function.py_func)
    try:
        for k in sorted(chosen):
            seconds, (*before, after), slow = chosen[k]
            replayed = tuple(a.copy() for a in before)
            count = len(problems)
            step(stepping.moreau_step.py_func, replayed)
            for problem in problems[count:]:  # 0 where the replay is the native step bit for bit
                problem["replay_dy"] = float(np.max(np.abs(replayed[0] - after)))
    finally:
        stepping.solve_cones = solve
        for name, function in compiled.items():
            setattr(stepping, name, function)
    if not problems:
        raise ValueError(f"{path.name}: no kept step had a contact problem (raise it with --lift, or run longer)")
    arrays = {f"{name}_{n}": np.asarray(problem[name]) for n, problem in enumerate(problems) for name in FIELDS}
    meta = dict(model=path.name, steps=steps, lift=lift, dt=dt, method=scene.file_method,
                kept=[{key: problem[key] for key in ("step", "slow", "step_ms", "rows", "replay_dy")}
                      for problem in problems])
    temporary = out.with_name(out.name + ".partial.npz")
    np.savez(temporary, meta=np.array(json.dumps(meta)), **arrays)
    os.replace(temporary, out)
    times = sorted(seconds for seconds, _k, _states in slowest)
    print(f"{path.name}: {steps} steps; kept the problems of {len(chosen)} ({len(slowest)} slowest, "
          f"{1e3 * times[0]:.2f} to {1e3 * times[-1]:.2f} ms a step) in {out}; the replayed steps end "
          f"{sum(p['replay_dy'] == 0.0 for p in problems)} of {len(problems)} bit for bit on the native ones, the "
          f"others within {max(p['replay_dy'] for p in problems):.1e}")


def load(path: Path) -> tuple[dict, list[dict]]:
    if not path.is_file():
        raise ValueError(f"problems={str(path)!r}: no such file (write one with `capture`)")
    with np.load(path) as data:
        meta = json.loads(str(data["meta"]))
        problems = [{name: data[f"{name}_{n}"] for name in FIELDS} for n in range(len(meta["kept"]))]
    return meta, problems


def _kept_size(p: np.ndarray) -> int:
    """The length of the step's kept memory (moreau_step's end_geometry) in the checkout imported: broadphase.kept_size,
    or in a checkout before the broad phase's neighbour list (2026-11-30) the kept geometry alone."""
    from rbody.engine.contacts import broadphase, rows

    if hasattr(broadphase, "kept_size"):
        return broadphase.kept_size(p)
    from rbody.engine import multibody
    from rbody.engine.constraints.jacobians import unit_count
    return rows.kept_geometry_size(int(p[multibody.H_NQ]), unit_count(p))


def _solve_before_solve_cones(cone_solve):
    """A checkout before solve_cones (2026-11-29): its step's solve, the same calls written in its moreau_step."""
    def solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps):
        residual = cone_solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps)
        if residual > tolerance:
            lam[:] = 0.0
            residual = cone_solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps)
        return residual
    return solve


def solve_times(problems: list[dict], repeats: int) -> list[tuple[list[float], float]]:
    """Each problem solved `repeats` times from its start, as the step solves it: (seconds of each, residual)."""
    from rbody.engine.constraints import stepping

    solve = getattr(stepping, "solve_cones", None) or _solve_before_solve_cones(stepping.cone_solve)

    def once(problem):
        lam = problem["lam"].copy()
        start = time.perf_counter()
        residual = solve(problem["W"], problem["b"], problem["lo"], problem["hi"], problem["role"], problem["mu"],
                         lam, float(problem["tolerance"]), int(problem["sweeps"]))
        return time.perf_counter() - start, residual

    once(problems[0])  # compiles
    results = []
    for problem in problems:
        seconds, residual = zip(*(once(problem) for _ in range(repeats)))
        results.append((list(seconds), residual[-1]))
    return results


def header() -> None:
    import numba

    from validation.machine import describe_machine

    print(f"{describe_machine()}; numpy {np.__version__}, numba {numba.__version__}")


def time_suite(path: Path, repeats: int, as_json: bool) -> None:
    if repeats < 1:
        raise ValueError(f"repeats={repeats}: expected at least 1")
    meta, problems = load(path)
    results = solve_times(problems, repeats)
    import rbody

    if as_json:
        print(json.dumps(dict(rbody=str(Path(rbody.__file__).resolve().parents[1]),
                              results=[dict(seconds=s, residual=r) for s, r in results])))
        return
    header()
    print(f"{meta['model']}: the problems of {len(problems)} steps of {meta['steps']} "
          f"(lift {meta['lift']} m, dt {meta['dt']} s, {meta['method']}); rbody from {Path(rbody.__file__).parent}")
    print("| step | rows | kept as | replay's max \\|dy\\| | min / median / max [ms] | residual | tolerance |")
    print("|---|---|---|---|---|---|---|")
    for info, problem, (seconds, residual) in zip(meta["kept"], problems, results):
        ms = 1e3 * np.array(seconds)
        print(f"| {info['step']} | {info['rows']} | {'slowest' if info['slow'] else 'spread'} | "
              f"{info.get('replay_dy', float('nan')):.1e} | {ms.min():.3f} / "
              f"{np.median(ms):.3f} / {ms.max():.3f} | {residual:.2g} | {float(problem['tolerance']):.2g} |")
    for kind, slow in (("slowest", True), ("spread", False)):
        total = sum(min(s) for info, (s, _r) in zip(meta["kept"], results) if info["slow"] == slow)
        print(f"{kind}: sum of minima {1e3 * total:.2f} ms")


def _checkouts(other: Path) -> dict[str, Path]:
    """This checkout and `other` (refused unless it is a checkout of rbody), by name."""
    if not (other / "rbody" / "__init__.py").is_file():
        raise ValueError(f"other={str(other)!r}: not a checkout of rbody (no rbody/__init__.py there)")
    return {"this": HERE.parents[1], "other": other.resolve()}


def _child(name: str, root: Path, arguments: list[str]) -> dict:
    """This script run with `arguments` (ending in --json) by the checkout at root, in its own process: its JSON
    answer, checked to come from that checkout's rbody."""
    env = dict(os.environ, RBODY_ROOT=str(root), PYTHONPATH=str(root))
    done = subprocess.run([sys.executable, str(HERE), *arguments], env=env, check=True, capture_output=True,
                          text=True)
    answer = json.loads(done.stdout.strip().splitlines()[-1])
    if Path(answer["rbody"]) != root:
        raise RuntimeError(f"the {name} checkout's run imported rbody from {answer['rbody']}, not {root}")
    return answer


def compare(path: Path, other: Path, repeats: int) -> None:
    if repeats < 1:
        raise ValueError(f"repeats={repeats}: expected at least 1")
    roots = _checkouts(other)
    meta, problems = load(path)
    header()
    best = {name: [np.inf] * len(problems) for name in roots}
    residual = {}
    for repeat in range(repeats):
        for name, root in roots.items():
            results = _child(name, root, ["time", str(path), "--repeats", str(WITHIN), "--json"])["results"]
            best[name] = [min(b, *r["seconds"]) for b, r in zip(best[name], results)]
            residual[name] = [r["residual"] for r in results]
        print(f"  round {repeat + 1} of {repeats}", file=sys.stderr, flush=True)
    print(f"{meta['model']}: {len(problems)} problems; this = {roots['this']}, other = {roots['other']}; the "
          f"minimum of {repeats} processes each, alternating, {WITHIN} solves each")
    print("| step | rows | kept as | this [ms] | other [ms] | this / other | residual this | residual other |")
    print("|---|---|---|---|---|---|---|---|")
    for n, info in enumerate(meta["kept"]):
        a, b = 1e3 * best["this"][n], 1e3 * best["other"][n]
        print(f"| {info['step']} | {info['rows']} | {'slowest' if info['slow'] else 'spread'} | {a:.3f} | {b:.3f} | "
              f"{a / b:.2f} | {residual['this'][n]:.2g} | {residual['other'][n]:.2g} |")
    for kind, slow in (("slowest", True), ("spread", False)):
        chosen = [n for n, info in enumerate(meta["kept"]) if info["slow"] == slow]
        a, b = (1e3 * sum(best[name][n] for n in chosen) for name in ("this", "other"))
        print(f"{kind}: this {a:.2f} ms, other {b:.2f} ms, ratio {a / b:.2f}")


def census_runs(path: Path, steps: int, lift: float, runs: int) -> dict:
    """The model run natively `runs` times from its first state: each run's step times [s], and each step's residual
    and rows (those of the first run; a run repeats them bit for bit)."""
    import rbody
    from rbody.engine.constraints import stepping

    if steps < 1 or runs < 1:
        raise ValueError(f"steps={steps} and runs={runs}: expected positive counts")
    _scene, dt, step, first = _native_run(path, steps, lift)
    step(stepping.moreau_step, tuple(a.copy() for a in first))  # compiles
    seconds, residuals, rows = [], [], []
    for run in range(runs):
        state = tuple(a.copy() for a in first)
        times = []
        for k in range(steps):
            start = time.perf_counter()
            status, residual, m = step(stepping.moreau_step, state)
            times.append(time.perf_counter() - start)
            if status != 0:
                raise rbody.SimulationError(f"{path.name}: step {k} (t = {k * dt:g} s) left the residual "
                                            f"{residual:.3g}")
            if run == 0:
                residuals.append(float(residual))
                rows.append(int(m))
        seconds.append(times)
        print(f"  run {run + 1} of {runs}", file=sys.stderr, flush=True)
    return dict(rbody=str(Path(rbody.__file__).resolve().parents[1]), seconds=seconds, residual=residuals, rows=rows)


def census(path: Path, steps: int, lift: float, runs: int, other: Path | None) -> None:
    """Print the census (module docstring) of this checkout, and of `other` beside it."""
    if other is None:
        results = {"this": census_runs(path, steps, lift, runs)}
    else:
        roots = _checkouts(other)
        if steps < 1 or runs < 1:
            raise ValueError(f"steps={steps} and runs={runs}: expected positive counts")
        results = {name: dict(seconds=[]) for name in roots}
        for run in range(runs):
            for name, root in roots.items():
                answer = _child(name, root, ["census", str(path), "--steps", str(steps), "--lift", repr(lift),
                                             "--runs", "1", "--json"])
                results[name]["seconds"] += answer["seconds"]
                results[name].update(rbody=answer["rbody"], residual=answer["residual"], rows=answer["rows"])
            print(f"  round {run + 1} of {runs}", file=sys.stderr, flush=True)
    print(f"{path.name}: {steps} steps (lift {lift} m), {runs} runs of each checkout; per step the minimum over the "
          f"runs [us]; steps accepted above {ROUND_GOAL:g}")
    print("| checkout | sum [ms] | mean of each run [us] | median | 90% | 99% | max | steps > 1 ms | > 5 ms | "
          f"above {ROUND_GOAL:g} |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    minima = {}
    for name, result in results.items():
        seconds = 1e6 * np.array(result["seconds"])
        best = minima[name] = seconds.min(axis=0)
        residual = np.array(result["residual"])
        quantiles = np.percentile(best, [50, 90, 99])
        print(f"| {name} ({result['rbody']}) | {best.sum() / 1e3:.1f} | "
              f"{' / '.join(f'{run.mean():.0f}' for run in seconds)} | {quantiles[0]:.1f} | {quantiles[1]:.1f} | "
              f"{quantiles[2]:.0f} | {best.max():.0f} | {int((best > 1e3).sum())} | {int((best > 5e3).sum())} | "
              f"{int((residual > ROUND_GOAL).sum())} |")
    for name, result in results.items():
        residual = np.array(result["residual"])
        above = np.flatnonzero(residual > ROUND_GOAL)
        slowest = np.argsort(minima[name])[::-1][:10]
        print(f"{name}: above {ROUND_GOAL:g}: "
              + (", ".join(f"{k} ({residual[k]:.1e})" for k in above[:30]) or "none")
              + ("" if above.size <= 30 else f", and {above.size - 30} more"))
        print(f"{name}: slowest: " + ", ".join(f"{k} ({minima[name][k] / 1e3:.1f} ms, {residual[k]:.0e})"
                                               for k in slowest))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    cap = commands.add_parser("capture")
    cap.add_argument("model", type=Path)
    cap.add_argument("out", type=Path)
    cap.add_argument("--steps", type=int, default=1000)
    cap.add_argument("--lift", type=float, default=0.0, help="raise the free body by this [m] at the start")
    cap.add_argument("--keep", type=int, default=24)
    tim = commands.add_parser("time")
    tim.add_argument("problems", type=Path)
    tim.add_argument("--repeats", type=int, default=5)
    tim.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    com = commands.add_parser("compare")
    com.add_argument("problems", type=Path)
    com.add_argument("other", type=Path, help="another checkout of rbody (a git worktree)")
    com.add_argument("--repeats", type=int, default=5)
    cen = commands.add_parser("census")
    cen.add_argument("model", type=Path)
    cen.add_argument("--steps", type=int, default=1000)
    cen.add_argument("--lift", type=float, default=0.0, help="raise the free body by this [m] at the start")
    cen.add_argument("--runs", type=int, default=2)
    cen.add_argument("--other", type=Path, help="another checkout of rbody (a git worktree), run alternately")
    cen.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.command == "census" and args.json:
        print(json.dumps(census_runs(args.model, args.steps, args.lift, args.runs)))
    elif args.command == "census":
        header()
        census(args.model, args.steps, args.lift, args.runs, args.other)
    elif args.command == "capture":
        header()
        capture(args.model, args.out, args.steps, args.lift, args.keep)
    elif args.command == "time":
        time_suite(args.problems, args.repeats, args.json)
    else:
        compare(args.problems, args.other, args.repeats)


if __name__ == "__main__":
    main()
