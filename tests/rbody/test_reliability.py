"""Issue 12: no silent wrong answer, work estimated before it starts, clear messages.

Each test here failed before its fix (the value or the message it checks was wrong or missing)."""

from __future__ import annotations

import numpy as np
import pytest

import rbody
from rbody import Inertia, simulate
from rbody.errors import SimulationError
from rbody.motion import quat_to_matrix
from rbody.scenes import compound_pendulum, pi_collisions, rocket, swinging_rod


# ----- mass properties: scale before squaring ---------------------------------------------------------

@pytest.mark.parametrize("axis", [[1e300, 1e300, 0.0], [1e-200, 1e-200, 0.0], [3e-310, 3e-310, 0.0]])
def test_rod_axis_of_any_size_gives_the_same_tensor(axis):
    want = Inertia.rod(1.0, 1.0, axis=[1.0, 1.0, 0.0]).tensor
    got = Inertia.rod(1.0, 1.0, axis=axis).tensor
    np.testing.assert_allclose(got, want, rtol=0, atol=4e-16)
    assert got[0, 1] == pytest.approx(-1 / 24)  # products of inertia carry the minus sign


def test_point_masses_far_from_the_origin_keep_their_moments():
    # Two unit masses 2 m apart at x = 1e16: I_yy = I_zz = 2 (m d^2/4 each), whatever the offset.
    inertia = Inertia.point_masses([1.0, 1.0], [[1e16, 0, 0], [1e16 + 2, 0, 0]])
    np.testing.assert_allclose(np.diag(inertia.tensor), [0.0, 2.0, 2.0], rtol=1e-15, atol=0)
    assert abs(inertia.com[0] - (1e16 + 1)) <= 2.0  # the nearest float to 1e16 + 1


def test_point_masses_whose_moments_overflow_are_refused():
    with pytest.raises(ValueError, match="overflow"):
        Inertia.point_masses([1.0, 1.0], [[-1e200, 0, 0], [1e200, 0, 0]])


def test_tensor_beyond_float64_sums_says_why():
    with pytest.raises(ValueError, match=r"largest entry 1e\+308.*overflow"):
        Inertia(1.0, np.zeros(3), 1e308 * np.eye(3))


# ----- the pendulum's limits ----------------------------------------------------------------------------

T = np.linspace(0.0, 3.0, 7)


@pytest.mark.parametrize("theta0", [0.0, 2 * np.pi, -4 * np.pi])
def test_pendulum_at_rest_at_the_bottom_stays_there(theta0):
    out = swinging_rod(1.0, theta0=theta0, t_end=3.0).exact(T)
    np.testing.assert_array_equal(out["theta"], np.full(T.size, theta0))
    np.testing.assert_array_equal(out["omega"], np.zeros(T.size))


def test_tiny_swing_is_continuous_with_the_elliptic_solution():
    # theta0 = 1e-9: k^2 = 2.5e-19, elliptic; 1e-11: harmonic. Both scale with the amplitude.
    a = swinging_rod(1.0, theta0=1e-9, t_end=3.0).exact(T)["theta"]
    b = swinging_rod(1.0, theta0=1e-11, t_end=3.0).exact(T)["theta"] * 100
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-24)
    assert np.all(np.isfinite(swinging_rod(1.0, theta0=1e-200, t_end=3.0).exact(T)["theta"]))


def test_no_gravity_is_a_uniform_turn_matching_the_run():
    scene = swinging_rod(1.0, theta0=0.5, omega0=1.5, gravity=0.0, t_end=2.0)
    exact = scene.exact(T)
    np.testing.assert_allclose(exact["theta"], 0.5 + 1.5 * T, rtol=1e-15)
    np.testing.assert_array_equal(exact["omega"], np.full(T.size, 1.5))
    run = simulate(scene, dt=0.01, method="rk4")
    np.testing.assert_allclose(run["theta"], scene.exact(run.t)["theta"], rtol=1e-13)
    assert scene.period == pytest.approx(2 * np.pi / 1.5)
    body = Inertia.solid_sphere(1.0, 0.1)
    out = compound_pendulum(body, pivot=[0, 0, 0.5], theta0=0.3, gravity=0.0, t_end=1.0).exact(T)
    np.testing.assert_array_equal(out["theta"], np.full(T.size, 0.3))


# ----- messages -----------------------------------------------------------------------------------------

def test_one_zero_quaternion_among_many_is_named_briefly():
    q = np.tile([0.5, 0.5, 0.5, 0.5], (200_000, 1))
    q[123_456] = 0.0
    with pytest.raises(ValueError) as error:
        quat_to_matrix(q)
    message = str(error.value)
    assert len(message) < 300
    assert "(123456,)" in message and "1 of 200000" in message


def test_non_finite_values_in_a_large_array_are_named_briefly():
    from rbody._checks import finite_array

    values = np.zeros((100_000, 3))
    values[777, 2] = np.nan
    with pytest.raises(ValueError) as error:
        finite_array(values, "positions")
    assert len(str(error.value)) < 300 and "(777, 2)" in str(error.value)
