"""cone_solve's patience: a warm-started solve whose rounds stop halving the residual above the tolerance gives up
after `patience` rounds (the step then starts again from rest, solve_cones), and rounds that halve it are never cut
short. The problem that stalls: two equality rows that contradict each other (w_1 = lam_1 + lam_2 + 1 and
w_2 = lam_1 + lam_2 - 1 cannot both vanish: the least residual is 1), beside a contact that pushes and slides."""

import sys
from pathlib import Path

import numpy as np
import pytest

from rbody.engine.constraints.cone import NORMAL, ROW, TANGENT
from rbody.engine.constraints.stepping import CONE_ROUND, cone_solve

sys.path.insert(0, str(Path(__file__).parent))
from test_cone_drift import MU, ROLES, TOLERANCE, crawling_problem  # noqa: E402


def contradicting_rows():
    W = np.eye(5)
    W[:2, :2] = 1.0  # the two rows of one direction
    W[2, 2] = 2.0
    b = np.array([1.0, -1.0, -1.0, 0.3, 0.1])
    lo = np.array([-np.inf, -np.inf, 0.0, -np.inf, -np.inf])
    role = np.array([ROW, ROW, NORMAL, TANGENT, TANGENT + 1])
    mu = np.array([0.0, 0.0, 0.0, 0.5, 0.5])
    return W, b, lo, np.full(5, np.inf), role, mu


@pytest.mark.parametrize("patience", [3, 8])
def test_rounds_that_stall_above_the_tolerance_end_after_the_patience(patience):
    W, b, lo, hi, role, mu = contradicting_rows()
    lam = np.zeros(5)
    residual, sweeps = cone_solve(W, b, lo, hi, role, mu, lam, 1e-10, 2000)
    assert sweeps == 2000 and residual == pytest.approx(1.0)  # the whole budget, never below the least residual
    guarded = np.zeros(5)
    stopped, spent = cone_solve(W, b, lo, hi, role, mu, guarded, 1e-10, 2000, patience)
    assert spent == (patience + 1) * CONE_ROUND  # the first round sets the mark; `patience` more do not halve it
    assert stopped == residual
    assert guarded[2] == pytest.approx(0.5, rel=1e-12)  # the contact's impulse is the problem's all the same


@pytest.mark.parametrize("seed", range(4))
def test_rounds_that_halve_the_residual_are_not_cut_short(seed):
    W, b, lo, hi = crawling_problem(seed)
    lam, guarded = np.zeros(8), np.zeros(8)
    residual, sweeps = cone_solve(W, b, lo, hi, ROLES, MU, lam, TOLERANCE, 2000)
    assert residual <= TOLERANCE
    assert cone_solve(W, b, lo, hi, ROLES, MU, guarded, TOLERANCE, 2000, 1) == (residual, sweeps)
    assert np.array_equal(guarded, lam)
