"""The benchmark's figures and its Markdown summary (validation.bench.run)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rbody.files import write_atomic  # noqa: E402
from validation.bench.scenes import REDUCED_LABEL  # noqa: E402
from validation.report import save_figure  # noqa: E402

LEVELS = (1e-3, 1e-6, 1e-9, 1e-12)
GOAL_RATIO = 10.0  # rbody at least this many times cheaper than the best other simulator
FLOOR, CEILING = 1e-17, 1e2  # error axis: zero error is drawn at FLOOR, larger or NaN errors at CEILING
COLOURMAPS = {"rbody": "Blues", "mujoco": "Oranges", "pymunk": "Greens", "pinocchio": "Purples", "bullet": "Reds"}
MARKERS = "osD^v<>ph*"
NAMES = {"rbody": "rbody", "mujoco": "MuJoCo", "pymunk": "pymunk", "pinocchio": "Pinocchio", "bullet": "Bullet",
         "mujoco reduced": "MuJoCo on rbody's reduction"}



def _series_of(points: Iterable) -> dict[tuple[str, str, str], list]:
    """(backend, method, settings) -> its points, one per dt: over repeated runs the run of median cost
    (the errors of the runs are the same; their costs differ by the machine's noise)."""
    runs: dict[tuple[str, str, str], dict[float, list]] = {}
    for p in points:
        if not math.isnan(p.dt):
            runs.setdefault((p.backend, p.method, p.settings), {}).setdefault(p.dt, []).append(p)
    out: dict[tuple[str, str, str], list] = {}
    for key, by_dt in runs.items():
        for same in by_dt.values():
            ranked = sorted(same, key=lambda q: (math.isnan(q.seconds_per_sim_second), q.seconds_per_sim_second))
            out.setdefault(key, []).append(ranked[(len(ranked) - 1) // 2])
    return out


def _estimated_cost(point, series: list) -> float:
    """Cost of a point that has none (unstable): cost x dt of the series' measured points / dt."""
    if not math.isnan(point.seconds_per_sim_second):
        return point.seconds_per_sim_second
    known = [q.seconds_per_sim_second * q.dt for q in series if not math.isnan(q.seconds_per_sim_second)]
    return float(np.median(known)) / point.dt if known else math.nan


def _clip(value: float) -> float:
    if math.isnan(value) or value > CEILING:
        return CEILING
    return max(value, FLOOR)


def plot_scene(points: Sequence, bench, out: Path) -> str:
    """wp_<scene>.png: error (left) and energy drift (middle) against cost, one line per backend, method
    and setting, and error against dt (right: an event-driven run is a flat line there); failures as
    crosses (at the top or right edge when there is no finite error)."""
    series = _series_of(p for p in points if p.scene == bench.name)
    figure, axes = plt.subplots(1, 3, figsize=(17, 6.4))
    by_backend: dict[str, list] = {}
    for key in series:
        by_backend.setdefault(key[0], []).append(key)
    for backend, keys in by_backend.items():
        colours = plt.get_cmap(COLOURMAPS.get(backend, "Greys"))(np.linspace(0.45, 0.95, len(keys)))
        for k, key in enumerate(keys):
            rows = sorted(series[key], key=lambda p: -p.dt)
            style = dict(ls="-" if key[2] == "default" or key[2].startswith("exact") else "--",
                         marker=MARKERS[k % len(MARKERS)], color=colours[k], ms=4, lw=1.3)
            label = f"{NAMES.get(backend, backend)} {key[1]}" + ("" if key[2] == "default" else f" [{key[2]}]")
            good = [p for p in rows if not p.failure and not math.isnan(p.seconds_per_sim_second)]
            bad = [p for p in rows if p.failure and not p.failure.startswith("not run")]
            costs = [_estimated_cost(p, rows) for p in bad]
            for axis, field in zip(axes[:2], ("error", "energy_drift")):
                axis.plot([_clip(getattr(p, field)) for p in good], [p.seconds_per_sim_second for p in good],
                          label=label if field == "error" else None, **style)
                axis.plot([_clip(getattr(p, field)) for p in bad], costs, "x", color=colours[k], ms=8, mew=2)
            axes[2].plot([p.dt for p in good], [_clip(p.error) for p in good], **style)
            axes[2].plot([p.dt for p in bad], [_clip(p.error) for p in bad], "x", color=colours[k], ms=8, mew=2)
    titles = (f"{bench.name}: work against precision", "energy drift", "error against the time step")
    xlabels = (f"max |{bench.measure} - exact| [{bench.unit}]  (x: failure)", "max |E - E*| / max |E*|",
               "dt [s] (event-driven: the sampling interval)")
    for axis, title, xlabel in zip(axes, titles, xlabels):
        axis.set_xscale("log")
        axis.set_yscale("log")
        axis.set_title(title)
        axis.set_xlabel(xlabel)
        axis.grid(True, which="major", lw=0.3)
        for level in LEVELS:
            (axis.axhline if axis is axes[2] else axis.axvline)(level, color="grey", lw=0.6, ls=":")
    for axis in axes[:2]:
        axis.set_xlim(FLOOR / 3, CEILING * 3)
        axis.set_ylabel("cost: seconds per simulated second (stepping and observables)")
    axes[2].set_ylim(FLOOR / 3, CEILING * 3)
    axes[2].set_ylabel(f"max |{bench.measure} - exact| [{bench.unit}]")
    axes[0].plot([], [], "x", color="black", label="failure (unstable, miscount, slip)")
    figure.legend(loc="lower center", ncol=4, fontsize=7, frameon=False)
    figure.tight_layout(rect=(0, 0.17, 1, 1))
    return save_figure(figure, out, f"wp_{bench.name}.png", dpi=100, tight=False)


# ----- the summary -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Reading:
    """A cost read off one series' work-precision curve at an error level: the series (backend, method,
    settings), the time step [s] and cost [s per simulated second] there (interpolated: between two
    neighbouring points, in log-log, else a measured point's)."""

    backend: str
    method: str
    settings: str
    dt: float
    seconds_per_sim_second: float
    interpolated: bool = False


def column(point) -> str:
    """The table column of a point: its backend, or "mujoco reduced" for MuJoCo on rbody's reduction."""
    if point.backend == "mujoco" and point.settings.startswith(REDUCED_LABEL):
        return "mujoco reduced"
    return point.backend


def _log(value: float) -> float:
    return math.log(max(value, FLOOR))


def curve_cost(series: Sequence, level: float) -> Reading | None:
    """The least cost at which one series (the points of one backend, method and setting in one run) reaches
    error <= level on its work-precision curve: its valid points (no failure) in dt order, each pair of
    neighbours joined by a straight line in log error - log cost (and log dt); a point at or below the level
    counts as it is, a pair that crosses the level gives the cost where its line does. No extrapolation
    beyond the measured points; a failed point breaks the curve."""
    rows = sorted((p for p in series if not math.isnan(p.dt)), key=lambda p: -p.dt)
    valid = [not p.failure and np.isfinite(p.error) and np.isfinite(p.seconds_per_sim_second) for p in rows]
    best: Reading | None = None

    def offer(reading: Reading) -> None:
        nonlocal best
        if best is None or reading.seconds_per_sim_second < best.seconds_per_sim_second:
            best = reading

    for i, p in enumerate(rows):
        if valid[i] and p.error <= level:
            offer(Reading(p.backend, p.method, p.settings, p.dt, p.seconds_per_sim_second))
        if i + 1 < len(rows) and valid[i] and valid[i + 1]:
            q = rows[i + 1]
            lo, hi = sorted((p.error, q.error))
            if lo <= level < hi:  # the line between the two crosses the level
                s = (_log(level) - _log(p.error)) / (_log(q.error) - _log(p.error))
                cost = math.exp(_log(p.seconds_per_sim_second)
                                + s * (_log(q.seconds_per_sim_second) - _log(p.seconds_per_sim_second)))
                dt = math.exp(math.log(p.dt) + s * (math.log(q.dt) - math.log(p.dt)))
                offer(Reading(p.backend, p.method, p.settings, dt, cost, interpolated=True))
    return best


def cheapest(points: Iterable, scene: str, key: str, level: float, run: int | None = None) -> Reading | None:
    """The least cost of column `key` (a backend, or "mujoco reduced") on `scene` at error <= level, over all
    its series, read off each series' curve (curve_cost); run: only the points of that run."""
    series: dict[tuple, list] = {}
    for p in points:
        if p.scene == scene and column(p) == key and (run is None or p.run == run):
            series.setdefault((p.method, p.settings), []).append(p)
    readings = [r for rows in series.values() if (r := curve_cost(rows, level)) is not None]
    return min(readings, key=lambda r: r.seconds_per_sim_second) if readings else None


def _cell(reading: Reading | None, spread: tuple[float, float] | None = None) -> str:
    if reading is None:
        return "never"
    setting = ("" if reading.settings in ("default",) or reading.settings.startswith("exact")
               else f", {reading.settings.removeprefix(REDUCED_LABEL)}")
    cost = f"{reading.seconds_per_sim_second:.2g}"
    if spread is not None and spread[1] > spread[0]:
        cost += f" [{spread[0]:.2g}..{spread[1]:.2g}]"
    where = f"dt~{reading.dt:.3g}" if reading.interpolated else f"dt={reading.dt:.3g}"
    return f"{cost} ({reading.method}{setting}, {where})"


def _ratio_text(ratios: list[float]) -> str:
    """The median ratio over the runs and its range: '21.3x (19.8-22.0)'."""
    finite = sorted(r for r in ratios if np.isfinite(r))
    median = float(np.median(finite))
    text = f"{median:.3g}x"
    if len(finite) > 1:
        text += f" ({finite[0]:.3g}..{finite[-1]:.3g})"
    return text + ("" if median >= GOAL_RATIO else " (goal 10x missed)")


def level_table(points: Sequence, scene: str, backends: Sequence[str]) -> tuple[str, list[dict]]:
    """Markdown table of each column's cost per level (the median over the runs, read off the curves) and
    rbody's standing: the best other column's cost over rbody's, per run, its median and range.

    backends: the columns, "rbody" first (a backend, or "mujoco reduced")."""
    runs = sorted({int(p.run) for p in points if p.scene == scene}) or [1]
    others = [b for b in backends if b != "rbody"]
    lines = ["| error <= | " + " | ".join(NAMES.get(b, b) for b in backends)
             + " | best other / rbody: median (range over runs) |", "|---|" + "---|" * (len(backends) + 1)]
    standing = []
    for level in LEVELS:
        per_run = {r: {b: cheapest(points, scene, b, level, r) for b in backends} for r in runs}
        cells, medians, partial = [], {}, []
        for b in backends:
            costs = [per_run[r][b].seconds_per_sim_second for r in runs if per_run[r][b] is not None]
            if len(costs) < len(runs):  # reached in some runs only: shown as not reached
                cells.append("never" if not costs else f"{_cell(per_run[runs[0]][b])} (in {len(costs)} of {len(runs)} runs)")
                medians[b] = None
                partial += [b] if costs else []
                continue
            median = float(np.median(costs))
            middle = min((per_run[r][b] for r in runs), key=lambda x: abs(x.seconds_per_sim_second - median))
            medians[b] = Reading(middle.backend, middle.method, middle.settings, middle.dt, median, middle.interpolated)
            cells.append(_cell(medians[b], (min(costs), max(costs))))
        own = medians.get("rbody")
        rival = min((medians[b] for b in others if medians[b] is not None), key=lambda x: x.seconds_per_sim_second,
                    default=None)
        ratios = []
        if own is not None and rival is not None:
            for r in runs:
                mine = per_run[r]["rbody"]
                theirs = [per_run[r][b] for b in others if per_run[r][b] is not None]
                ratios.append(min(x.seconds_per_sim_second for x in theirs) / mine.seconds_per_sim_second)
            ratio, verdict = float(np.median(ratios)), _ratio_text(ratios)
        elif own is not None and [b for b in partial if b != "rbody"]:
            ratio, verdict = math.nan, "others reach it in some runs only"
        elif own is not None:
            ratio, verdict = math.inf, "only rbody reaches it"
        elif rival is not None:
            ratio, verdict = 0.0, "rbody never reaches it"
        else:
            ratio, verdict = math.nan, "none reaches it"
        standing.append({"scene": scene, "level": level, "ratio": ratio, "ratios": ratios, "rbody": own,
                         "rival": rival})
        lines.append(f"| {level:.0e} | " + " | ".join(cells) + f" | {verdict} |")
    return "\n".join(lines), standing


def _failures(points: Sequence, scene: str) -> list[str]:
    """One line per backend and kind of failure on a scene."""
    kinds: dict[tuple[str, str], list] = {}
    for p in points:
        if p.scene == scene and p.failure:
            kind = p.failure.split(":")[0]
            kinds.setdefault((p.backend, kind), []).append(p)
    lines = []
    for (backend, kind), rows in sorted(kinds.items()):
        example = rows[0]
        reason = example.failure[len(kind) + 1:].strip()
        where = ("" if math.isnan(example.dt)
                 else f" (e.g. {example.method} [{example.settings}] at dt={example.dt:.3g})")
        lines.append(f"- {NAMES.get(backend, backend)}: {len(rows)} x {kind}{where}: {reason}")
    return lines


def peer_settings(bench) -> str:
    """One line per scene: the settings each backend was swept with (every series is in the table)."""
    by_backend: dict[str, list[str]] = {}
    for series in bench.series:
        key = "mujoco reduced" if series.settings.startswith(REDUCED_LABEL) else series.backend
        label = series.settings.removeprefix(REDUCED_LABEL)
        methods = by_backend.setdefault(key, [])
        entry = f"{series.method} [{label}]"
        if entry not in methods:
            methods.append(entry)
    parts = [f"{NAMES.get(k, k)}: {', '.join(v)}" for k, v in by_backend.items() if k != "rbody"]
    return "Series swept: " + "; ".join(parts) + "." if parts else ""


def write_summary(out: Path, points: Sequence, benches: Sequence, figures: Sequence[str], batch, growth,
                  header: Sequence[str], *, quick: bool, seconds: float) -> Path:
    """summary.md: per scene the cheapest cost at each error level, the goals, batch and growth results."""
    parts = ["# Speed against error: rbody, MuJoCo, pymunk and the peers Pinocchio and Bullet", ""]
    parts += [f"- {line}" for line in header]
    runs = sorted({int(p.run) for p in points}) or [1]
    parts += [f"- wall time of this benchmark: {seconds:.0f} s; runs of every sweep: {len(runs)}", "",
              "**The same work on every side.** Cost is wall seconds per simulated second (lower is better) of "
              "the work that turns an initial state into the scene's observables at the saved times: for rbody "
              "the whole `rbody.simulate` call (model, stability check, stepping, every observable); for MuJoCo "
              "the `mujoco.rollout` of the model with the sensors that record the observed quantities, the "
              "contact onsets and the translation into the observables (`run_seconds`); for pymunk the "
              "`space.step` loop with the reading of every saved body state and the same translation. Model "
              "compilation is charged to no one. (The other way, timing stepping alone everywhere, would need "
              "rbody to defer its observables; its call would then still hold the model and the stability "
              "check.) bench.csv also gives the stepping alone (`stepping_seconds_per_sim_second`).", "",
              "**Read off the curves.** Each point is the minimum over up to 5 timed runs after one warm-up run "
              "per series. A cell gives the least cost at which a column reaches the level: over all its methods "
              "and settings, on each series' work-precision curve, between two neighbouring valid points by "
              "straight-line interpolation in log error - log cost (`dt~`), or at a measured point (`dt=`); never "
              "by extrapolation. `never`: no series got there. "
              + (f"**Over {len(runs)} runs.** Every sweep was run {len(runs)} times; a cell is the median "
                 "cost over the runs [min..max], and the last column the ratio of the best other column's cost to "
                 "rbody's, computed in each run: its median (min..max over the runs)." if len(runs) > 1 else
                 "**One run**: the ratios carry the noise of one run on this machine (use --repeat 3)."),
              "",
              "**Each peer at its best.** MuJoCo: its four integrators; models without contact pairs run with "
              "contacts and the constraint solver disabled (`<flag contact=\"disable\" constraint=\"disable\"/>`); "
              "where rbody integrates a reduced model (rolling), MuJoCo also runs the same reduction in its own "
              "column (slide + armature I/R^2; slide + hinge + joint equality), beside its contact model with "
              "the best contact settings found and with noslip iterations. pymunk: its defaults and more solver "
              "work, per scene below. Pinocchio: its aba by rk4, a Python loop over pin's bindings (its cost is "
              "theirs as much as the algorithm's). Bullet: semi-implicit Euler over dt and, on contacts, its "
              "solver iterations and contact ERP (validation/bench/scenes.py). The last column takes the cheapest "
              "of all other columns.", ""]
    standings = []
    for bench, figure in zip(benches, figures):
        reduced = any(column(p) == "mujoco reduced" for p in points if p.scene == bench.name)
        backends = ["rbody", "mujoco"] + (["mujoco reduced"] if reduced else []) + ["pymunk"] + [
            peer for peer in ("pinocchio", "bullet") if any(p.backend == peer and p.scene == bench.name
                                                            and not math.isnan(p.dt) for p in points)]
        table, standing = level_table(points, bench.name, backends)
        standings += standing
        parts += [f"## {bench.name}", "", f"{bench.scene.describe()}. Error: max abs error of `{bench.measure}` "
                  f"[{bench.unit}] against {'the reference run' if bench.reference else 'the exact solution'}."
                  + (f" {bench.note}." if bench.note else ""), "", peer_settings(bench), "", table, ""]
        failures = _failures(points, bench.name)
        if failures:
            parts += ["Failures (crosses in the figure):", ""] + failures + [""]
        parts += [f"![{bench.name}]({figure})", ""]
    if batch is not None:
        parts += batch["markdown"] + [""]
    if growth is not None:
        parts += growth["markdown"] + [""]
    parts += goals(standings, batch, growth, {b.name: b.scene.t_end for b in benches})
    path = out / "summary.md"
    write_atomic(path, "\n".join(parts) + "\n")
    return path


def _label(reading: Reading) -> str:
    """'MuJoCo RK4', or 'MuJoCo on rbody's reduction (slide + armature I/R^2) RK4'."""
    if reading.settings.startswith(REDUCED_LABEL):
        return f"{NAMES['mujoco reduced']} ({reading.settings.removeprefix(REDUCED_LABEL)}) {reading.method}"
    return f"{NAMES.get(reading.backend, reading.backend)} {reading.method}"


def goals(standings: Sequence[dict], batch, growth, t_end: dict[str, float] | None = None) -> list[str]:
    """The issue's goals, each met or missed with the measured margin and, for a miss, where rbody's time
    goes: the fixed cost of a simulate call (measured by bench.batch) or the steps themselves."""
    lines = ["## Goals", ""]
    missed = [s for s in standings if 0 <= s["ratio"] < GOAL_RATIO]
    reached = [s for s in standings if s["rival"] is not None]
    lines.append(f"- rbody >= {GOAL_RATIO:g}x cheaper than the best of the other engines at every level they reach: "
                 + ("met" if reached and not missed else "not met" if missed else "no level reached by them")
                 + f" ({len(reached) - len(missed)} of {len(reached)} (scene, level) pairs).")
    serial = batch["single"]["one thread"]["call_us"] * 1e-6 if batch is not None else None
    launch = batch["single"]["default"]["call_us"] * 1e-6 if batch is not None else None
    for s in missed:
        own, rival = s["rbody"], s["rival"]
        if own is None:
            lines.append(f"  - {s['scene']} at {s['level']:.0e}: rbody never reaches it; {_label(rival)} "
                         f"does at {rival.seconds_per_sim_second:.2g} s/s.")
            continue
        why = ""
        if t_end and s["scene"] in t_end:
            run = own.seconds_per_sim_second * t_end[s["scene"]]
            steps = max(1, round(t_end[s["scene"]] / own.dt))
            why = f" rbody's run: {steps} steps in {run * 1e6:.0f} us"
            if serial is not None and run < 3 * serial:
                why += (f", mostly the fixed cost of a simulate call ({serial * 1e6:.0f} us for one step of the rod "
                        "on one thread: building the model, observing, dispatching)")
            elif launch is not None and launch > 3 * serial and run < 3 * launch:
                why += (f", mostly the launch of the parallel loop for a batch of one on the shared cores (a "
                        f"one-step call: {launch * 1e6:.0f} us with numba's threads against {serial * 1e6:.0f} us "
                        "on one thread)")
            else:
                why += f", {run / steps * 1e9:.0f} ns per step: the steps themselves"
            why += "."
        lines.append(f"  - {s['scene']} at {s['level']:.0e}: {s['ratio']:.3g}x (short by a factor "
                     f"{GOAL_RATIO / s['ratio']:.2g}): rbody {own.method} dt={own.dt:.3g} at "
                     f"{own.seconds_per_sim_second:.2g} s/s against {_label(rival)} "
                     f"dt={rival.dt:.3g} at {rival.seconds_per_sim_second:.2g} s/s.{why}")
    only = sorted({(s["scene"], s["level"]) for s in standings if s["ratio"] == math.inf})
    lines.append("- levels only rbody reaches: "
                 + (", ".join(f"{scene} {level:.0e}" for scene, level in only) or "none"))
    for source in (batch, growth):
        if source is not None:
            lines += source["goals"]
    return lines
