"""Rigid motion r' = R' + w x (r - R) (the chapter's 5.14), the rolling hoop, and quaternions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.linalg import expm

from rbody import Inertia, RigidMotion, point_velocity
from rbody.motion import (quat_conjugate, quat_exp, quat_from_axis_angle, quat_from_matrix,
                          quat_integrate_body, quat_multiply, quat_normalize, quat_rotate, quat_to_matrix)

coord = st.floats(-10.0, 10.0)
vec3 = st.tuples(coord, coord, coord).map(np.array)
quat_st = (st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: sum(x * x for x in q) > 0.01)
           .map(lambda q: quat_normalize(np.array(q))))


def skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


# ----- point velocities ---------------------------------------------------------------------------------

def test_point_velocity_broadcasts():
    rng = np.random.default_rng(1)
    r = rng.normal(size=(5, 4, 3))
    R = rng.normal(size=3)
    V = rng.normal(size=(4, 3))
    omega = rng.normal(size=(5, 1, 3))
    v = point_velocity(r, R, V, omega)
    assert v.shape == (5, 4, 3)
    for i in range(5):
        for j in range(4):
            assert np.allclose(v[i, j], V[j] + np.cross(omega[i, 0], r[i, j] - R), rtol=1e-15, atol=1e-15)


def test_point_velocity_is_perpendicular_to_omega_for_pure_rotation():
    v = point_velocity([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]], np.zeros(3), np.zeros(3), [0.0, 0.0, 3.0])
    assert np.allclose(v, [[0.0, 3.0, 0.0], [-6.0, 0.0, 0.0]], atol=0)


@settings(max_examples=60, deadline=None)
@given(vec3, vec3, vec3, vec3, st.lists(vec3, min_size=1, max_size=5))
def test_about_keeps_omega_and_gives_the_same_velocities(R, V, omega, Q, points):
    """The chapter: Q' = R' + w x (Q - R), and then r' = Q' + w x (r - Q): the same w about any point."""
    motion = RigidMotion(R, V, omega)
    moved = motion.about(Q)
    assert np.array_equal(moved.omega, motion.omega)
    assert np.array_equal(moved.R, Q)
    assert np.allclose(moved.V, V + np.cross(omega, Q - R), rtol=1e-14, atol=1e-12)
    r = np.array(points)
    scale = 1 + np.linalg.norm(V) + np.linalg.norm(omega) * (1 + np.abs(r).max() + np.abs(Q).max() + np.abs(R).max())
    assert np.allclose(moved.velocity_at(r), motion.velocity_at(r), rtol=0, atol=1e-13 * scale)
    # rigidity: the velocities of two body points have equal components along the line joining them
    if len(r) > 1:
        d = r[1] - r[0]
        v = motion.velocity_at(r)
        assert abs(d @ (v[1] - v[0])) <= 1e-12 * scale * (1 + np.linalg.norm(d))


@settings(max_examples=60, deadline=None)
@given(vec3, vec3, vec3.filter(lambda w: np.linalg.norm(w) > 1e-2))
def test_instantaneous_axis_points_move_along_the_axis(R, V, omega):
    motion = RigidMotion(R, V, omega)
    point, direction = motion.instantaneous_axis()
    assert np.linalg.norm(direction) == pytest.approx(1.0, rel=1e-15)
    scale = np.linalg.norm(V) + np.linalg.norm(omega) * (1 + np.linalg.norm(R) + np.linalg.norm(point))
    for s in (0.0, 1.0, -3.0):
        v = motion.velocity_at(point + s * direction)
        assert np.linalg.norm(np.cross(v, direction)) <= 1e-12 * scale
    assert abs((point - R) @ direction) <= 1e-12 * (1 + np.linalg.norm(point - R))  # nearest R


# ----- the chapter's rolling hoop ----------------------------------------------------------------------

A, RATE = 0.35, 2.2                     # hoop radius a [m], angular speed theta' [rad/s]


def rolling_hoop(x_centre=1.3):
    """A hoop in the x-z plane rolling towards +x on the ground z = 0: centre (x, 0, a) at speed
    v = a theta' (the chapter's no-slip condition 5.16); rolling towards +x turns it about +y."""
    return RigidMotion((x_centre, 0.0, A), (A * RATE, 0.0, 0.0), (0.0, RATE, 0.0))


def test_rolling_hoop_contact_point_is_at_rest_and_top_moves_at_twice_the_centre():
    hoop = rolling_hoop()
    assert np.allclose(hoop.velocity_at((1.3, 0.0, 0.0)), 0.0, atol=1e-15)
    assert np.allclose(hoop.velocity_at((1.3, 0.0, 2 * A)), (2 * A * RATE, 0.0, 0.0), rtol=1e-15)


@pytest.mark.parametrize("angle", np.linspace(0.0, 2 * np.pi, 13))
def test_rolling_hoop_rim_speed_both_angle_conventions(angle):
    """The chapter: with theta measured at the centre from the TOP of the hoop, the rim point P has
    speed 2 a theta' cos(theta/2) (AP = 2 a cos(theta/2) from the contact point A); with psi measured
    from the CONTACT point, P = C + a (sin psi, 0, -cos psi) and the speed is 2 a theta' sin(psi/2).
    The velocity is at right angles to AP, not tangent to the hoop."""
    hoop = rolling_hoop()
    centre, contact = hoop.R, hoop.R - (0.0, 0.0, A)
    from_top = centre + A * np.array([np.sin(angle), 0.0, np.cos(angle)])
    from_contact = centre + A * np.array([np.sin(angle), 0.0, -np.cos(angle)])
    v_top, v_contact = hoop.velocity_at(from_top), hoop.velocity_at(from_contact)
    assert np.linalg.norm(v_top) == pytest.approx(2 * A * RATE * abs(np.cos(angle / 2)), abs=1e-14)
    assert np.linalg.norm(v_contact) == pytest.approx(2 * A * RATE * abs(np.sin(angle / 2)), abs=1e-14)
    assert np.linalg.norm(from_top - contact) == pytest.approx(2 * A * abs(np.cos(angle / 2)), abs=1e-15)
    for p, v in ((from_top, v_top), (from_contact, v_contact)):
        assert abs((p - contact) @ v) <= 1e-14


def test_rolling_hoop_instantaneous_axis_passes_through_the_contact_point():
    hoop = rolling_hoop()
    point, direction = hoop.instantaneous_axis()
    assert np.allclose(point, (1.3, 0.0, 0.0), atol=1e-15)
    assert np.allclose(direction, (0.0, 1.0, 0.0))
    # and the same from any reference point of the body
    point2, _ = hoop.about((1.0, 0.0, 0.5)).instantaneous_axis()
    assert np.allclose(point2, (1.3, 0.0, 0.0), atol=1e-14)


def test_rolling_kinetic_energy_about_the_contact_point():
    """The chapter (5.15): T = 1/2 M v^2 + 1/2 I w^2; rolling, T = 1/2 I_A w^2 with I_A about the
    contact line (the hoop: M a^2 + M a^2 = 2 M a^2)."""
    mass = 1.7
    hoop = Inertia.hoop(mass, A, "y")
    motion = rolling_hoop()
    T = 0.5 * mass * motion.V @ motion.V + hoop.kinetic_energy(motion.omega)
    assert T == pytest.approx(0.5 * hoop.moment("y", through=(0, 0, -A)) * RATE**2, rel=1e-14)
    assert T == pytest.approx(mass * A**2 * RATE**2, rel=1e-14)


def test_pure_translation_has_no_axis():
    with pytest.raises(ValueError, match="pure translation has no rotation axis"):
        RigidMotion((0, 0, 0), (1, 0, 0), (0, 0, 0)).instantaneous_axis()


# ----- quaternions ---------------------------------------------------------------------------------------

def test_quaternion_of_a_quarter_turn_about_z():
    q = quat_from_axis_angle((0.0, 0.0, 2.0), np.pi / 2)
    assert np.allclose(q, (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)), rtol=1e-15)
    assert np.allclose(quat_rotate(q, (1.0, 0.0, 0.0)), (0.0, 1.0, 0.0), atol=1e-15)  # right-handed
    assert np.allclose(quat_to_matrix(q), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)


@settings(max_examples=100, deadline=None)
@given(quat_st)
def test_matrix_quaternion_round_trip(q):
    R = quat_to_matrix(q)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    back = quat_from_matrix(R)
    assert back[0] >= 0
    assert min(np.linalg.norm(back - q), np.linalg.norm(back + q)) < 1e-14
    assert np.allclose(quat_to_matrix(back), R, atol=1e-14)


@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 1)])
@pytest.mark.parametrize("angle", [0.0, 0.3, np.pi / 2, np.pi - 1e-9, np.pi])
def test_matrix_to_quaternion_on_every_branch(axis, angle):
    """Half-turns make the trace -1 and force Shepperd's x, y and z branches."""
    q = quat_from_axis_angle(axis, angle)
    back = quat_from_matrix(quat_to_matrix(q))
    assert min(np.linalg.norm(back - q), np.linalg.norm(back + q)) < 1e-12


@settings(max_examples=100, deadline=None)
@given(quat_st, quat_st, vec3)
def test_multiply_composes_rotations(p, q, v):
    """R(p q) = R(p) R(q): apply q, then p; the conjugate is the inverse."""
    assert np.allclose(quat_to_matrix(quat_multiply(p, q)), quat_to_matrix(p) @ quat_to_matrix(q), atol=1e-14)
    assert np.allclose(quat_rotate(quat_multiply(p, q), v), quat_rotate(p, quat_rotate(q, v)),
                       atol=1e-13 * (1 + np.linalg.norm(v)))
    assert np.allclose(quat_multiply(q, quat_conjugate(q)), (1.0, 0.0, 0.0, 0.0), atol=1e-15)
    # v' = q v q* as a pure quaternion
    pure = np.r_[0.0, v]
    rotated = quat_multiply(quat_multiply(q, pure), quat_conjugate(q))
    assert np.allclose(rotated[1:], quat_rotate(q, v), atol=1e-13 * (1 + np.linalg.norm(v)))


@settings(max_examples=60, deadline=None)
@given(quat_st, vec3, st.floats(0.0, 3.0))
def test_integrate_body_is_the_exact_rotation(q, omega_body, t):
    """Constant body rate: R(t) = R(0) exp(t [w_body]x) (matrix exponential), for any step size."""
    exact = quat_to_matrix(q) @ expm(t * skew(omega_body))
    one_step = quat_integrate_body(q, omega_body, t)
    assert np.allclose(quat_to_matrix(one_step), exact, atol=1e-12 * (1 + t * np.linalg.norm(omega_body)))
    assert np.linalg.norm(one_step) == pytest.approx(1.0, abs=1e-15)
    steps = quat_normalize(q)
    for _ in range(4):
        steps = quat_integrate_body(steps, omega_body, t / 4)
    assert np.allclose(quat_to_matrix(steps), exact, atol=1e-12 * (1 + t * np.linalg.norm(omega_body)))


def test_quat_exp_is_exact_near_zero_and_batched():
    assert np.array_equal(quat_exp(np.zeros(3)), [1.0, 0.0, 0.0, 0.0])
    tiny = np.array([1e-12, -2e-12, 3e-12])
    assert np.allclose(quat_exp(tiny), np.r_[1.0, tiny / 2], rtol=1e-15, atol=0)
    phi = np.array([[0.0, 0.0, np.pi], [2 * np.pi, 0.0, 0.0]])
    assert np.allclose(quat_exp(phi), [[0.0, 0.0, 0.0, 1.0], [-1.0, 0.0, 0.0, 0.0]], atol=1e-15)
    qs = quat_integrate_body(np.tile([1.0, 0, 0, 0], (2, 1)), [[0, 0, 1.0], [0, 1.0, 0]], np.array([np.pi, np.pi / 2]))
    assert np.allclose(qs, [[0, 0, 0, 1.0], [math.sqrt(0.5), 0, math.sqrt(0.5), 0]], atol=1e-15)


# ----- bad input ----------------------------------------------------------------------------------------

BAD = [
    (lambda: point_velocity([1.0, 0.0], np.zeros(3), np.zeros(3), np.zeros(3)), r"r has shape \(2,\): expected \(\.\.\., 3\)"),
    (lambda: point_velocity(np.zeros(3), np.zeros(3), [np.nan, 0, 0], np.zeros(3)), r"V=.*finite"),
    (lambda: point_velocity(np.zeros((4, 3)), np.zeros(3), np.zeros((5, 3)), np.zeros(3)), r"do not broadcast"),
    (lambda: RigidMotion((0, 0), (0, 0, 0), (0, 0, 0)), r"R has shape \(2,\): expected \(3,\)"),
    (lambda: RigidMotion((0, 0, 0), (0, 0, 0), (np.inf, 0, 0)), r"omega=.*finite"),
    (lambda: RigidMotion((0, 0, 0), (0, 0, 0), (0, 0, 1)).about((0, 0)), r"Q has shape"),
    (lambda: quat_normalize(np.zeros(4)), r"are zero .*non-zero quaternion"),
    (lambda: quat_normalize((1.0, 0.0, 0.0)), r"quaternion has shape \(3,\): expected \(\.\.\., 4\)"),
    (lambda: quat_to_matrix((np.nan, 0, 0, 1)), r"finite"),
    (lambda: quat_multiply((1, 0, 0, 0), (1, 0, 0)), r"q has shape \(3,\)"),
    (lambda: quat_from_axis_angle((0, 0, 0), 1.0), r"axis=\[0, 0, 0\]: a rotation axis must be non-zero"),
    (lambda: quat_from_axis_angle((0, 0, 1), np.nan), r"angle=nan"),
    (lambda: quat_from_matrix(np.diag([1.0, 1.0, -1.0])), r"expected a proper rotation"),
    (lambda: quat_from_matrix(np.eye(4)), r"matrix has shape \(4, 4\)"),
    (lambda: quat_integrate_body((1, 0, 0, 0), (0, 0, 1), np.inf), r"dt=inf"),
    (lambda: quat_exp((1.0, 2.0)), r"rotation_vector has shape"),
]


@pytest.mark.parametrize("call, message", BAD, ids=[m for _, m in BAD])
def test_bad_input_raises_value_error_naming_the_problem(call, message):
    with pytest.raises(ValueError, match=message):
        call()
