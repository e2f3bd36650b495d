"""The scenes of issue 7 in the main command's cases: MuJoCo and pymunk against the closed forms, and
the refusals stated."""

import numpy as np
import pytest

from validation import cases
from validation.evaluate import evaluate

pytestmark = pytest.mark.crosssim


def test_particles_are_refused_by_both_simulators_with_the_reason():
    (case,) = cases.particles_case(quick=True)
    rows, runs = evaluate(case, ("mujoco", "pymunk"))
    assert [r.verdict for r in rows] == ["refused", "refused"] and not runs
    assert "no layout" in rows[0].note and "not planar" in rows[1].note


def test_stacked_balls_small_ball_rises_to_the_closed_form_top_in_pymunk():
    (case,) = cases.stacked_balls_case(quick=True)
    rows, runs = evaluate(case, ("pymunk",))
    top = np.max(runs["pymunk"]["small_height"])
    # the exact top (with the 0.02 m gap) is about 8.08 m: pymunk within 4.4e-2 m (measured 3.5e-2 m)
    assert top == pytest.approx(case.scene.top_height, abs=0.05)
    assert {r.metric: r.verdict for r in rows} == {"max_abs_error": "ok", "energy_error": "ok"}


def test_scattering_leaves_at_a_right_angle_in_pymunk():
    (case,) = cases.scattering_case(quick=True)
    _rows, runs = evaluate(case, ("pymunk",))
    v1, v2 = runs["pymunk"]["velocity_1"][-1], runs["pymunk"]["velocity_2"][-1]
    assert abs(v1 @ v2) < 1e-12 and np.linalg.norm(v1) > 0.4 and np.linalg.norm(v2) > 0.4


@pytest.mark.parametrize("backend", ["mujoco", "pymunk"])
def test_rocket_and_avalanche_follow_the_closed_forms(backend):
    for case in cases.variable_mass_cases(quick=True):
        rows, _runs = evaluate(case, (backend,))
        assert {r.metric for r in rows} == {"max_abs_error", "final_relative_error"}
        (error,) = [r.value for r in rows if r.metric == "max_abs_error"]
        assert error < 0.02  # first order in dt: 2e-3 .. 1.4e-2 m measured in the quick runs


def test_two_body_orbit_in_mujoco_matches_kepler_to_rk4_accuracy():
    (case,) = cases.two_body_case(quick=True)
    rows, _runs = evaluate(case, ("mujoco",))
    values = {r.metric: r.value for r in rows}
    assert values["max_abs_error"] < 1e-9 and values["energy_error"] < 1e-10
