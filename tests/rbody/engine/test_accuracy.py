"""Issue 23: accuracy, not only stability. A method stepping the fastest mode poorly is warned about with the
figure (rbody.errors.AccuracyWarning), and an error estimate by step doubling is given on request.

The oscillator: a body on a hinge with a stiff spring and no gravity, q'' = -(k / I) q, w = sqrt(k / I), exact
q(t) = q0 cos(w t); after one period the exact state is the start."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from rbody import AccuracyWarning, Body, Inertia, Joint, Layout, Scene, simulate
from rbody.engine.accuracy import ACCURACY_TOLERANCE, accuracy_threshold, period_error
from rbody.engine.stability import fastest_rate, stability_interval
from rbody.scenes import pi_collisions, swinging_rod

STIFFNESS, MOMENT = 400.0, 0.01   # w = sqrt(k / I) = 200 rad/s: a stiff joint spring
W = math.sqrt(STIFFNESS / MOMENT)
Q0 = 0.1


def spring(t_end: float) -> Scene:
    body = Inertia(1.0, np.zeros(3), np.diag([MOMENT, MOMENT, MOMENT]))
    layout = Layout(bodies=(Body("wheel", body),),
                    joints=(Joint("spring", "hinge", "wheel", axis=(0.0, 1.0, 0.0), stiffness=STIFFNESS, qpos0=Q0),))
    return Scene.from_layout(layout, t_end=t_end, gravity=0.0)


def test_the_scene_rate_is_the_spring_frequency():
    assert float(fastest_rate(spring(0.1), "rk4")[0]) == pytest.approx(W, rel=1e-6)


METHODS = ["euler", "symplectic_euler", "verlet", "rk4", "yoshida6"]


@pytest.mark.parametrize("method", METHODS)
def test_each_threshold_separates_runs_within_and_beyond_one_percent_per_period(method):
    """The compiled method on the oscillator, one period in N whole steps, from (q0, 0) and from (0, w q0): the two
    final states are the columns of the method's period map P; ||P - I|| equals the period error derived from the
    step matrix (rbody.engine.accuracy), and is below 1 % just below the threshold, above it just above."""
    threshold = accuracy_threshold(method)
    errors = {}
    for side, factor in (("below", 0.85), ("above", 1.2)):
        steps = math.ceil(2 * math.pi / (factor * threshold)) if side == "below" else \
            math.floor(2 * math.pi / (factor * threshold))
        period = 2 * math.pi / W
        dt = period / steps
        body = Inertia(1.0, np.zeros(3), np.diag([MOMENT, MOMENT, MOMENT]))
        layout = Layout(bodies=(Body("wheel", body),),
                        joints=(Joint("spring", "hinge", "wheel", axis=(0.0, 1.0, 0.0), stiffness=STIFFNESS),))
        scene = Scene.from_layout(layout, t_end=period, gravity=0.0, qpos0=[[Q0], [0.0]], qvel0=[[0.0], [W * Q0]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AccuracyWarning)
            run = simulate(scene, dt=dt, method=method)
        assert run.t.size == steps + 1 and run.t[-1] == pytest.approx(period, rel=1e-12)
        final = np.stack([run["qpos"][-1, :, 0], run["qvel"][-1, :, 0] / W]) / Q0  # columns: the two starts
        errors[side] = float(np.linalg.norm(final - np.eye(2), 2))
        assert errors[side] == pytest.approx(period_error(method, dt * W), rel=1e-6)
    assert errors["below"] < ACCURACY_TOLERANCE < errors["above"], errors


def test_thresholds_lie_inside_the_stability_intervals_and_grow_with_the_order():
    values = [accuracy_threshold(m) for m in METHODS]
    assert values == sorted(values)
    for method in METHODS[1:]:
        assert accuracy_threshold(method) < stability_interval(method)
    assert accuracy_threshold("gauss6") == math.inf and accuracy_threshold("reference") == math.inf
    assert accuracy_threshold("splitting") == accuracy_threshold("verlet")


@pytest.mark.parametrize("fraction", [0.99, 0.5, 0.25])
def test_rk4_inside_its_stability_limit_but_beyond_its_accuracy_warns_with_the_figure(fraction):
    """The issue's runs: rk4 at 0.99, 0.5 and 0.25 of its stability limit on the stiff spring lost 100 %, 100 %
    and 79 % of the energy in 0.01 s without a word."""
    dt = fraction * stability_interval("rk4") / W
    with pytest.warns(AccuracyWarning, match=rf"dt \* w = {dt * W:.3g} .* beyond rk4's accuracy threshold 0.662"):
        run = simulate(spring(0.5), dt=dt, method="rk4")
    energy = run["energy"]
    assert energy[-1] < 0.9 * energy[0]  # the warning is about a real loss: 10 % and more in 0.5 s (16 periods)


def test_a_run_within_the_threshold_says_nothing():
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        simulate(spring(0.05), dt=0.5 * accuracy_threshold("rk4") / W, method="rk4")
        simulate(swinging_rod(1.0, theta0=1.0, t_end=1.0), dt=1e-3)


def test_the_pendulum_released_near_the_top_at_most_of_its_limit_warns():
    """A pendulum released at 3.1 rad with verlet at 0.9 of its stability limit lost 47 % of its energy."""
    rod = swinging_rod(1.0, theta0=3.1, t_end=2.0)
    dt = 0.9 * 2.0 / float(fastest_rate(rod, "verlet")[0])
    with pytest.warns(AccuracyWarning, match="verlet's accuracy threshold"):
        simulate(rod, dt=dt, method="verlet")


@pytest.mark.parametrize("method, x", [("rk4", 0.3), ("verlet", 0.05)])
def test_the_error_estimate_by_step_doubling_is_within_a_factor_two_of_the_true_error(method, x):
    scene = spring(0.2)
    run = simulate(scene, dt=x / W, method=method, error_estimate=True)
    true = np.max(np.abs(run["qpos"][:, 0] - Q0 * np.cos(W * run.t)))
    estimate = run.meta["error_estimate"]["qpos"]
    assert 0.5 * true <= estimate <= 2.0 * true, (estimate, true)
    assert "step doubling" in run.meta["error_estimate_how"]
    assert set(run.meta["error_estimate"]) >= {"qpos", "qvel", "energy"}
    plain = simulate(scene, dt=x / W, method=method)
    assert np.array_equal(plain["qpos"], run["qpos"]) and "error_estimate" not in plain.meta


def test_no_error_estimate_where_there_is_no_step():
    run = simulate(pi_collisions(1), dt=0.1, error_estimate=True)
    assert "error_estimate" not in run.meta and "found exactly" in run.meta["error_estimate_how"]
    with pytest.raises(ValueError, match="error_estimate='yes'"):
        simulate(spring(0.01), dt=1e-4, error_estimate="yes")
