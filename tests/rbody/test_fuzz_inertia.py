"""Fuzzing Inertia and from_mesh (issue 12): any input either gives finite mass properties that obey the
chapter's invariants, or a ValueError; never another exception, a NaN or a silently wrong tensor."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rbody import Inertia

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
EXTREME = st.sampled_from([0.0, -0.0, 1e-320, 1e-300, 1e-150, 1e-8, 1.0, 1e8, 1e150, 1e300, 1.7e308, -1.0, -1e300,
                           float("nan"), float("inf"), -float("inf")])
ANY_FLOAT = st.one_of(EXTREME, st.floats(allow_nan=True, allow_infinity=True))


def _valid(inertia: Inertia) -> None:
    assert np.isfinite(inertia.mass) and inertia.mass > 0
    assert np.all(np.isfinite(inertia.com)) and np.all(np.isfinite(inertia.tensor))
    moments = np.linalg.eigvalsh(inertia.tensor)
    scale = max(float(np.max(np.abs(inertia.tensor))), np.finfo(float).tiny)
    assert moments[0] >= -1e-12 * scale and moments[0] + moments[1] >= moments[2] - 1e-12 * scale


def _either_valid_or_value_error(make):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            inertia = make()
        except ValueError as error:
            assert str(error) and len(str(error)) < 1000
            return None
    _valid(inertia)
    return inertia


@FAST
@given(mass=ANY_FLOAT, length=ANY_FLOAT, axis=st.lists(ANY_FLOAT, min_size=3, max_size=3))
def test_rod_of_any_input(mass, length, axis):
    rod = _either_valid_or_value_error(lambda: Inertia.rod(mass, length, axis=axis))
    if rod is not None:  # the moment about the axis is 0, across it M L^2 / 12, whatever the axis's size
        n = np.array(axis) / np.max(np.abs(axis))
        n /= np.linalg.norm(n)
        assert abs(n @ rod.tensor @ n) <= 1e-12 * mass * length**2


@FAST
@given(masses=st.lists(st.one_of(EXTREME, st.floats(1e-3, 1e3)), min_size=1, max_size=4),
       offset=st.one_of(EXTREME, st.floats(-1e17, 1e17)), data=st.data())
def test_point_masses_anywhere(masses, offset, data):
    n = len(masses)
    local = np.array(data.draw(st.lists(st.lists(st.floats(-1, 1), min_size=3, max_size=3), min_size=n, max_size=n)))
    made = _either_valid_or_value_error(lambda: Inertia.point_masses(masses, local + offset))
    if made is not None and np.isfinite(offset) and abs(offset) < 1e15 and all(m > 1e-3 for m in masses):
        near = Inertia.point_masses(masses, local)  # the same system at the origin: the same tensor
        # the positions themselves are rounded to ~|offset| eps: the moments move by ~ m |x| |offset| eps
        np.testing.assert_allclose(made.tensor, near.tensor, rtol=1e-9,
                                   atol=16 * np.sum(masses) * (1 + abs(offset)) * 2.2e-16 + 1e-12 * np.sum(masses))


@FAST
@given(mass=ANY_FLOAT, entries=st.lists(ANY_FLOAT, min_size=6, max_size=6))
def test_constructor_with_any_tensor(mass, entries):
    a, b, c, d, e, f = entries
    tensor = np.array([[a, d, e], [d, b, f], [e, f, c]])
    _either_valid_or_value_error(lambda: Inertia(mass, np.zeros(3), tensor))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scale=st.sampled_from([1e-100, 1e-8, 1.0, 1e8, 1e100]), shift=st.sampled_from([0.0, 1e6, -1e12]),
       extents=st.lists(st.floats(0.1, 10.0), min_size=3, max_size=3), twist=st.floats(-np.pi, np.pi))
def test_box_mesh_anywhere_gives_the_box(scale, shift, extents, twist):
    import trimesh

    box = trimesh.creation.box(extents=extents)
    c, s = np.cos(twist), np.sin(twist)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    mesh = trimesh.Trimesh(box.vertices @ turn.T * scale + shift * scale, box.faces, process=False)
    got = _either_valid_or_value_error(lambda: Inertia.from_mesh(mesh, mass=1.0))
    if got is None:
        pytest.fail("a plain box was refused")
    want = Inertia.box(1.0, np.array(extents) * scale).rotated(turn).tensor
    # The vertices themselves are rounded to ~eps |shift|: relative to the box, eps |shift| / extent.
    rounding = 2.2e-16 * abs(shift) / min(extents)
    np.testing.assert_allclose(got.tensor, want, rtol=0, atol=np.max(np.abs(want)) * (1e-12 + 16 * rounding))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(moved=st.integers(0, 7), to=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
def test_box_with_a_moved_corner_is_refused_or_has_the_volume_of_its_surface(moved, to):
    """A corner moved anywhere: the surface is simple (then the mass is that of the volume it bounds, which
    trimesh computes the same way) or it folds through itself and is refused; never a crash."""
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    vertices = box.vertices.copy()
    vertices[moved] = to
    mesh = trimesh.Trimesh(vertices, box.faces, process=False)
    got = _either_valid_or_value_error(lambda: Inertia.from_mesh(mesh, density=1.0))
    if got is not None:
        assert got.mass == pytest.approx(mesh.volume, rel=1e-9)
