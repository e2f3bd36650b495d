"""Figures of the hard cases (PNG, matplotlib without a screen), drawn in the report's colours."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from validation.report import COLOURS, plt, save_figure

METHOD_COLOURS = {"euler": "tab:red", "symplectic_euler": "tab:pink", "verlet": "tab:blue", "rk4": "tab:orange",
                  "yoshida6": "tab:green", "gauss6": "tab:purple", "splitting": "tab:cyan", "reference": "black",
                  "Euler": "tab:brown", "RK4": "tab:olive", "implicit": "tab:gray", "implicitfast": "gold",
                  "pymunk": "darkgreen", "mujoco": "tab:orange", "Pinocchio": "indigo", "Bullet": "darkred"}
# MuJoCo's integrators dashed, pymunk dotted, rbody's methods solid.
MUJOCO_LABELS = ("Euler", "RK4", "implicit", "implicitfast")


def _style(label: str) -> tuple[str, str]:
    """(colour, line style) of a curve labelled '<method or integrator or backend> ...'."""
    key = label.split(" ")[0]
    style = "--" if key in MUJOCO_LABELS else ":" if key == "pymunk" else "-." if key in ("Pinocchio", "Bullet") else "-"
    return METHOD_COLOURS.get(key, "black"), style
FLOOR = 1e-17  # below round-off: drawn at the floor of the log axis


def figure_pi_time(points: Mapping[str, Sequence[tuple[float, int, int]]], out: Path) -> str:
    """Leading digits of pi right against the time of the run, one marker per run.

    points: backend -> [(seconds, digits right, digits asked for N)]."""
    figure, axis = plt.subplots(figsize=(7, 4.2))
    for backend, runs in points.items():
        if not runs:
            continue
        seconds = np.maximum([r[0] for r in runs], 1e-4)
        right = [r[1] for r in runs]
        axis.semilogx(seconds, right, "o", color=COLOURS.get(backend, "black"), label=backend, alpha=0.8)
        if backend == "rbody":
            axis.semilogx(seconds, right, "-", color=COLOURS["rbody"], lw=0.8)
    axis.set(xlabel="time of the run [s] (rbody: the whole run; MuJoCo, pymunk: their stepping)",
             ylabel="leading digits of pi right",
             title="pi collisions: digits right against time")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend()
    return save_figure(figure, out, "hard_pi_digits_time.png")


def figure_drift(curves: Mapping[str, tuple[np.ndarray, np.ndarray]], out: Path, name: str, title: str,
                 xlabel: str, ylabel: str) -> str:
    """Log-log drift curves: label -> (x (T,), |drift| (T,))."""
    figure, axis = plt.subplots(figsize=(7.5, 4.5))
    for label, (x, y) in curves.items():
        colour, style = _style(label)
        x, y = np.asarray(x, float), np.maximum(np.abs(np.asarray(y, float)), FLOOR)
        keep = x > 0
        axis.loglog(x[keep], y[keep], style, color=colour, lw=1.1, label=label)
    axis.set(xlabel=xlabel, ylabel=ylabel, title=title)
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=8, ncol=2)
    return save_figure(figure, out, name)


def figure_panels(panels: Sequence[tuple[str, Mapping[str, tuple[np.ndarray, np.ndarray]]]], out: Path, name: str,
                  title: str, xlabel: str, ylabel: str, *, logx: bool = True) -> str:
    """Side-by-side log drift panels sharing the y axis: [(panel title, label -> (x, |y|))]."""
    figure, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.2), sharey=True, squeeze=False)
    for axis, (panel, curves) in zip(axes[0], panels):
        for label, (x, y) in curves.items():
            colour, style = _style(label)
            x, y = np.asarray(x, float), np.maximum(np.abs(np.asarray(y, float)), FLOOR)
            keep = x > 0 if logx else np.ones(x.shape, bool)
            plot = axis.loglog if logx else axis.semilogy
            plot(x[keep], y[keep], style, color=colour, lw=1.1, label=label)
        axis.set(title=panel, xlabel=xlabel)
        axis.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel(ylabel)
    axes[0][-1].legend(fontsize=7)
    figure.suptitle(title)
    return save_figure(figure, out, name)


def figure_step_outcomes(grid: Mapping[str, Sequence[tuple[float, str]]], out: Path, name: str, title: str) -> str:
    """Outcome of each method against dt / (its stability limit): one row of markers per method."""
    markers = {"refused": ("s", "tab:blue"), "blew up": ("x", "tab:red"), "correct": ("o", "tab:green"),
               "inaccurate": ("o", "lightgray"), "wrong": ("X", "black")}
    figure, axis = plt.subplots(figsize=(7, 0.45 * len(grid) + 1.6))
    labels = list(grid)
    for k, label in enumerate(labels):
        for factor, outcome in grid[label]:
            marker, colour = markers.get(outcome, ("o", "gray"))
            axis.semilogx([factor], [k], marker, color=colour, ms=8)
    for outcome, (marker, colour) in markers.items():
        axis.plot([], [], marker, color=colour, label=outcome)
    axis.axvline(1.0, color="black", lw=0.8)
    axis.set_yticks(range(len(labels)), labels, fontsize=8)
    axis.set(xlabel="dt / estimated stability limit", title=title)
    axis.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return save_figure(figure, out, name)


__all__ = ["figure_pi_time", "figure_drift", "figure_panels", "figure_step_outcomes"]
