"""The benchmark's figures and its Markdown summary (validation.bench.run)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Iterable, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LEVELS = (1e-3, 1e-6, 1e-9, 1e-12)
GOAL_RATIO = 10.0  # rbody at least this many times cheaper than the best other simulator
FLOOR, CEILING = 1e-17, 1e2  # error axis: zero error is drawn at FLOOR, larger or NaN errors at CEILING
COLOURMAPS = {"rbody": "Blues", "mujoco": "Oranges", "pymunk": "Greens"}
MARKERS = "osD^v<>ph*"
NAMES = {"rbody": "rbody", "mujoco": "MuJoCo", "pymunk": "pymunk"}


def _series_of(points: Iterable) -> dict[tuple[str, str, str], list]:
    out: dict[tuple[str, str, str], list] = {}
    for p in points:
        if not math.isnan(p.dt):
            out.setdefault((p.backend, p.method, p.settings), []).append(p)
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
        axis.set_ylabel("cost: seconds of stepping per simulated second")
    axes[2].set_ylim(FLOOR / 3, CEILING * 3)
    axes[2].set_ylabel(f"max |{bench.measure} - exact| [{bench.unit}]")
    axes[0].plot([], [], "x", color="black", label="failure (unstable, miscount, slip)")
    figure.legend(loc="lower center", ncol=4, fontsize=7, frameon=False)
    figure.tight_layout(rect=(0, 0.17, 1, 1))
    name = f"wp_{bench.name}.png"
    figure.savefig(out / name, dpi=100)
    plt.close(figure)
    return name


# ----- the summary -----------------------------------------------------------------------------------

def cheapest(points: Iterable, scene: str, backend: str, level: float):
    """The cheapest valid point of `backend` on `scene` with error <= level, or None."""
    good = [p for p in points if p.scene == scene and p.backend == backend and not p.failure
            and p.error <= level and not math.isnan(p.seconds_per_sim_second)]
    return min(good, key=lambda p: p.seconds_per_sim_second) if good else None


def _cell(point) -> str:
    if point is None:
        return "never"
    setting = "" if point.settings in ("default",) or point.settings.startswith("exact") else f", {point.settings}"
    return f"{point.seconds_per_sim_second:.2g} ({point.method}{setting}, dt={point.dt:.3g})"


def level_table(points: Sequence, scene: str, backends: Sequence[str]) -> tuple[str, list[dict]]:
    """Markdown table of the cheapest cost per level and backend, and rbody's standing at each level."""
    others = [b for b in backends if b != "rbody"]
    lines = ["| error <= | " + " | ".join(NAMES.get(b, b) for b in backends) + " | best other / rbody |",
             "|---|" + "---|" * (len(backends) + 1)]
    standing = []
    for level in LEVELS:
        best = {b: cheapest(points, scene, b, level) for b in backends}
        rival = min((best[b] for b in others if best[b] is not None), key=lambda p: p.seconds_per_sim_second,
                    default=None)
        own = best.get("rbody")
        if own is not None and rival is not None:
            ratio = rival.seconds_per_sim_second / own.seconds_per_sim_second
            verdict = f"{ratio:.3g}x" + ("" if ratio >= GOAL_RATIO else " (goal 10x missed)")
        elif own is not None:
            ratio, verdict = math.inf, "only rbody reaches it"
        elif rival is not None:
            ratio, verdict = 0.0, "rbody never reaches it"
        else:
            ratio, verdict = math.nan, "none reaches it"
        standing.append({"scene": scene, "level": level, "ratio": ratio, "rbody": own, "rival": rival})
        lines.append(f"| {level:.0e} | " + " | ".join(_cell(best[b]) for b in backends) + f" | {verdict} |")
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


def write_summary(out: Path, points: Sequence, benches: Sequence, figures: Sequence[str], batch, growth,
                  header: Sequence[str], *, quick: bool, seconds: float) -> Path:
    """summary.md: per scene the cheapest cost at each error level, the goals, batch and growth results."""
    parts = ["# Speed against error: rbody, MuJoCo and pymunk", ""]
    parts += [f"- {line}" for line in header]
    parts += [f"- wall time of this benchmark: {seconds:.0f} s", "",
              "Cost is seconds of stepping per simulated second (lower is better): after one warm-up run per "
              "series, the minimum over up to 5 timed runs (bench.csv's `repeats` says how many). A cell gives "
              "the cheapest point of that backend, over all its methods and settings, whose error is at or "
              "below the level; `never` means no point of the sweep got there. The last column is the cost "
              "of the best of MuJoCo and pymunk divided by rbody's (how many times cheaper rbody is).", ""]
    standings = []
    for bench, figure in zip(benches, figures):
        backends = ["rbody", "mujoco", "pymunk"]
        table, standing = level_table(points, bench.name, backends)
        standings += standing
        parts += [f"## {bench.name}", "", f"{bench.scene.describe()}. Error: max abs error of `{bench.measure}` "
                  f"[{bench.unit}] against {'the reference run' if bench.reference else 'the exact solution'}."
                  + (f" {bench.note}." if bench.note else ""), "", table, ""]
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
    path.write_text("\n".join(parts) + "\n")
    return path


def goals(standings: Sequence[dict], batch, growth, t_end: dict[str, float] | None = None) -> list[str]:
    """The issue's goals, each met or missed with the measured margin and, for a miss, where rbody's time
    goes: the fixed cost of a simulate call (measured by bench.batch) or the steps themselves."""
    lines = ["## Goals", ""]
    missed = [s for s in standings if 0 <= s["ratio"] < GOAL_RATIO]
    reached = [s for s in standings if s["rival"] is not None]
    lines.append(f"- rbody >= {GOAL_RATIO:g}x cheaper than the best of MuJoCo and pymunk at every level they reach: "
                 + ("met" if reached and not missed else "not met" if missed else "no level reached by them")
                 + f" ({len(reached) - len(missed)} of {len(reached)} (scene, level) pairs).")
    serial = batch["single"]["one thread"]["call_us"] * 1e-6 if batch is not None else None
    launch = batch["single"]["default"]["call_us"] * 1e-6 if batch is not None else None
    for s in missed:
        own, rival = s["rbody"], s["rival"]
        if own is None:
            lines.append(f"  - {s['scene']} at {s['level']:.0e}: rbody never reaches it; {NAMES[rival.backend]} "
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
                     f"{own.seconds_per_sim_second:.2g} s/s against {NAMES[rival.backend]} {rival.method} "
                     f"dt={rival.dt:.3g} at {rival.seconds_per_sim_second:.2g} s/s.{why}")
    only = sorted({(s["scene"], s["level"]) for s in standings if s["ratio"] == math.inf})
    lines.append("- levels only rbody reaches: "
                 + (", ".join(f"{scene} {level:.0e}" for scene, level in only) or "none"))
    for source in (batch, growth):
        if source is not None:
            lines += source["goals"]
    return lines
