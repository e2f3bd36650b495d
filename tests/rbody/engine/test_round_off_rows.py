"""Rows whose Jacobian is round-off (rbody.engine.constraints.dynamics.definite_solve, stepping._drop_null_equalities).

A planar loop closed by a connect has one component of the connect across the loop's plane: a zero row, computed as
round-off (1e-17) when the loop's plane is turned in the world by a rotation such as 90 degrees about z. Solving that
row's round-off residual through its round-off Jacobian is a step of order one in a random direction: the position
projection of a loop resting on its stops jumped to the other stops in one step, and Gauss-Seidel pushed the other
rows of a gripper's step by impulses of order one. The loop below (an underactuated finger's five-bar: a driver and
its coupler, a spring-loaded rocker and its follower, closed at the follower's origin) rests on its driver's lower
stop and its coupler's upper stop, its rocker's spring pushing it into them; written here for the test."""

import numpy as np
import pytest

import rbody
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.cone import NORMAL, ROW, TANGENT, TANGENT2
from rbody.engine.constraints.solver import cholesky_factor
from rbody.engine.constraints.stepping import _drop_null_equalities

LOOP = """
<mujoco model="planar loop">
  <compiler angle="radian" autolimits="true"/>
  <option><flag contact="{contact}"/></option>
  <worldbody>
    <geom name="wall" type="box" pos="0.035 0 0.11" size="0.005 0.02 0.02"/>
    <body name="base" quat="1 0 0 -1">
      <body name="driver" pos="0 0.03 0.05">
        <joint name="driver" axis="1 0 0" range="0 0.9" damping="0.1" armature="0.004"/>
        <geom type="capsule" fromto="0 0 0 0 0.03 -0.004" size="0.004" mass="0.02" contype="0" conaffinity="0"/>
        <body name="coupler" pos="0 0.03 -0.005">
          <joint name="coupler" axis="1 0 0" range="-1.5 0"/>
          <geom type="capsule" fromto="0 0 0 0 0.005 0.04" size="0.003" mass="0.01" contype="0" conaffinity="0"/>
        </body>
      </body>
      <body name="rocker" pos="0 0.012 0.06">
        <joint name="rocker" axis="1 0 0" range="-0.3 0.9" stiffness="0.04" springref="2" damping="0.001"/>
        <geom type="capsule" fromto="0 0 0 0 0.05 0.035" size="0.004" mass="0.02" contype="0" conaffinity="0"/>
        <body name="follower" pos="0 0.05 0.035">
          <joint name="follower" axis="1 0 0" range="-0.9 0.9" pos="0 -0.02 0.006"/>
          <geom name="pad" type="box" size="0.005 0.005 0.02" mass="0.02"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <connect anchor="0 0 0" body1="follower" body2="coupler"/>
  </equality>
  <actuator>
    <motor name="close" joint="driver"/>
  </actuator>
</mujoco>
"""


def test_definite_solve_refuses_a_round_off_row():
    """Two rows of order 0.05 and one of round-off, not parallel to them: its pivot is its own diagonal entry (the
    old bound, 1e-10 of it, took it), far below RANK_RTOL of the largest: refused, the minimum-norm solve follows."""
    rng = np.random.default_rng(3)
    J = np.array([[0.0435, 0.0476, -0.0375, 0.0065], rng.normal(size=4) * 1e-17, [-0.038, -0.0065, 0.055, 0.018]])
    W = J @ J.T
    x = np.zeros(3)
    assert not dyn.definite_solve(W, np.array([0.0, 1e-17, 0.0]), x)
    L = np.empty((3, 3))
    assert cholesky_factor(W, L, 1e-10, 0.0)          # what the relative bound alone accepts
    assert dyn.definite_solve(W[np.ix_([0, 2], [0, 2])], np.array([1.0, 2.0]), x[:2])  # a definite pair is solved
    np.testing.assert_allclose(W[np.ix_([0, 2], [0, 2])] @ x[:2], [1.0, 2.0], rtol=1e-12)


@pytest.mark.parametrize("on_support", [False, True], ids=["dense", "supports"])
def test_drop_null_equalities_keeps_every_row_an_impulse_acts_through(on_support):
    """The step's columns: a connect's round-off row goes, the rest move up in order with their bounds, right-hand
    sides, roles, coefficients, free rates and supports; a limit's row is kept however small. On supports (a tree of
    many dofs) each column is read on its own support, which here holds its every nonzero."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(4, 6))
    A[:, 1] *= 1e-17                         # an equality's round-off row
    A[:, 4] *= 1e-9                          # a limit's small row (W's 1e-18 of the others): kept
    index = np.arange(10, 16)
    lo = np.array([-np.inf, -np.inf, 0.0, 0.0, 0.0, -np.inf])
    hi = np.full(6, np.inf)
    b = np.arange(6.0)
    role = np.array([ROW, ROW, NORMAL, TANGENT, ROW, ROW])
    mu = np.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.0])
    rates = np.arange(6.0) + 0.5
    support = np.array([0, 1, 2, 3, 0, 1, 2, 3], dtype=np.int64)  # every dof, twice: the columns' supports
    start = np.array([0, 4, 0, 4, 0, 4], dtype=np.int64)
    length = np.array([4, -1, 4, 4, -1, 4], dtype=np.int64)  # (-1: every dof, an equality's or a limit's row)
    before = A.copy()
    m = _drop_null_equalities(A, index, lo, hi, b, role, mu, 6, rates, support, start, length, on_support)
    assert m == 5
    assert list(start[:5]) == [0, 0, 4, 0, 4] and list(length[:5]) == [4, 4, 4, -1, 4]
    np.testing.assert_array_equal(A[:, :5], before[:, [0, 2, 3, 4, 5]])
    assert list(index[:5]) == [10, 12, 13, 14, 15] and list(b[:5]) == [0, 2, 3, 4, 5]
    assert list(role[:5]) == [ROW, NORMAL, TANGENT, ROW, ROW] and mu[2] == 0.5 and lo[1] == 0.0
    assert TANGENT2 not in role[:5]
    assert list(rates[:5]) == [0.5, 2.5, 3.5, 4.5, 5.5]


@pytest.mark.parametrize("dt", [1e-3, 1e-4])
def test_loop_on_its_stops_moves_with_the_event_scheme(dt):
    """The rocker's spring lifts the driver off its stop while the coupler stays on its own: the time-stepping runs
    (it jumped to the other stops at its first step), the coupler on its stop and the loop closed to round-off,
    within order h of the event-driven run (measured 4.1e-4 rad at 1 ms, 4.1e-5 at 0.1 ms)."""
    scene = rbody.from_mjcf(LOOP.format(contact="disable"))
    exact = rbody.simulate(scene, dt=1e-3, method="rk4", t_end=0.05)
    run = rbody.simulate(scene, dt=dt, method="moreau", t_end=0.05)
    q = run["qpos"]
    assert q[:, 1].max() <= 1e-12                         # the coupler at its upper stop, 0
    assert np.abs(run["constraint_error"]).max() <= 1e-12
    assert 0.01 < q[-1, 0] < 0.8                          # the driver lifted off its lower stop, short of its upper
    assert np.abs(q[-1] - exact["qpos"][-1]).max() <= 0.6 * dt


def test_loop_pressing_its_pad_on_a_wall_holds():
    """The motor closes the driver until the follower's pad meets a wall: the pad's contacts with the loop's rows in
    one step's problem (Gauss-Seidel with the connect's round-off row pushed the others by impulses of order one and
    the step failed). The pad rests on the wall without passing it, the motion stops."""
    scene = rbody.from_mjcf(LOOP.format(contact="enable"))
    run = rbody.simulate(scene, dt=1e-3, method="moreau", t_end=0.5, ctrl=np.array([0.2]))
    assert run["contacts"][-1] > 0
    assert run["contact_distance"].min() >= -1e-12
    assert np.abs(run["qvel"][-1]).max() <= 1e-9
