"""Hard case 8: long pendulum chains, every method and MuJoCo's RK4 on the exported MJCF."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rbody.scenes import pendulum_chain
from validation.hard.rows import CaseResult, HardRow, error_outcome, short
from validation.hard.kit import energy_bounded, envelope, rbody_verdict, run_backend

# ----- 8. long chains ---------------------------------------------------------------------------------

CHAIN_LINKS = (2, 8, 32)
CHAIN_METHODS = ("gauss6", "rk4", "euler", "verlet")
CHAIN_DT = 1e-3
PINOCCHIO_LINKS = 8   # Pinocchio's runs (a Python loop over aba, ~40 us a step) up to this many links
CHAIN_THETA = 0.5  # every rod starts at this absolute angle [rad]


def _departure(t: np.ndarray, a: np.ndarray, b: np.ndarray, threshold: float = 1e-3) -> float:
    """First time [s] at which max |a - b| over the rods exceeds threshold [rad] (inf if never)."""
    gap = np.max(np.abs(a - b), axis=-1)
    over = np.flatnonzero(gap > threshold)
    return float(t[over[0]]) if over.size else math.inf


def case_long_chains(quick: bool, out: Path) -> CaseResult:
    from validation.hard.figures import figure_panels

    t_end = 10.0 if quick else 100.0
    links = (2, 8) if quick else CHAIN_LINKS
    result = CaseResult(
        8, "Long pendulum chains",
        f"pendulum_chain with {', '.join(map(str, links))} unit rods, all at {CHAIN_THETA} rad, {t_end:g} s at "
        f"dt = {CHAIN_DT:g} s: every method's energy drift; gauss6 (symplectic for any Hamiltonian) bounded; the "
        "explicit symplectic ones refused (the mass matrix depends on the angles); MuJoCo RK4 on the MJCF export "
        "and pymunk measured the same way, and how long each stays within 1e-3 rad of rbody's gauss6.")
    panels = []
    for n in links:
        scene = pendulum_chain(n, theta0=np.full(n, CHAIN_THETA), t_end=t_end)
        variant = f"{n} links"
        curves, runs = {}, {}
        for method in CHAIN_METHODS:
            trajectory, error, seconds = run_backend(scene, "rbody", CHAIN_DT, method=method, save_every=10)
            if error is not None:
                outcome = error_outcome(error)
                verdict, reason = rbody_verdict(scene, method, CHAIN_DT, None, outcome) if method in scene.methods \
                    else ("pass", "")
                result.rows.append(HardRow(variant, "rbody", f"{method} dt={CHAIN_DT:g}", outcome, None, "energy drift",
                                           seconds, verdict, "; ".join(x for x in (short(error), reason) if x)))
                continue
            drift = float(np.max(np.abs(trajectory["energy"] - trajectory["energy"][0])) / _energy_scale(scene))
            wrong = ""
            if method == "gauss6" and not energy_bounded(trajectory["energy"], round(t_end / CHAIN_DT)):
                wrong = "gauss6's energy drifted instead of staying bounded"
            if drift > 1.0:
                wrong = f"energy error {drift:.3g}: the run is meaningless"
            verdict, reason = rbody_verdict(scene, method, CHAIN_DT, None, "error", wrong)
            runs[method] = trajectory
            curves[method] = envelope(trajectory.t,
                                      (trajectory["energy"] - trajectory["energy"][0]) / _energy_scale(scene))
            result.rows.append(HardRow(variant, "rbody", f"{method} dt={CHAIN_DT:g}", "error", drift, "energy drift",
                                       seconds, verdict, reason))
        reference = runs.get("gauss6")
        for backend, settings, label in (("mujoco", {"integrator": "RK4"}, "RK4"), ("pymunk", {}, "pymunk"),
                                         ("pinocchio", {"method": "rk4"}, "Pinocchio rk4"), ("bullet", {}, "Bullet")):
            if backend == "pinocchio" and n > PINOCCHIO_LINKS:
                result.rows.append(HardRow(variant, backend, f"{label} dt={CHAIN_DT:g}", "not run", None, "-", 0.0,
                                           "", f"{round(t_end / CHAIN_DT):d} steps of a Python loop over pin's aba on "
                                           f"{n} links: over the case's budget (its rk4 is rbody's rk4 on the 2 and "
                                           "8 links above)"))
                continue
            trajectory, error, seconds = run_backend(scene, backend, CHAIN_DT, save_every=10, **settings)
            if error is not None:
                result.rows.append(HardRow(variant, backend, f"{label} dt={CHAIN_DT:g}", error_outcome(error), None,
                                           "energy drift", seconds, "", short(error)))
                continue
            drift = float(np.max(np.abs(trajectory["energy"] - trajectory["energy"][0])) / _energy_scale(scene))
            note = ""
            if reference is not None and reference.t.size == trajectory.t.size:
                note = (f"within 1e-3 rad of rbody gauss6 until t = "
                        f"{_departure(trajectory.t, trajectory['theta'], reference['theta']):.3g} s")
            curves[f"{label} (MuJoCo)" if backend == "mujoco" else label] = envelope(
                trajectory.t, (trajectory["energy"] - trajectory["energy"][0]) / _energy_scale(scene))
            result.rows.append(HardRow(variant, backend, f"{label} dt={CHAIN_DT:g}", "error", drift, "energy drift",
                                       seconds, "", note))
        if reference is not None and "rk4" in runs:
            together = _departure(reference.t, runs["rk4"]["theta"], reference["theta"])
            result.rows.append(HardRow(variant, "rbody", f"rk4 vs gauss6 dt={CHAIN_DT:g}", "error", together,
                                       "time within 1e-3 rad [s]", 0.0, "",
                                       "two accurate methods agree over the whole run" if math.isinf(together) else
                                       "the motion is chaotic: two accurate methods part after a time set by its "
                                       "Lyapunov exponent"))
        panels.append((variant, curves))
    result.figures.append((f"Pendulum chains: energy drift |E - E0| / (M g L) against time, dt = {CHAIN_DT:g} s",
                           figure_panels(panels, out, "hard_chains.png", "Pendulum chains: energy drift", "t [s]",
                                         "|E - E0| / (M g L)")))
    for n in links:
        drifts = {f"{r.backend} {r.setting.split(' dt=')[0]}": r.value for r in result.rows
                  if r.variant == f"{n} links" and r.measure == "energy drift" and r.value is not None}
        result.findings.append(f"{n} links, energy drift over {t_end:g} s: "
                               + ", ".join(f"{k} {v:.2g}" for k, v in drifts.items()) + ".")
    result.findings += [
        "gauss6 (symplectic for any Hamiltonian) keeps the chain's energy bounded; rk4 drifts, and MuJoCo's RK4 on "
        "the exported MJCF drifts the same (the same method on the same equations in the same coordinates); pymunk's "
        "pivot joints lose energy; verlet is refused before any work (the Hamiltonian is not separable).",
    ]
    return result


def _energy_scale(scene) -> float:
    """M g L of the chain [J]: total mass times g times total length."""
    return float(np.sum(scene.masses) * scene.gravity * np.sum(scene.lengths))


__all__ = ["case_long_chains"]
