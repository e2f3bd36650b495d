"""Systems of particles (the chapter's section 5.1): P = M R', angular momentum about two points,
the kinetic-energy split (5.3), the reduced mass, and a rigid body's energy (5.15)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rbody import Inertia, Particles, point_velocity, reduced_mass, two_body

coord = st.floats(-10.0, 10.0)
vec3 = st.tuples(coord, coord, coord)


@st.composite
def systems(draw, min_size=1, max_size=6):
    n = draw(st.integers(min_size, max_size))
    masses = draw(st.lists(st.floats(1e-2, 1e2), min_size=n, max_size=n))
    positions = draw(st.lists(vec3, min_size=n, max_size=n))
    velocities = draw(st.lists(vec3, min_size=n, max_size=n))
    return Particles(np.array(masses), np.array(positions, float), np.array(velocities, float))


def scale(system):
    """M (1 + max |x|)(1 + max |v|): the size of P, L and T for tolerances."""
    return system.total_mass * (1 + np.abs(system.positions).max()) * (1 + np.abs(system.velocities).max())


def test_two_particles_by_hand():
    s = Particles([1.0, 3.0], [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]], [[0.0, 2.0, 0.0], [0.0, -2.0, 0.0]])
    assert s.total_mass == 4.0
    assert np.array_equal(s.centre_of_mass, [3.0, 0.0, 0.0])
    assert np.array_equal(s.centre_of_mass_velocity, [0.0, -1.0, 0.0])
    assert np.array_equal(s.momentum, [0.0, -4.0, 0.0])
    # L about the origin: only particle 2 contributes, 3 (4 x) x (-2 y) = -24 z
    assert np.array_equal(s.angular_momentum(), [0.0, 0.0, -24.0])
    assert s.kinetic_energy == pytest.approx(0.5 * 1 * 4 + 0.5 * 3 * 4, rel=1e-15)
    translational, internal = s.kinetic_energy_split()
    assert translational == pytest.approx(0.5 * 4 * 1, rel=1e-15)
    assert internal == pytest.approx(8.0 - 2.0, rel=1e-15)


@settings(max_examples=80, deadline=None)
@given(systems())
def test_momentum_is_total_mass_times_centre_velocity(system):
    """The chapter: P = sum m_i x_i' = M R'."""
    assert np.allclose(system.momentum, system.total_mass * system.centre_of_mass_velocity,
                       rtol=0, atol=1e-13 * scale(system))
    # in the centre-of-mass frame the momentum and sum m_i y_i vanish
    rel = system.relative_to_centre()
    assert np.allclose(rel.momentum, 0.0, atol=1e-13 * scale(system))
    assert np.allclose(rel.masses @ rel.positions, 0.0, atol=1e-13 * scale(system))


@settings(max_examples=80, deadline=None)
@given(systems(), vec3)
def test_angular_momentum_splits_about_the_centre_of_mass(system, point):
    """The chapter: L = M R x R' + sum m_i y_i x y_i' (orbital plus spin), and about a point Q
    L_Q = L_O - Q x P."""
    R, V, M = system.centre_of_mass, system.centre_of_mass_velocity, system.total_mass
    spin = system.relative_to_centre().angular_momentum()
    assert np.allclose(system.angular_momentum(), M * np.cross(R, V) + spin, rtol=0, atol=1e-12 * scale(system))
    Q = np.array(point)
    assert np.allclose(system.angular_momentum(Q), system.angular_momentum() - np.cross(Q, system.momentum),
                       rtol=0, atol=1e-12 * scale(system) * (1 + np.abs(Q).max()))
    # about the centre of mass, the moving and the fixed frame agree: sum m (x - R) x x' = spin
    assert np.allclose(system.angular_momentum(R), spin, rtol=0, atol=1e-12 * scale(system))


@settings(max_examples=80, deadline=None)
@given(systems())
def test_kinetic_energy_split(system):
    """The chapter's (5.3): T = 1/2 M R'^2 + 1/2 sum m_i y_i'^2."""
    translational, internal = system.kinetic_energy_split()
    V = system.centre_of_mass_velocity
    assert translational == pytest.approx(0.5 * system.total_mass * V @ V, rel=1e-14, abs=1e-300)
    assert translational + internal == pytest.approx(system.kinetic_energy, rel=1e-12,
                                                     abs=1e-13 * scale(system) * (1 + np.abs(system.velocities).max()))
    assert internal >= 0.0


@settings(max_examples=60, deadline=None)
@given(systems(min_size=2), vec3, vec3)
def test_rigid_body_energy_and_angular_momentum(system, V, omega):
    """The chapter (5.14) and (5.15): particles moving rigidly, y_i' = w x y_i, have
    T = 1/2 M R'^2 + 1/2 w^T I w and spin angular momentum I w, I from Inertia.point_masses."""
    body = Inertia.point_masses(system.masses, system.positions)
    V, omega = np.array(V), np.array(omega)
    velocities = point_velocity(system.positions, body.com, V, omega)
    rigid = Particles(system.masses, system.positions, velocities)
    size = body.mass * (1 + np.abs(system.positions).max()) ** 2 * (1 + np.linalg.norm(V) + np.linalg.norm(omega)) ** 2
    assert np.allclose(rigid.centre_of_mass_velocity, V, atol=1e-12 * (1 + np.linalg.norm(V) + np.linalg.norm(omega)) * (1 + np.abs(system.positions).max()))
    T = 0.5 * body.mass * V @ V + body.kinetic_energy(omega)
    assert rigid.kinetic_energy == pytest.approx(T, rel=1e-10, abs=1e-12 * size)
    assert np.allclose(rigid.relative_to_centre().angular_momentum(), body.angular_momentum(omega),
                       rtol=0, atol=1e-12 * size)


def test_reduced_mass():
    assert reduced_mass(2.0, 3.0) == pytest.approx(1.2, rel=1e-15)
    assert reduced_mass(5.0, 5.0) == 2.5
    assert reduced_mass(1.0, 1e12) == pytest.approx(1.0, rel=1e-11)  # a light body on a heavy one


@settings(max_examples=80, deadline=None)
@given(st.floats(1e-2, 1e2), vec3, vec3, st.floats(1e-2, 1e2), vec3, vec3)
def test_two_body_coordinates(m1, x1, v1, m2, x2, v2):
    """R, r = x1 - x2 and mu = m1 m2 / M: x1 = R + (m2/M) r, x2 = R - (m1/M) r,
    T = 1/2 M R'^2 + 1/2 mu r'^2 and L = M R x R' + mu r x r'."""
    x1, v1, x2, v2 = map(np.array, (x1, v1, x2, v2))
    c = two_body(m1, x1, v1, m2, x2, v2)
    M = m1 + m2
    tol = 1e-12 * (1 + np.abs(np.r_[x1, x2]).max()) * (1 + np.abs(np.r_[v1, v2]).max())
    assert c["mu"] == pytest.approx(m1 * m2 / M, rel=1e-15)
    assert np.allclose(c["R"] + m2 / M * c["r"], x1, atol=tol)
    assert np.allclose(c["R"] - m1 / M * c["r"], x2, atol=tol)
    assert np.allclose(c["R_dot"] + m2 / M * c["r_dot"], v1, atol=tol)
    pair = Particles([m1, m2], [x1, x2], [v1, v2])
    T = 0.5 * M * c["R_dot"] @ c["R_dot"] + 0.5 * c["mu"] * c["r_dot"] @ c["r_dot"]
    assert T == pytest.approx(pair.kinetic_energy, rel=1e-12, abs=M * tol * (1 + np.abs(np.r_[v1, v2]).max()))
    L = M * np.cross(c["R"], c["R_dot"]) + c["mu"] * np.cross(c["r"], c["r_dot"])
    assert np.allclose(L, pair.angular_momentum(), atol=M * tol * (1 + np.abs(np.r_[x1, x2]).max()))


def test_arrays_are_read_only():
    s = Particles([1.0], [[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]])
    with pytest.raises(ValueError):
        s.velocities[0, 0] = 2.0


BAD = [
    (lambda: Particles([], np.zeros((0, 3)), np.zeros((0, 3))), r"need at least one particle"),
    (lambda: Particles([1.0, 0.0], np.zeros((2, 3)), np.zeros((2, 3))), r"every mass > 0"),
    (lambda: Particles([1.0, -2.0], np.zeros((2, 3)), np.zeros((2, 3))), r"every mass > 0"),
    (lambda: Particles([np.nan], np.zeros((1, 3)), np.zeros((1, 3))), r"masses=\[nan\].*finite"),
    (lambda: Particles([1.0, 1.0], np.zeros((3, 3)), np.zeros((2, 3))), r"positions has shape \(3, 3\): expected \(2, 3\)"),
    (lambda: Particles([1.0], np.zeros((1, 3)), np.zeros((1, 2))), r"velocities has shape \(1, 2\)"),
    (lambda: Particles([1.0], [[0.0, np.inf, 0.0]], np.zeros((1, 3))), r"positions=.*finite"),
    (lambda: Particles([1.0], np.zeros((1, 3)), np.zeros((1, 3))).angular_momentum((0, 0)), r"about has shape"),
    (lambda: reduced_mass(0.0, 1.0), r"m1=0\.0: must be > 0"),
    (lambda: reduced_mass(1.0, -1.0), r"m2=-1\.0: must be > 0"),
    (lambda: reduced_mass(1.0, np.nan), r"m2=nan.*finite"),
    (lambda: two_body(1.0, (0, 0), (0, 0, 0), 1.0, (0, 0, 0), (0, 0, 0)), r"x1 has shape \(2,\)"),
    (lambda: two_body(1.0, (0, 0, 0), (0, 0, 0), 0.0, (0, 0, 0), (0, 0, 0)), r"m2=0\.0: must be > 0"),
]


@pytest.mark.parametrize("call, message", BAD, ids=[m for _, m in BAD])
def test_bad_input_raises_value_error_naming_the_problem(call, message):
    with pytest.raises(ValueError, match=message):
        call()
