"""Hard cases 2 and 3: the swinging rod near the top, free rotation near the intermediate axis."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

import rbody
from rbody import stability
from rbody.engine.methods import SYMPLECTIC
from rbody.scenes import free_rotation, swinging_rod
from validation.hard.kit import EPS, energy_bounded, envelope, mean_period, rbody_verdict, run_backend
from validation.hard.rows import CaseResult, HardRow, attempt, error_outcome, short

# ----- 2. the swinging rod near the top -----------------------------------------------------------

GAPS = (1e-3, 1e-6, 1e-9)
NEAR_TOP_METHODS = ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6")
NEAR_TOP_H = 0.05     # dt w0 of rbody's runs
OTHER_DT = 1e-3       # MuJoCo's and pymunk's step [s]
THETA_TOLERANCE = 1e-11  # |theta - theta_mpmath| [rad] the exact solution must meet near the top


def mp_theta(theta0: float, length: float, gravity: float, t: np.ndarray, dps: int = 50) -> tuple[np.ndarray, float]:
    """theta(t) (T,) [rad] of the rod released at rest from theta0, and its period [s], in mpmath at dps
    digits: sin(theta/2) = k sn(w0 t + K | k^2), cos(theta/2) = dn(...), w0^2 = 3 g / (2 L), from the
    float inputs exactly."""
    import mpmath

    with mpmath.workdps(dps):
        th, g, L = mpmath.mpf(theta0), mpmath.mpf(gravity), mpmath.mpf(length)
        w0 = mpmath.sqrt(g * (L / 2) / (L * L / 3))  # M g d / I, M = 1
        m = mpmath.sin(th / 2) ** 2
        K = mpmath.ellipk(m)
        k = mpmath.sqrt(m)
        out = np.empty(len(t))
        for j, tj in enumerate(t):
            u = w0 * mpmath.mpf(float(tj)) + K
            out[j] = float(2 * mpmath.atan2(k * mpmath.ellipfun("sn", u, m=m), mpmath.ellipfun("dn", u, m=m)))
        return out, float(4 * K / w0)


def _scipy_theta(theta0: float, w0: float, t: np.ndarray) -> np.ndarray:
    """The same with scipy.special.ellipj at m = sin^2(theta0/2) in float64 (for the finding)."""
    from scipy.special import ellipj, ellipk

    m = math.sin(theta0 / 2) ** 2
    with np.errstate(all="ignore"):
        sn, _cn, dn, _ph = ellipj(w0 * t + ellipk(m), m)
        return 2 * np.arctan2(math.sqrt(m) * sn, dn)


def _exact_rows(gap: float, result: CaseResult) -> str:
    """Period and theta(t) of rbody's closed form against mpmath; returns the scipy finding."""
    theta0 = math.pi - gap
    scene = swinging_rod(1.0, theta0=theta0, t_end=1.0)
    t = np.linspace(0.0, 3 * scene.period, 301)
    (reference, period), seconds = _timed(mp_theta, theta0, 1.0, scene.gravity, t)
    exact, exact_seconds = _timed(scene.exact, t)
    error = float(np.max(np.abs(exact["theta"] - reference)))
    period_error = abs(scene.period - period) / period
    variant = f"pi - {gap:g}"
    result.rows.append(HardRow(variant, "rbody", "period 4 K(k^2)/w0 (ellipkm1)", "exact" if period_error <= 4 * EPS
                               else "error", period_error, "period rel. error vs mpmath", exact_seconds,
                               "pass" if period_error <= 4 * EPS else "FAIL", f"mpmath period {period!r} s"))
    ok = error <= THETA_TOLERANCE
    result.rows.append(HardRow(variant, "rbody", "exact theta(t), 3 periods", "exact" if ok else "error", error,
                               "max |theta - theta_mpmath| [rad]", exact_seconds, "pass" if ok else "FAIL",
                               f"mpmath at 50 digits took {seconds:.1f} s" + ("" if ok else
                               f"; above {THETA_TOLERANCE:g} rad: u0 = F(phi0 | m) is evaluated at phi0 = fl(pi/2), "
                               "whose cosine 6.1e-17 is not small against sqrt(1 - m)")))
    w0 = math.sqrt(1.5 * scene.gravity)
    scipy_error = float(np.nanmax(np.abs(_scipy_theta(theta0, w0, t) - reference))) if np.any(
        np.isfinite(_scipy_theta(theta0, w0, t))) else float("nan")
    return f"pi - {gap:g}: {scipy_error:.2g} rad"


def _timed(function, *args):
    result, error, seconds = attempt(function, *args)
    if error is not None:
        raise error
    return result, seconds


def _near_top_run(scene, backend: str, dt: float, period: float, settings: dict):
    """(row fields, energy curve (t/period, |dE/E0|) or None) of one long run near the top."""
    trajectory, error, seconds = run_backend(scene, backend, dt, **settings)
    if error is not None:
        return (error_outcome(error), None, short(error), seconds, None), None
    theta, omega, energy = trajectory["theta"], trajectory["omega"], trajectory["energy"]
    measured, count = mean_period(trajectory.t, theta, omega)
    drift = np.abs(energy - energy[0]) / abs(energy[0])
    whirl = bool(np.max(np.abs(theta)) > math.pi)
    note = f"{count} crossings, energy drift {np.max(drift):.3g}"
    if whirl:
        note += f"; the swing turned into a whirl (max |theta| {np.max(np.abs(theta)):.3g} rad)"
    value = abs(measured - period) / period if np.isfinite(measured) else None
    fields = ("error", value, note, seconds, (whirl, energy, float(np.max(drift))))
    return fields, envelope(trajectory.t / period, drift)


def case_near_top(quick: bool, out: Path) -> CaseResult:
    from validation.hard.figures import figure_panels

    periods = 100 if quick else 10_000
    other_periods = 10 if quick else 100
    result = CaseResult(
        2, "The swinging rod near the top (k -> 1)",
        "rbody's exact period and theta(t) match mpmath (period to 4 eps, theta to "
        f"{THETA_TOLERANCE:g} rad); each method runs {periods} periods at dt w0 = {NEAR_TOP_H} and keeps the swing "
        "a swing, the symplectic ones with bounded energy (rk4 drifts), or rbody refuses the run with a clear error "
        "where its stability or float64 resolution estimate (rbody.stability) says it cannot be right.")
    scipy_findings, panels = [], []
    for gap in GAPS:
        scipy_findings.append(_exact_rows(gap, result))
        theta0 = math.pi - gap
        probe = swinging_rod(1.0, theta0=theta0, t_end=1.0)
        period, w0 = probe.period, math.sqrt(1.5 * probe.gravity)
        variant = f"pi - {gap:g}"
        dt = NEAR_TOP_H / w0
        scene = swinging_rod(1.0, theta0=theta0, t_end=periods * period)
        curves = {}
        for method in NEAR_TOP_METHODS:
            (outcome, value, note, seconds, extra), curve = _near_top_run(
                scene, "rbody", dt, period, {"method": method, "save_every": 8})
            wrong = ""
            if extra is not None:
                whirl, energy, drift = extra
                if whirl:
                    wrong = "the swing turned into a whirl"
                elif method in SYMPLECTIC and not energy_bounded(energy, round(scene.t_end / dt)):
                    wrong = "the energy of a symplectic method drifted instead of staying bounded"
                elif drift > 1.0:
                    wrong = f"energy error {drift:.3g}: the run is meaningless"
                curves[method] = curve
            verdict, reason = rbody_verdict(scene, method, dt, None, outcome, wrong)
            result.rows.append(HardRow(variant, "rbody", f"{method} dt w0={NEAR_TOP_H}", outcome, value,
                                       f"period rel. error ({periods} periods)", seconds, verdict,
                                       "; ".join(x for x in (note, reason) if x)))
        short_scene = swinging_rod(1.0, theta0=theta0, t_end=other_periods * period)
        for backend, settings, label in (("mujoco", {"integrator": "RK4"}, "RK4"),
                                         ("mujoco", {"integrator": "Euler"}, "Euler"),
                                         ("pymunk", {}, "pymunk"), ("bullet", {}, "Bullet")):
            (outcome, value, note, seconds, _extra), curve = _near_top_run(
                short_scene, backend, OTHER_DT, period, dict(settings, save_every=10))
            if curve is not None:
                curves[f"{label} (dt={OTHER_DT:g})"] = curve
            result.rows.append(HardRow(variant, backend, f"{label} dt={OTHER_DT:g}", outcome, value,
                                       f"period rel. error ({other_periods} periods)", seconds, "", note))
        result.rows.append(HardRow(variant, "pinocchio", f"rk4 dt={OTHER_DT:g}", "not run", None, "-", 0.0, "",
                                   f"{round(short_scene.t_end / OTHER_DT):d} steps of a Python loop over pin's aba "
                                   "(~60 us a step here, minutes per gap: over the case's budget); on the rod its rk4 "
                                   "is rbody's rk4 to round-off (the main command's swinging_rod: both 4.43e-11 rad)"))
        if curves:
            panels.append((f"theta0 = pi - {gap:g}", curves))
    if panels:
        result.figures.append((f"Energy drift |E - E0|/|E0| against time in periods, near the top (rbody "
                               f"{periods} periods at dt w0 = {NEAR_TOP_H}; MuJoCo, pymunk {other_periods} at "
                               f"dt = {OTHER_DT:g} s)",
                               figure_panels(panels, out, "hard_near_top_energy.png",
                                             "Swinging rod near the top: energy drift", "t / period",
                                             "|E - E0| / |E0|")))
    result.findings += [
        "The exact period 4 K(k^2)/w0 uses ellipkm1(cos^2(theta0/2)), exact to round-off at every gap. "
        "scipy.special.ellipj at m = sin^2(theta0/2) (the naive route) misses theta(t) by " + "; ".join(scipy_findings)
        + " (m rounds to 1 at pi - 1e-9, where K is infinite).",
        "Float64 limit of every time-stepped run: the margin 1 - k^2 = cos^2(theta0/2) (2.5e-7, 2.5e-13, 2.5e-19) is "
        "carried at the bottom of the swing only as the speed 2 w0 sqrt(1 - (1 - k^2)), i.e. to ~eps, and each step's "
        "rounding moves it by ~eps at random; the period's sensitivity to it is 1 / (2 (1 - k^2) K). At pi - 1e-9 no "
        "run in (theta, omega) can tell the swing from a whirl; at pi - 1e-6 the round-off walk reaches the margin "
        "within ~10^3-10^4 periods. rbody.stability.resolution_problem states this limit.",
        "Symplectic methods keep the energy error bounded (a modified energy is conserved), so they keep the swing "
        "and its period near the top where the margin allows; rk4 loses energy steadily (its |R(i h w)| < 1), which "
        "near the top shortens the period by far more than the energy error itself suggests.",
    ]
    return result


# ----- 3. free rotation near the intermediate axis ------------------------------------------------

ROTATION_BODY = (1.0, 2.0, 3.0)      # principal moments [kg m^2]
ROTATION_OMEGA = (0.05, 10.0, 0.05)  # near the intermediate axis [rad/s]
ROTATION_METHODS = ("splitting", "yoshida6", "gauss6", "rk4", "euler")
ROTATION_DT = 1e-3
MUJOCO_INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
EULER_SCAN = (2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 5e-2)
EULER_SCAN_QUICK = (1e-3, 5e-3, 2e-2)


def _rotation_measures(scene, trajectory) -> tuple[float, float, float, int]:
    """Max relative drift of the energy and of |L|, the flip period's relative error, the flip count."""
    energy = trajectory["energy"]
    momentum = np.linalg.norm(trajectory["L_world"], axis=-1)
    drift_e = float(np.max(np.abs(energy / energy[0] - 1)))
    drift_l = float(np.max(np.abs(momentum / momentum[0] - 1)))
    w = trajectory["omega_body"]
    # w2 crosses 0 downwards once per period; its rate there is w2' = (I3 - I1) w3 w1 / I2
    moments = np.array(ROTATION_BODY)
    rate = (moments[2] - moments[0]) * w[:, 2] * w[:, 0] / moments[1]
    measured, flips = mean_period(trajectory.t, -w[:, 1], -rate)
    error = abs(measured - scene.period) / scene.period if np.isfinite(measured) else float("nan")
    return drift_e, drift_l, error, flips


def case_intermediate_axis(quick: bool, out: Path) -> CaseResult:
    from validation.hard.figures import figure_panels

    t_end = 100.0 if quick else 1000.0
    body = rbody.Inertia(1.0, np.zeros(3), np.diag(ROTATION_BODY))
    scene = free_rotation(body, omega0=ROTATION_OMEGA, t_end=t_end)
    flips = t_end / scene.period
    result = CaseResult(
        3, "Free rotation near the intermediate axis (the tennis racket)",
        f"moments {ROTATION_BODY} kg m^2, omega0 = {ROTATION_OMEGA} rad/s, {t_end:g} s ({flips:.0f} flips of period "
        f"{scene.period:.4g} s): each method keeps |L| and the energy (splitting and yoshida6 keep |L| to round-off) "
        "and flips with the exact elliptic period, or rbody refuses; MuJoCo's integrators are measured, and the step "
        "at which MuJoCo's Euler diverges.")
    energy_curves, momentum_curves = {}, {}
    for method in ROTATION_METHODS:
        trajectory, error, seconds = run_backend(scene, "rbody", ROTATION_DT, method=method, save_every=10)
        if error is not None:
            outcome = error_outcome(error)
            verdict, reason = rbody_verdict(scene, method, ROTATION_DT, None, outcome)
            result.rows.append(HardRow("energy, |L|, flips", "rbody", f"{method} dt={ROTATION_DT:g}", outcome, None,
                                       "energy drift", seconds, verdict,
                                       "; ".join(x for x in (short(error), reason) if x)))
            continue
        drift_e, drift_l, period_error, count = _rotation_measures(scene, trajectory)
        wrong = "" if max(drift_e, drift_l) < 1e-2 else f"invariants drifted by {max(drift_e, drift_l):.3g}"
        if method in ("splitting", "yoshida6") and drift_l > 1e-12:
            wrong = f"|L| drifted by {drift_l:.3g}; the exact rotations keep it to round-off"
        verdict, reason = rbody_verdict(scene, method, ROTATION_DT, None, "error", wrong)
        note = f"|L| drift {drift_l:.3g}; flip period rel. error {period_error:.3g} over {count} flips"
        result.rows.append(HardRow("energy, |L|, flips", "rbody", f"{method} dt={ROTATION_DT:g}", "error", drift_e,
                                   "energy drift", seconds, verdict, "; ".join(x for x in (note, reason) if x)))
        result.rows.append(HardRow("energy, |L|, flips", "rbody", f"{method} dt={ROTATION_DT:g}", "error",
                                   period_error, "flip period rel. error", 0.0, verdict))
        energy_curves[method] = envelope(trajectory.t, trajectory["energy"] / trajectory["energy"][0] - 1)
        momentum = np.linalg.norm(trajectory["L_world"], axis=-1)
        momentum_curves[method] = envelope(trajectory.t, momentum / momentum[0] - 1)
    for integrator in MUJOCO_INTEGRATORS:
        trajectory, error, seconds = run_backend(scene, "mujoco", ROTATION_DT, integrator=integrator, save_every=10)
        if error is not None:
            result.rows.append(HardRow("energy, |L|, flips", "mujoco", f"{integrator} dt={ROTATION_DT:g}",
                                       error_outcome(error), None, "energy drift", seconds, "", short(error)))
            continue
        drift_e, drift_l, period_error, count = _rotation_measures(scene, trajectory)
        result.rows.append(HardRow("energy, |L|, flips", "mujoco", f"{integrator} dt={ROTATION_DT:g}", "error", drift_e,
                                   "energy drift", seconds, "",
                                   f"|L| drift {drift_l:.3g}; flip period rel. error {period_error:.3g} over "
                                   f"{count} flips"))
        result.rows.append(HardRow("energy, |L|, flips", "mujoco", f"{integrator} dt={ROTATION_DT:g}", "error",
                                   period_error, "flip period rel. error", 0.0))
        energy_curves[integrator] = envelope(trajectory.t, trajectory["energy"] / trajectory["energy"][0] - 1)
        momentum = np.linalg.norm(trajectory["L_world"], axis=-1)
        momentum_curves[integrator] = envelope(trajectory.t, momentum / momentum[0] - 1)
    result.rows.append(HardRow("energy, |L|, flips", "pymunk", "-", "refused", None, "-", 0.0, "",
                               "pymunk is 2-D: a body turning about three axes cannot be expressed"))
    trajectory, error, seconds = run_backend(scene, "bullet", ROTATION_DT, save_every=10)
    if error is not None:
        result.rows.append(HardRow("energy, |L|, flips", "bullet", f"dt={ROTATION_DT:g}", error_outcome(error), None,
                                   "energy drift", seconds, "", short(error)))
    else:
        drift_e, drift_l, period_error, count = _rotation_measures(scene, trajectory)
        result.rows.append(HardRow("energy, |L|, flips", "bullet", f"semi-implicit Euler dt={ROTATION_DT:g}", "error",
                                   drift_e, "energy drift", seconds, "",
                                   f"|L| drift {drift_l:.3g}; flip period rel. error {period_error:.3g} over "
                                   f"{count} flips"))
        result.rows.append(HardRow("energy, |L|, flips", "bullet", f"semi-implicit Euler dt={ROTATION_DT:g}", "error",
                                   period_error, "flip period rel. error", 0.0))
        energy_curves["Bullet"] = envelope(trajectory.t, trajectory["energy"] / trajectory["energy"][0] - 1)
        momentum = np.linalg.norm(trajectory["L_world"], axis=-1)
        momentum_curves["Bullet"] = envelope(trajectory.t, momentum / momentum[0] - 1)
    result.rows.append(HardRow("energy, |L|, flips", "pinocchio", f"rk4 dt={ROTATION_DT:g}", "not run", None, "-",
                               0.0, "", f"{round(t_end / ROTATION_DT):d} steps of a Python loop over pin's aba "
                               "(~270 us a step here: over the case's budget); its rk4 is rbody's rk4 on this body "
                               "(the main command's free_rotation: 7.9e-13 rad/s from the closed form)"))

    # Where MuJoCo's Euler diverges: the time at which the energy has doubled, or MuJoCo reports an unstable state.
    scan_end = 100.0 if quick else 1000.0
    scan = free_rotation(body, omega0=ROTATION_OMEGA, t_end=scan_end)
    divergence = {}
    for dt in EULER_SCAN_QUICK if quick else EULER_SCAN:
        trajectory, error, seconds = run_backend(scan, "mujoco", dt, integrator="Euler",
                                                 save_every=max(1, round(0.01 / dt)))
        if error is not None:
            found = re.search(r"near t=([-+0-9.eE]+) s", str(error))
            outcome, value, note = error_outcome(error), float(found.group(1)) if found else None, short(error)
        else:
            growth = np.abs(trajectory["energy"] / trajectory["energy"][0] - 1)
            doubled = np.flatnonzero(growth > 1.0)
            outcome = "blew up" if doubled.size else "error"
            value = float(trajectory.t[doubled[0]]) if doubled.size else float(np.max(growth))
            note = "the energy doubled" if doubled.size else ""
        if outcome == "blew up" and value is not None:
            divergence[dt] = value
        result.rows.append(HardRow(f"Euler step scan, {scan_end:g} s", "mujoco", f"Euler dt={dt:g}", outcome, value,
                                   "time to divergence [s]" if outcome == "blew up" else "energy drift", seconds, "",
                                   note))
    result.figures.append((f"Free rotation near the intermediate axis over {t_end:g} s: drift of the energy (left) "
                           "and |L| (right), rbody methods and MuJoCo integrators at dt = 1e-3 s",
                           figure_panels([("energy |E/E0 - 1|", energy_curves), ("|L|/|L0| - 1", momentum_curves)],
                                         out, "hard_intermediate_axis.png", "Free rotation near the intermediate axis",
                                         "t [s]", "relative drift")))
    rk4_limit = stability.stability_limit(scene, "rk4")
    result.findings += [
        f"The exact flip period 4 K(m)/|lambda| = {scene.period:.6g} s (m from the complementary parameter); the "
        f"fastest linear rate of the motion is {float(stability.fastest_rate(scene)[0]):.4g} rad/s, so rk4's "
        f"stability limit is {rk4_limit:.3g} s and euler's growth limit over the run "
        f"{stability.stability_limit(scene, 'euler'):.3g} s.",
        "MuJoCo's Euler diverges here (the energy doubles, then MuJoCo reports an unstable state) after "
        + (", ".join(f"{t:.3g} s at dt = {dt:g}" for dt, t in sorted(divergence.items())) or "no scanned step")
        + f" (rows 'Euler step scan', {scan_end:g} s runs); dt x that time is "
        + (f"{min(dt * t for dt, t in divergence.items()):.2g}..{max(dt * t for dt, t in divergence.items()):.2g} s^2"
           if divergence else "-")
        + " (a constant would be the explicit Euler growth (1 + (dt lambda)^2)^(1/2) per step of Euler's equations "
        "for omega, the same map as rbody's euler, which gives the same energy drift); implicit and implicitfast "
        "lose the energy instead, RK4 keeps it.",
    ]
    return result


__all__ = ["case_near_top", "case_intermediate_axis", "run_backend", "rbody_verdict",
           "mean_period", "envelope", "energy_bounded", "mp_theta"]
