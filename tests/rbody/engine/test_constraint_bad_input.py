"""Bad input to the constraint layer: errors before any work for a description that cannot be compiled, and a
SimulationError naming the time, the constraints and the residual for a set that cannot hold, a force that does not
exist, or a solver out of budget. A redundant loop, and a Zeno cascade of impacts, run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbody import Body, Equality, Joint, Layout, Scene, SimulationError, simulate
from rbody.engine.constraints import stepping

from .test_constraint_closed_forms import four_bar, friction_oscillator
from .test_constraint_scheme import limited_pendulum, rod


def two_rods(*equalities, ranges=(None, None), qpos0=(0.0, 0.0), qvel0=(0.0, 0.0)):
    bodies = (Body("a", rod()), Body("b", rod(), pos=(0.5, 0, 0)))
    joints = tuple(Joint(name, "hinge", body, axis=(0, 1, 0), range=r, qpos0=q, qvel0=v)
                   for name, body, r, q, v in zip(("qa", "qb"), ("a", "b"), ranges, qpos0, qvel0))
    return Scene.from_layout(Layout(bodies=bodies, joints=joints, equalities=equalities), t_end=1.0)


@pytest.mark.parametrize("equality, match", [
    (Equality("e", "connect", body1="ghost"), "equality 'e': body1='ghost' is not a body"),
    (Equality("e", "joint", joint1="qa", joint2="nope"), "equality 'e': joint2='nope' is not a joint"),
    (Equality("e", "weld", body1="a", body2="nobody"), "body2='nobody'"),
])
def test_an_equality_naming_what_the_tree_lacks_is_refused_before_any_work(equality, match):
    with pytest.raises(ValueError, match=match):
        two_rods(equality)


def test_a_tendon_equality_naming_no_tendon_is_refused_naming_it():
    with pytest.raises(ValueError, match="equality 't': tendon1='cable' is not a tendon of the layout"):
        two_rods(Equality("t", "tendon", tendon1="cable"))


def test_two_equalities_that_contradict_each_other_are_refused_at_the_start_with_the_residual():
    """q_a = q_b and q_a = q_b + 0.5 cannot both hold: the projection at t = 0 stalls, and the error names them."""
    scene = two_rods(Equality("same", "joint", joint1="qa", joint2="qb"),
                     Equality("offset", "joint", joint1="qa", joint2="qb", polycoef=(0.5, 1, 0, 0, 0)))
    with pytest.raises(SimulationError, match=r"at t=0 s constraints 'same', 'offset'; no configuration satisfies "
                                              r"these constraints together .* residual 0\.25"):
        simulate(scene, dt=1e-2)


def test_an_equality_that_no_stop_allows_is_refused():
    """q_a = q_b with q_a <= 0.1 and q_b >= 0.2: no configuration satisfies the three."""
    scene = two_rods(Equality("same", "joint", joint1="qa", joint2="qb"), ranges=((-1.0, 0.1), (0.2, 1.0)),
                     qpos0=(0.0, 0.5))
    with pytest.raises(SimulationError, match=r"at t=0 s constraints .*'same'.*no configuration satisfies.*residual"):
        simulate(scene, dt=1e-2)


def test_a_motion_no_force_can_keep_is_refused_with_the_time_and_the_residual():
    """q_a = q_b and q_a = q_b + q_b^2 both hold at q = 0 and admit v_a = v_b there, but not the accelerations
    (the second needs a_a = a_b + v_b^2): moving through q = 0 is impossible and no force makes it so."""
    scene = two_rods(Equality("same", "joint", joint1="qa", joint2="qb"),
                     Equality("curve", "joint", joint1="qa", joint2="qb", polycoef=(0, 1, 1, 0, 0)),
                     qvel0=(1.0, 1.0))
    with pytest.raises(SimulationError, match=r"at t=0 s constraints 'same', 'curve'; .*no consistent force"
                                              r".*residual"):
        simulate(scene, dt=1e-2)


def test_a_time_step_whose_problem_the_solver_cannot_finish_within_its_budget_is_refused(monkeypatch):
    monkeypatch.setattr(stepping, "EXACT_ROWS", 0)  # Gauss-Seidel only,
    monkeypatch.setattr(stepping, "PGS_SWEEPS", 1)  # and one sweep
    with pytest.raises(SimulationError, match=r"method 'moreau' with dt=0\.001: at t=\d.* s, constraints 'loop'.*"
                                              r"residual above 1e-10 .*residual \d"):
        simulate(four_bar(0.6, t_end=0.1), dt=1e-3, method="moreau")


def test_redundant_loops_run():
    """A four-bar closed by a connect (one redundant row) and by a connect plus a joint coupling that says what the
    loop already says (crank = rocker): both run, the loop closed to round-off."""
    extra = (Equality("loop", "connect", body1="coupler", body2="rocker", anchor=(0.8, 0, 0)),
             Equality("same", "joint", joint1="c", joint2="a"))
    for scene in (four_bar(0.6, t_end=1.0), four_bar(0.6, t_end=1.0, equalities=extra)):
        for method in ("rk4", "moreau"):
            run = simulate(scene, dt=1e-3, method=method)
            assert np.abs(run["constraint_error"]).max() < 1e-12


def test_a_cascade_of_impacts_on_a_loaded_stop_ends_in_rest():
    """The rod falls onto a stop that gravity presses it against (lower stop 0.3 rad), e = 1/2: the bounces shrink
    geometrically and would be infinitely many in a finite time (Zeno); below ZENO_RATIO of the first speed an
    impact is plastic, and the rod rests on the stop, the energy accounted for."""
    run = simulate(limited_pendulum(1.0, 0.3, 2.0, restitution=0.5, t_end=3.0), dt=1e-3)
    speeds_ratio = 0.5 ** np.arange(run.meta["impacts"])
    assert 10 < run.meta["impacts"] < 40 and speeds_ratio[-1] < 1e-5
    assert run["active_limits"][-1, 0] and run["qpos"][-1, 0] == 0.3
    assert np.ptp(run["energy"] + run["dissipated"]) < 1e-11


def test_bad_arguments_to_a_constrained_run_are_value_errors():
    with pytest.raises(ValueError):
        simulate(friction_oscillator(1.0), dt=-1.0)
    with pytest.raises(ValueError, match="method='rk5'"):
        simulate(friction_oscillator(1.0), dt=1e-3, method="rk5")
    assert math.isfinite(simulate(friction_oscillator(1.0, t_end=0.1), dt=1e-2)["qpos"][-1, 0])
