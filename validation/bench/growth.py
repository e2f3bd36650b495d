"""How cost grows: pi collisions against digits, the chain against its links, a batch against its size.

Each is fitted as cost ~ x^p on log-log axes (least squares on the logs), p given in the summary:

- pi: rbody's exact event run of pi_collisions(N) (heavy ball at 10^-N m/s), N = 0..8, against the number
  of impacts floor(pi 10^N): the time of building the scene (which runs the events once to find when
  the last impact happens, t_end) and of simulate (the sampled run), fitted from N = 4 on (below, the
  fixed cost of a call dominates).
- chain: n = 2..32 unit rods at theta0 from 0.3 to 0.1 rad, dt = 1e-3 for 5 s: rbody rk4 and gauss6 on
  the chain's own kernel (the n x n mass matrix solved by Cholesky at each evaluation, n^3 / 3 flops),
  rbody rk4 on the general engine (Scene.from_layout of the same chain: the articulated-body algorithm,
  linear in n), MuJoCo RK4 (contacts and constraints disabled), pymunk; cost per simulated second
  against n, each the work that gives the observables (meta["run_seconds"]). Pinocchio, where it is
  installed (the optional extra `bench`): its forward dynamics pin.aba on the model it reads from rbody's
  MJCF, timed per call from Python and counted 4 times per step (an RK4 step's evaluations; the
  integration itself is not counted), after a check that its accelerations are rbody's (CHAIN_AGREEMENT).
- batch: seconds per step of a batch of rods against its size (from validation.bench.batch), from
  64 rods on (one rod leaves a core idle).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np


PI_DIGITS = {False: tuple(range(9)), True: tuple(range(6))}
PI_GOALS = {7: 1.0, 8: 10.0}  # digits -> seconds
PI_FIT_FROM = 4
CHAIN_LINKS = {False: (2, 4, 8, 16, 32), True: (2, 4, 8)}
CHAIN_T_END = {False: 5.0, True: 0.2}  # [s]: long enough that the fixed cost of a call does not dominate
CHAIN_DT = 1e-3
# Pinocchio's and rbody's forward dynamics at a random state must agree to this (relative to max |qdd|)
# before Pinocchio's time is reported: the same model, read from rbody's MJCF.
CHAIN_AGREEMENT = 1e-10
ABA_PER_RK4_STEP = 4
BATCH_FIT_FROM = 64
COLUMNS = ("kind", "backend", "method", "x", "work", "seconds", "seconds_construct", "seconds_per_sim_second",
           "repeats", "failure")


def _best(run, budget: float = 2.0, repeats: int = 5):
    """min wall time of run() over up to `repeats` calls (fewer once `budget` seconds are spent), the
    number of calls, and the last call's result."""
    times: list[float] = []
    started = time.perf_counter()
    while len(times) < repeats and (not times or time.perf_counter() - started < budget):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return min(times), len(times), result


def pi_growth(quick: bool) -> list[dict]:
    import rbody
    from rbody import scenes

    rows = []
    scenes.pi_collisions(0, speed=1.0)  # compile or load the event kernels
    for digits in PI_DIGITS[quick]:
        speed = 10.0**-digits
        construct, _, scene = _best(lambda: scenes.pi_collisions(digits, speed=speed), budget=1.0)
        seconds, repeats, run = _best(lambda: rbody.simulate(scene, dt=scene.t_end / 100), budget=1.0)
        count = int(run["collisions"][-1])
        failure = "" if count == scene.expected_collisions else f"miscount: {count}, exact {scene.expected_collisions}"
        rows.append({"kind": "pi", "backend": "rbody", "method": "events", "x": digits,
                     "work": scene.expected_collisions, "seconds": seconds, "seconds_construct": construct,
                     "seconds_per_sim_second": seconds / scene.t_end, "repeats": repeats, "failure": failure})
    return rows


def chain_growth(quick: bool) -> list[dict]:
    import validation
    from rbody import scenes
    from rbody.errors import SimulationError

    from rbody.scene import Scene

    runs = (("rbody", "rk4", {"method": "rk4"}), ("rbody", "gauss6", {"method": "gauss6"}),
            ("rbody", "rk4 general engine", {"method": "rk4"}),
            ("mujoco", "RK4", {"integrator": "RK4"}), ("pymunk", "chipmunk", {}))
    t_end = CHAIN_T_END[quick]
    rows = []
    for links in CHAIN_LINKS[quick]:
        chain = scenes.pendulum_chain(links, theta0=np.linspace(0.3, 0.1, links), t_end=t_end)
        general = Scene.from_layout(chain.layout, t_end=t_end, name=f"chain_{links}")
        for backend, method, settings in runs:
            scene = general if method.endswith("general engine") else chain
            save_every = max(1, round(t_end / CHAIN_DT / 100))
            row = {"kind": "chain", "backend": backend, "method": method, "x": links, "work": links,
                   "seconds": math.nan, "seconds_construct": math.nan, "seconds_per_sim_second": math.nan,
                   "repeats": 0, "failure": ""}
            try:
                validation.run(scene, backend, dt=CHAIN_DT, save_every=save_every, **settings)  # warm-up
                seconds = []
                started = time.perf_counter()
                while len(seconds) < 5 and (not seconds or time.perf_counter() - started < 2.0):
                    run = validation.run(scene, backend, dt=CHAIN_DT, save_every=save_every, **settings)
                    seconds.append(float(run.meta["run_seconds"]))
                row.update(seconds=min(seconds), seconds_per_sim_second=min(seconds) / float(run.t[-1]),
                           repeats=len(seconds))
            except (SimulationError, ValueError, NotImplementedError) as error:
                row["failure"] = f"{type(error).__name__}: {str(error).splitlines()[0][:150]}"
            rows.append(row)
        rows.append(pinocchio_chain_row(chain, links))
    return rows


def pinocchio_chain_row(chain, links: int) -> dict:
    """Pinocchio's forward dynamics on the chain (module docstring): a row with its cost per simulated
    second at CHAIN_DT, or the reason it is missing (not installed, or not the same model)."""
    import os
    import tempfile

    from rbody.engine.multibody import Multibody
    from rbody.mjcf import to_mjcf

    row = {"kind": "chain", "backend": "pinocchio", "method": f"aba x {ABA_PER_RK4_STEP} per step", "x": links,
           "work": links, "seconds": math.nan, "seconds_construct": math.nan, "seconds_per_sim_second": math.nan,
           "repeats": 0, "failure": ""}
    try:
        import pinocchio
    except ImportError:
        row["failure"] = "not installed (pip install 'rbody[bench]')"
        return row
    folder = tempfile.mkdtemp()
    path = os.path.join(folder, "chain.xml")
    try:
        with open(path, "w") as f:
            f.write(to_mjcf(chain, dt=CHAIN_DT))
        model = pinocchio.buildModelFromMJCF(path)
    finally:
        if os.path.exists(path):
            os.remove(path)
        os.rmdir(folder)
    data = model.createData()
    rng = np.random.default_rng(links)
    q, v, tau = rng.normal(size=model.nq), rng.normal(size=model.nv), np.zeros(model.nv)
    theirs = np.asarray(pinocchio.aba(model, data, q, v, tau))
    ours = Multibody(chain.layout, gravity=chain.gravity).forward_dynamics(q, v)
    gap = float(np.max(np.abs(theirs - ours)) / np.max(np.abs(ours)))
    if not gap <= CHAIN_AGREEMENT:
        row["failure"] = f"not the same model: accelerations differ by {gap:.2g} of max |qdd| from rbody's"
        return row
    calls = 2000
    seconds, repeats, _ = _best(lambda: [pinocchio.aba(model, data, q, v, tau) for _ in range(calls)])
    per_call = seconds / calls
    row.update(seconds=per_call, seconds_per_sim_second=ABA_PER_RK4_STEP * per_call / CHAIN_DT, repeats=repeats)
    return row


def batch_growth(batch: dict | None) -> list[dict]:
    if batch is None:
        return []
    rows = []
    for r in batch["rows"]:
        if r["failure"] or not r["mode"].startswith(("rbody", "mujoco rollout")):
            continue
        per_step = r["seconds"] / r["steps"]
        rows.append({"kind": "batch", "backend": r["mode"].split()[0], "method": r["mode"], "x": r["size"],
                     "work": r["size"], "seconds": per_step, "seconds_construct": math.nan,
                     "seconds_per_sim_second": per_step / 1e-3, "repeats": r["repeats"], "failure": ""})
    return rows


def exponent(x, y) -> float:
    """p of y ~ x^p, least squares on log y against log x (NaN with fewer than two points)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    keep = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if keep.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(x[keep]), np.log(y[keep]), 1)[0])


def fits(rows: list[dict]) -> list[dict]:
    """One fitted exponent per (kind, backend, method)."""
    groups: dict[tuple, list] = {}
    for r in rows:
        if not r["failure"]:
            groups.setdefault((r["kind"], r["backend"], r["method"]), []).append(r)
    out = []
    for (kind, backend, method), mine in groups.items():
        if kind == "pi":
            mine = [r for r in mine if r["x"] >= PI_FIT_FROM]
            p = exponent([r["work"] for r in mine], [r["seconds"] for r in mine])
            q = exponent([r["work"] for r in mine], [r["seconds_construct"] for r in mine])
            out.append({"kind": kind, "backend": backend, "method": method, "against": "impacts", "p": p,
                        "p_construct": q})
        else:
            if kind == "batch":
                mine = [r for r in mine if r["x"] >= BATCH_FIT_FROM]
            out.append({"kind": kind, "backend": backend, "method": method,
                        "against": "links" if kind == "chain" else "rods", "p": exponent(
                            [r["x"] for r in mine], [r["seconds_per_sim_second"] for r in mine])})
    return out


def run_growth(out: Path, *, quick: bool, header: list[str], batch: dict | None = None, log=sys.stderr) -> dict:
    """growth.csv, growth.png and the summary's lines."""
    from validation.bench.csvfile import write_csv

    start = time.perf_counter()
    rows = pi_growth(quick)
    print(f"  growth: pi digits {PI_DIGITS[quick][-1]} ({time.perf_counter() - start:.1f} s)", file=log, flush=True)
    start = time.perf_counter()
    rows += chain_growth(quick)
    print(f"  growth: chain ({time.perf_counter() - start:.1f} s)", file=log, flush=True)
    rows += batch_growth(batch)
    write_csv(out / "growth.csv", rows, COLUMNS, header)
    fitted = fits(rows)
    figure = _plot(rows, fitted, out)
    return {"rows": rows, "fits": fitted, "figure": figure, "markdown": _markdown(rows, fitted, figure),
            "goals": _goals(rows, quick)}


def _plot(rows: list[dict], fitted: list[dict], out: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from validation.report import save_figure  # here, not at import: the batch workers stay without matplotlib

    p = {(f["kind"], f["method"]): f["p"] for f in fitted}
    figure, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    panels = (("pi", "impacts floor(pi 10^N)", "seconds per run"),
              ("chain", "links n", "seconds per simulated second"),
              ("batch", "rods in one call", "seconds per step of the batch"))
    for axis, (kind, xlabel, ylabel) in zip(axes, panels):
        methods = sorted({(r["backend"], r["method"]) for r in rows if r["kind"] == kind})
        for backend, method in methods:
            mine = [r for r in rows if r["kind"] == kind and r["method"] == method and r["backend"] == backend
                    and not r["failure"]]
            x = [r["work"] if kind == "pi" else r["x"] for r in mine]
            y = [r["seconds"] if kind in ("pi", "batch") else r["seconds_per_sim_second"] for r in mine]
            name = method if method.startswith(backend) else f"{backend} {method}"
            axis.loglog(x, y, "o-", label=f"{name} (p = {p.get((kind, method), math.nan):.2f})")
            if kind == "pi":
                axis.loglog(x, [r["seconds_construct"] for r in mine], "s--", label="building the scene (one run)")
        axis.set(xlabel=xlabel, ylabel=ylabel, title=f"cost growth: {kind}")
        axis.legend(fontsize=7)
    return save_figure(figure, out, "growth.png", dpi=100)


def _markdown(rows: list[dict], fitted: list[dict], figure: str) -> list[str]:
    lines = ["## How cost grows", "", "Fitted exponent p of cost ~ x^p (least squares on log-log):", "",
             "| what | backend | method | against | p |", "|---|---|---|---|---|"]
    for f in fitted:
        extra = f" (building the scene: {f['p_construct']:.2f})" if "p_construct" in f else ""
        lines.append(f"| {f['kind']} | {f['backend']} | {f['method']} | {f['against']} | {f['p']:.2f}{extra} |")
    pi = [r for r in rows if r["kind"] == "pi"]
    if pi:
        lines += ["", "| digits | impacts | simulate [s] | building the scene [s] | count |", "|---|---|---|---|---|"]
        lines += [f"| {r['x']} | {r['work']} | {r['seconds']:.3g} | {r['seconds_construct']:.3g} | "
                  f"{r['failure'] or 'exact'} |" for r in pi]
    chain = [r for r in rows if r["kind"] == "chain"]
    if chain:
        links = sorted({r["x"] for r in chain})
        methods = sorted({(r["backend"], r["method"]) for r in chain})
        lines += ["", "Chain, seconds per simulated second at dt = 1e-3 (pinocchio: 4 forward-dynamics calls per "
                  "step from Python, the integration not counted):", "",
                  "| links | " + " | ".join(f"{b} {m}" for b, m in methods) + " |", "|---|" + "---|" * len(methods)]
        for n in links:
            cells = []
            for b, m in methods:
                r = next(r for r in chain if r["x"] == n and r["backend"] == b and r["method"] == m)
                cells.append(r["failure"][:40] if r["failure"] else f"{r['seconds_per_sim_second']:.3g}")
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines + ["", f"![growth]({figure})"]


def _goals(rows: list[dict], quick: bool) -> list[str]:
    lines = []
    for digits, limit in PI_GOALS.items():
        row = next((r for r in rows if r["kind"] == "pi" and r["x"] == digits), None)
        if row is None:
            lines.append(f"- pi digits {digits} under {limit:g} s: not measured in this (quick) run.")
            continue
        total = row["seconds"] + row["seconds_construct"]
        lines.append(f"- pi digits {digits} under {limit:g} s: {'met' if total < limit else 'missed'} (simulate "
                     f"{row['seconds']:.3g} s + building the scene {row['seconds_construct']:.3g} s = {total:.3g} s"
                     + (f"; {row['failure']}" if row["failure"] else "") + ").")
    return lines
