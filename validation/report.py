"""The report: a Markdown page with the results table and PNG figures (matplotlib, no screen needed)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rbody.files import atomic_path, write_atomic  # noqa: E402
from rbody.trajectory import Trajectory  # noqa: E402

COLOURS = {"exact": "black", "rbody": "tab:blue", "mujoco": "tab:orange", "pymunk": "tab:green",
           "pinocchio": "tab:purple", "bullet": "tab:red"}
STYLES = {"exact": "-", "rbody": "--", "mujoco": "-.", "pymunk": ":", "pinocchio": ":", "bullet": "-"}


def format_value(value: float | None) -> str:
    if value is None:
        return "-"
    if value == int(value) and abs(value) < 1e6:
        return str(int(value))
    return f"{value:.3g}"


def table(rows: Iterable, *, markdown: bool = False) -> str:
    """The results table: scene, backend, metric, value, tolerance, verdict, wall time."""
    header = ("scene", "backend", "metric", "value", "tolerance", "verdict", "time [s]")
    lines = [(r.case, r.backend, r.metric, format_value(r.value), format_value(r.tolerance), r.verdict,
              f"{r.seconds:.2f}") for r in rows]
    if markdown:
        out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        out += ["| " + " | ".join(line) + " |" for line in lines]
        return "\n".join(out)
    widths = [max(len(h), *(len(line[k]) for line in lines)) if lines else len(h) for k, h in enumerate(header)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join([fmt.format(*header), fmt.format(*("-" * w for w in widths))] + [fmt.format(*line) for line in lines])


def notes(rows: Iterable) -> str:
    """Why each backend refused or failed, and each finding's tolerance reason."""
    out = []
    for r in rows:
        if r.verdict in ("refused", "failed", "FINDING"):
            out.append(f"- **{r.case} / {r.backend}** ({r.verdict}): {r.note}")
    return "\n".join(out)


# ----- figures -----------------------------------------------------------------------------------

def save_figure(figure, out: Path, name: str, *, dpi: int = 110, tight: bool = True) -> str:
    """Write `figure` as out/name (through a temporary name, then renamed) and close it; returns name.
    tight: lay it out with tight_layout first (False where the caller has laid it out itself)."""
    path = out / name
    if tight:
        figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=dpi, format=path.suffix.lstrip(".") or "png")
    plt.close(figure)
    return name


def figure_race(runs: Mapping[str, Trajectory], exact: Mapping[str, np.ndarray], labels, out: Path) -> str:
    """Distance against time for each body of the race: exact and each engine."""
    figure, axis = plt.subplots(figsize=(7, 4.2))
    t_exact = exact["t"]
    for k, label in enumerate(labels):
        axis.plot(t_exact, exact["distance"][:, k], color="black", lw=1)
        for backend, run in runs.items():
            axis.plot(run.t, run["distance"][:, k], STYLES[backend], color=COLOURS[backend], lw=1.5,
                      label=f"{backend}" if k == 0 else None)
        axis.annotate(label, (t_exact[-1], exact["distance"][-1, k]), fontsize=8)
    axis.plot([], [], color="black", lw=1, label="exact")
    axis.set(xlabel="t [s]", ylabel="distance down the slope [m]", title="The rolling race")
    axis.legend()
    return save_figure(figure, out, "rolling_race.png")


def figure_pendulum(runs: Mapping[str, Trajectory], exact_of, out: Path, name: str, title: str) -> str:
    """theta against time (top) and the energy error against time (bottom)."""
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    first = next(iter(runs.values()))
    exact = exact_of(first.t)
    top.plot(first.t, exact["theta"], color="black", lw=1, label="exact")
    for backend, run in runs.items():
        top.plot(run.t, run["theta"], STYLES[backend], color=COLOURS[backend], lw=1.2, label=backend)
        e = exact_of(run.t)
        drift = np.abs(run["energy"] - e["energy"]) / np.max(np.abs(e["energy"]))
        bottom.semilogy(run.t, np.maximum(drift, 1e-17), color=COLOURS[backend], lw=1, label=backend)
    top.set(ylabel="theta [rad]", title=title)
    bottom.set(xlabel="t [s]", ylabel="|E - E*| / |E*|")
    top.legend(loc="upper right")
    return save_figure(figure, out, name)


def figure_pi(counts: Mapping[str, Mapping[int, int]], out: Path) -> str:
    """Digits of pi each backend gets right, against the number of digits asked for."""
    from validation.tolerances import pi_digits_right

    figure, axis = plt.subplots(figsize=(6, 4))
    for backend, by_digits in counts.items():
        digits = sorted(by_digits)
        axis.plot(digits, [pi_digits_right(by_digits[d], d) for d in digits], "o" + STYLES[backend],
                  color=COLOURS[backend], label=backend)
    top = max((max(v) for v in counts.values() if v), default=4)
    axis.plot([0, top], [1, top + 1], color="black", lw=0.8, label="all digits right")
    axis.set(xlabel="digits asked for N (mass ratio 100^N)", ylabel="leading digits of pi right",
             title="Collision counts: digits of pi")
    axis.legend()
    return save_figure(figure, out, "pi_digits.png")


def figure_rotation(runs: Mapping[str, Trajectory], out: Path) -> str:
    """Drift of the invariants of free rotation: energy and |L| against time."""
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for backend, run in runs.items():
        energy = run["energy"]
        momentum = np.linalg.norm(run["L_world"], axis=-1)
        top.semilogy(run.t, np.maximum(np.abs(energy / energy[0] - 1), 1e-17), color=COLOURS[backend], label=backend)
        bottom.semilogy(run.t, np.maximum(np.abs(momentum / momentum[0] - 1), 1e-17), color=COLOURS[backend],
                        label=backend)
    top.set(ylabel="|E/E0 - 1|", title="Free rotation: invariants")
    bottom.set(xlabel="t [s]", ylabel="||L|/|L0| - 1|")
    top.legend()
    return save_figure(figure, out, "free_rotation.png")


def figure_series(runs: Mapping[str, Trajectory], exact_of, name: str, columns: Mapping[str, str], ylabel: str,
                  title: str, out: Path, file: str) -> str:
    """Observable `name` against time, exact (solid black) and each engine; columns: label -> index
    expression for a (T, k) observable ("" for a (T,) one)."""
    figure, axis = plt.subplots(figsize=(7, 4.2))
    first = next(iter(runs.values()))
    t = np.linspace(0.0, float(first.t[-1]), 800)
    exact = np.asarray(exact_of(t)[name])
    for k, (label, index) in enumerate(columns.items()):
        pick = (lambda a: a) if index == "" else (lambda a, i=int(index): a[:, i])
        axis.plot(t, pick(exact), color="black", lw=1, label="exact" if k == 0 else None)
        for backend, run in runs.items():
            axis.plot(run.t, pick(np.asarray(run[name])), STYLES[backend], color=COLOURS[backend], lw=1.3,
                      label=backend if k == 0 else None)
        axis.annotate(label, (t[-1], pick(exact)[-1]), fontsize=8)
    axis.set(xlabel="t [s]", ylabel=ylabel, title=title)
    axis.legend()
    return save_figure(figure, out, file)


def figure_orbit(runs: Mapping[str, Trajectory], exact_of, out: Path) -> str:
    """The two bodies' paths in the x-z plane: exact (solid black) and each engine."""
    figure, axis = plt.subplots(figsize=(6, 6))
    first = next(iter(runs.values()))
    exact = exact_of(np.linspace(0.0, float(first.t[-1]), 2000))
    for body in ("r1", "r2"):
        axis.plot(exact[body][:, 0], exact[body][:, 2], color="black", lw=1, label="exact" if body == "r1" else None)
        for backend, run in runs.items():
            axis.plot(run[body][:, 0], run[body][:, 2], STYLES[backend], color=COLOURS[backend], lw=1.3,
                      label=backend if body == "r1" else None)
    axis.set(xlabel="x [m]", ylabel="z [m]", title="The two-body problem: orbits about the centre of mass",
             aspect="equal")
    axis.legend()
    return save_figure(figure, out, "two_body.png")


def write(out: Path, rows: list, figures: list[tuple[str, str]], header: str, regressions: list[str],
          animations: list[tuple[str, str]] = ()) -> Path:
    """report.md with the header, the table, the notes, the figures, the animations (caption, file name) and
    the regressions."""
    parts = [header, "## Results", "", table(rows, markdown=True), "",
             "A verdict `ok` means the value is within the tolerance of validation/tolerances.py (its reason "
             "is in the notes); `FINDING` means it is outside: a disagreement with the closed form, "
             "measured and reported, not hidden; `refused` means the simulator cannot express the scene; "
             "`-` means the value is reported without a bound.", "", "## Notes", "", notes(rows), ""]
    for caption, name in figures:
        parts += [f"### {caption}", "", f"![{caption}]({name})", ""]
    if animations:
        parts += ["## The scenes in motion", "",
                  "Each engine's run of the scene side by side (validation/animations.py, drawn by rbody.animate).", ""]
        for caption, name in animations:
            parts += [f"### {caption}", "", f"![{caption}]({name})", ""]
    parts += ["## Regressions against baselines", ""]
    parts += [f"- {message}" for message in regressions] or ["none"]
    path = out / "report.md"
    write_atomic(path, "\n".join(parts) + "\n")
    return path
