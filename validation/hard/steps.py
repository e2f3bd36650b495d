"""Hard cases 6 and 9: too large a step, and time reversal."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

import rbody
from rbody import stability
from rbody.motion import quat_multiply, quat_to_matrix
from rbody.scenes import free_rotation, pendulum_chain, swinging_rod
from validation.hard.rows import CaseResult, HardRow, attempt, error_outcome, short
from validation.hard.kit import run_backend

# ----- 6. too large a step -----------------------------------------------------------------------------

STEP_FACTORS_QUICK = (0.5, 2.0, 10.0)
STEP_FACTORS = (0.5, 0.9, 1.1, 2.0, 5.0, 10.0)
CORRECT = 1e-2  # a returned run is correct when its energy and main observable are within this (relative)


def _step_scenes() -> list[tuple[str, object, tuple[str, ...]]]:
    body = rbody.Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]))
    return [("swinging rod, theta0 = 1", swinging_rod(1.0, theta0=1.0, t_end=20.0),
             ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6")),
            ("free rotation near the intermediate axis", free_rotation(body, omega0=(0.05, 10.0, 0.05), t_end=20.0),
             ("euler", "rk4", "gauss6", "splitting", "yoshida6"))]


def _run_errors(scene, trajectory) -> tuple[bool, float, float]:
    """(every observable finite, energy error relative to max |E*|, main observable error relative to its
    scale) against the exact solution."""
    finite = all(np.all(np.isfinite(trajectory[name])) for name in trajectory.observables)
    if not finite:
        return False, math.inf, math.inf
    exact = scene.exact(trajectory.t)
    energy = float(np.max(np.abs(trajectory["energy"] - exact["energy"])) / np.max(np.abs(exact["energy"])))
    main = scene.main_observable
    scale = float(np.max(np.abs(exact[main])))
    error = np.abs(np.asarray(trajectory[main]) - exact[main])
    return True, energy, float(np.max(error) / scale)


def case_large_steps(quick: bool, out: Path) -> CaseResult:
    from validation.hard.figures import figure_step_outcomes

    factors = STEP_FACTORS_QUICK if quick else STEP_FACTORS
    result = CaseResult(
        6, "Too large a step",
        "every method on the swinging rod and on free rotation at dt = factor x its stability limit estimated by "
        f"rbody.stability (factors {', '.join(f'{f:g}' for f in factors)}): beyond the limit rbody either stays "
        f"correct (energy and main observable within {CORRECT:g}) or raises SimulationError naming the limit; it never "
        "returns non-finite values, and no other error type escapes.")
    grid: dict[str, list[tuple[float, str]]] = {}
    for label, scene, methods in _step_scenes():
        rate = float(np.max(stability.fastest_rate(scene)))
        for method in methods:
            limit = stability.stability_limit(scene, method)
            key = f"{'rod' if 'rod' in label else 'rotation'}: {method}"
            # the multiples of the limit, and a probe at dt = t_end / 10 (where euler's state overflows)
            steps = [(factor * limit, f"{factor:g} x limit") for factor in factors]
            if method == "euler":
                steps.append((scene.t_end / 10, "probe: t_end/10"))
            for dt, how in steps:
                factor = dt / limit
                trajectory, error, seconds = attempt(rbody.simulate, scene, dt=dt, method=method)
                setting = f"{method} dt={dt:.3g} ({how})"
                if error is not None:
                    clear = isinstance(error, rbody.SimulationError)
                    named = "limit" in str(error)
                    outcome = error_outcome(error) if clear else "blew up"
                    if not clear:
                        verdict, why = "FAIL", f"{type(error).__name__} is not a SimulationError"
                    elif factor > 1 and not named:
                        verdict, why = "FAIL", "the error does not name the estimated limit"
                    else:
                        verdict, why = "pass", "" if factor > 1 else "stopped below the estimate (a clear error)"
                    grid.setdefault(key, []).append((factor, outcome))
                    result.rows.append(HardRow(label, "rbody", setting, outcome, None, "-", seconds, verdict,
                                               "; ".join(x for x in (why, short(error)) if x)))
                    continue
                finite, energy, main = _run_errors(scene, trajectory)
                correct = finite and energy <= CORRECT and main <= CORRECT
                if not finite:
                    verdict, why = "FAIL", "returned non-finite values without an error"
                elif factor > 1 and not correct:
                    verdict, why = "FAIL", "returned a wrong run beyond the limit without an error (silently wrong)"
                else:
                    verdict, why = "pass", ""
                kind = "correct" if correct else "wrong" if factor > 1 else "inaccurate"
                grid.setdefault(key, []).append((factor, kind))
                result.rows.append(HardRow(label, "rbody", setting, "error", max(energy, main),
                                           f"max(energy, {scene.main_observable}) rel. error", seconds, verdict,
                                           "; ".join(x for x in (f"energy {energy:.3g}, {scene.main_observable} "
                                                                 f"{main:.3g}", why) if x)))
        # The other simulators at the same multiples of 2/w (verlet's limit), for comparison.
        for backend, settings, name in (("mujoco", {"integrator": "RK4"}, "RK4"),
                                        ("mujoco", {"integrator": "Euler"}, "Euler"), ("pymunk", {}, "pymunk"),
                                        ("pinocchio", {"method": "rk4"}, "Pinocchio rk4"), ("bullet", {}, "Bullet")):
            for factor in (2.0, 10.0):
                dt = factor * 2.0 / rate
                trajectory, error, seconds = run_backend(scene, backend, dt, **settings)
                setting = f"{name} dt={dt:.3g} ({factor:g} x 2/w)"
                if error is not None:
                    result.rows.append(HardRow(label, backend, setting, error_outcome(error), None, "-", seconds, "",
                                               short(error)))
                    continue
                finite, energy, main = _run_errors(scene, trajectory)
                result.rows.append(HardRow(label, backend, setting, "error", max(energy, main),
                                           f"max(energy, {scene.main_observable}) rel. error", seconds, "",
                                           f"energy {energy:.3g}, {scene.main_observable} {main:.3g}"
                                           + ("" if finite else "; non-finite values returned")))
    result.figures.append(("Outcome of each rbody method against dt / its estimated stability limit "
                           "(correct: energy and main observable within 1e-2; inaccurate: below the limit, allowed; "
                           "wrong: beyond the limit and returned without an error)",
                           figure_step_outcomes(grid, out, "hard_large_steps.png", "Too large a step")))
    intervals = ", ".join(f"{m} {stability.stability_interval(m):.4g}" for m in
                          ("symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6", "splitting"))
    result.findings += [
        f"rbody.stability's limits: dt < beta / w with beta = {intervals} (gauss6: the contraction of its fixed-point "
        "stage solver, it is A-stable), w the fastest rate of the linearised motion (pendulum w0; free rotation the "
        "largest of |omega|/2 and the eigenvalues of Euler's equations along the exact motion); euler has no "
        f"interval and is limited to {stability.EULER_GROWTH:g}x amplitude growth over the run.",
    ]
    failed = [row for row in result.rows if row.verdict == "FAIL"]
    if failed:
        result.findings.append(f"{len(failed)} rbody runs beyond the limit came back without the required error "
                               "(rows FAIL): simulate does not yet check rbody.stability.check_step before stepping.")
    return result


# ----- 9. time reversal --------------------------------------------------------------------------------

def _rod_round_trip(backend: str, method: str | None, dt: float, steps: int, settings: dict) -> tuple[float, float]:
    """(return error, seconds): forward `steps` steps from (1, 0.5), velocity reversed, the same steps back;
    max(|theta - 1|, |omega + 0.5| / w0) [rad]."""
    t_end = steps * dt
    forward_scene = swinging_rod(1.0, theta0=1.0, omega0=0.5, t_end=t_end)
    w0 = math.sqrt(1.5 * forward_scene.gravity)
    options = dict(settings, **({"method": method} if method else {}))
    forward, error, s1 = run_backend(forward_scene, backend, dt, **options)
    if error is not None:
        raise error
    back_scene = swinging_rod(1.0, theta0=float(forward["theta"][-1]), omega0=-float(forward["omega"][-1]), t_end=t_end)
    back, error, s2 = run_backend(back_scene, backend, dt, **options)
    if error is not None:
        raise error
    return max(abs(back["theta"][-1] - 1.0), abs(back["omega"][-1] + 0.5) / w0), s1 + s2


def _chain_round_trip(links: int, method: str, dt: float, steps: int) -> tuple[float, float]:
    t_end = steps * dt
    theta0, omega0 = np.linspace(0.3, 0.6, links), np.zeros(links)
    forward_scene = pendulum_chain(links, theta0=theta0, omega0=omega0, t_end=t_end)
    forward, error, s1 = run_backend(forward_scene, "rbody", dt, method=method)
    if error is not None:
        raise error
    back_scene = pendulum_chain(links, theta0=forward["theta"][-1], omega0=-forward["omega"][-1], t_end=t_end)
    back, error, s2 = run_backend(back_scene, "rbody", dt, method=method)
    if error is not None:
        raise error
    return float(max(np.max(np.abs(back["theta"][-1] - theta0)), np.max(np.abs(back["omega"][-1] + omega0)))), s1 + s2


def _rotation_round_trip(method: str, dt: float, steps: int) -> tuple[float, float]:
    """Forward from the identity, then the body (its inertia turned to the final pose) spun with -omega_world
    for the same steps: the orientation's angle from the identity [rad] and |omega_world + omega0| / |omega0|."""
    t_end = steps * dt
    body = rbody.Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]))
    omega0 = np.array([0.3, 0.2, 3.0])
    forward, error, s1 = run_backend(free_rotation(body, omega0=omega0, t_end=t_end), "rbody", dt, method=method)
    if error is not None:
        raise error
    q_end = forward["quaternion"][-1] / np.linalg.norm(forward["quaternion"][-1])
    rotation = quat_to_matrix(q_end)
    omega_world = rotation @ forward["omega_body"][-1]
    back, error, s2 = run_backend(free_rotation(body.rotated(rotation), omega0=-omega_world, t_end=t_end), "rbody",
                                  dt, method=method)
    if error is not None:
        raise error
    q_back = back["quaternion"][-1] / np.linalg.norm(back["quaternion"][-1])
    total = quat_multiply(q_back, q_end)
    angle = 2 * math.atan2(float(np.linalg.norm(total[1:])), abs(float(total[0])))
    spin = quat_to_matrix(q_back) @ back["omega_body"][-1]
    return max(angle, float(np.linalg.norm(spin + omega0) / np.linalg.norm(omega0))), s1 + s2


ROUND_OFF = 1e-12  # a symmetric method's return error must be round-off: below this [rad]


def case_time_reversal(quick: bool, out: Path) -> CaseResult:
    result = CaseResult(
        9, "Time reversal",
        "forward N steps, velocities reversed, N steps back: the symmetric methods (verlet, yoshida6, gauss6, "
        f"splitting) return to the start to round-off (below {ROUND_OFF:g}); rk4 and symplectic_euler, which are not "
        "symmetric, miss by their truncation error (shown for contrast, as are MuJoCo, pymunk and the peers).")
    steps = 500 if quick else 2000
    cases = []
    for method in ("verlet", "yoshida6", "gauss6", "rk4", "symplectic_euler"):
        cases.append((f"swinging rod, {steps} steps", "rbody", method,
                      lambda method=method: _rod_round_trip("rbody", method, 1e-2, steps, {})))
    for backend, settings, name in (("mujoco", {"integrator": "RK4"}, "RK4"), ("pymunk", {}, "pymunk"),
                                    ("pinocchio", {"method": "rk4"}, "rk4"), ("bullet", {}, "semi-implicit Euler")):
        cases.append((f"swinging rod, {steps} steps", backend, name,
                      lambda backend=backend, settings=settings: _rod_round_trip(backend, None, 1e-2, steps, settings)))
    links = 2 if quick else 8
    chain_steps = 200 if quick else 1000
    for method in ("gauss6", "rk4"):
        cases.append((f"chain of {links}, {chain_steps} steps", "rbody", method,
                      lambda method=method: _chain_round_trip(links, method, 1e-3, chain_steps)))
    for method in ("splitting", "yoshida6", "gauss6", "rk4"):
        cases.append((f"free rotation, {steps} steps", "rbody", method,
                      lambda method=method: _rotation_round_trip(method, 1e-2, steps)))
    for variant, backend, method, function in cases:
        dt = 1e-3 if variant.startswith("chain") else 1e-2
        value, error, seconds = attempt(function)
        symmetric = method in ("verlet", "yoshida6", "gauss6", "splitting")
        if error is not None:
            result.rows.append(HardRow(variant, backend, f"{method} dt={dt:g}", error_outcome(error), None,
                                       "return error", seconds, "FAIL" if backend == "rbody" else "", short(error)))
            continue
        error_value, seconds = value
        if backend == "rbody" and symmetric:
            ok = error_value <= ROUND_OFF
            result.rows.append(HardRow(variant, backend, f"{method} dt={dt:g}", "exact" if ok else "error", error_value,
                                       "return error", seconds, "pass" if ok else "FAIL",
                                       "" if ok else "a symmetric method should return to round-off"))
        else:
            result.rows.append(HardRow(variant, backend, f"{method} dt={dt:g}", "error", error_value, "return error",
                                       seconds, "", "not symmetric: its truncation error shows"))
    result.findings.append(
        "The round trip of a symmetric method is its own inverse up to the rounding of each step; in the chain "
        "(chaotic at these angles) and near the intermediate axis the rounding is amplified by the motion's "
        "instability, so the return error grows with the run length even for an exact symmetric method.")
    return result


__all__ = ["case_large_steps", "case_time_reversal"]
