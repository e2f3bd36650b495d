"""Evaluations side by side (rbody.engine.simd lanes): each lane has the bits of the scalar computation.

The planar kernels over lanes (planar_rhs_lanes, planar_accel_lanes) against planar_rhs and planar_accel, the rk4
loop over lanes against the scalar loop, and the lane operations against numpy and the scalar sin_cos."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit

import rbody
from rbody import Body, Inertia, Joint, Layout, Multibody, Scene
from rbody.engine import integrators, simd
from rbody.engine import multibody as mb
from rbody.engine import planar as pl
from rbody.engine.memory import address
from rbody.engine.spatial import REDUCED_RANGE, sin_cos

sys.path.insert(0, str(Path(__file__).parent))
from test_planar import NORMALS, planar_tree  # noqa: E402
from trees import random_tree  # noqa: E402

L = pl.LANES


def to_lanes(rows: np.ndarray) -> np.ndarray:
    """(L, k) states -> the (k L,) structure of arrays the lane kernels read (entry j of lane l at j L + l)."""
    return np.ascontiguousarray(rows.T).reshape(-1)


def from_lanes(flat: np.ndarray, k: int) -> np.ndarray:
    return flat.reshape(k, L).T


@pytest.mark.parametrize("seed", range(6))
def test_planar_kernels_over_lanes_give_each_lane_the_scalar_bits(seed):
    rng = np.random.default_rng(seed)
    model = pl.planar_model(Multibody(planar_tree(rng, int(rng.integers(1, 7)), NORMALS["y"])))
    n, row = model.nv, np.array(model.row)
    y = np.hstack([rng.uniform(-3, 3, (L, n)), rng.uniform(-5, 5, (L, n))])
    y[1, :n] += 1e3 * rng.normal(size=n)  # far turned: the polynomial sin and cos after a long reduction
    y[2, :n] = 2.5e5  # beyond the polynomial's range: np.sin and np.cos, lane by lane
    theirs = np.empty_like(y)
    for lane in range(L):
        pl.planar_rhs(y[lane], row, theirs[lane])
    out = np.full(2 * n * L, np.nan)
    pl.planar_rhs_lanes(to_lanes(y), row, out)
    np.testing.assert_array_equal(from_lanes(out, 2 * n), theirs)
    accel = np.empty((L, n))
    for lane in range(L):
        pl.planar_accel(y[lane, :n], row, accel[lane])
    out = np.full(n * L, np.nan)
    pl.planar_accel_lanes(to_lanes(y[:, :n]), row, out)
    np.testing.assert_array_equal(from_lanes(out, n), accel)


def test_a_lane_whose_pivot_vanishes_gets_nan_where_the_scalar_kernel_does():
    """A hinge through a point mass, with no armature: the scalar kernel gives NaN; over lanes, every lane."""
    point = Inertia(1.0, np.zeros(3), np.zeros((3, 3)))
    held = Layout(bodies=(Body("p", point),), joints=(Joint("h", "hinge", "p", axis=(0.0, 1.0, 0.0), armature=0.1),))
    row = np.array(pl.planar_model(Multibody(held)).row)
    row[pl.HEADER + pl.N_ARMATURE] = 0.0
    y = np.column_stack([np.linspace(-1, 1, L), np.linspace(0, 2, L)])
    out = np.empty(2 * L)
    pl.planar_rhs_lanes(to_lanes(y), row, out)
    single = np.empty(2)
    pl.planar_rhs(y[3], row, single)
    assert np.isnan(single[1]) and np.all(np.isnan(from_lanes(out, 2)[:, 1]))


@pytest.mark.parametrize("count", [8, 13, 64])
def test_an_rk4_batch_over_lanes_equals_the_scalar_loop_bit_for_bit(count):
    rng = np.random.default_rng(count)
    layout = planar_tree(rng, 4, NORMALS["y"])
    nv = Multibody(layout).nv
    scene = Scene.from_layout(layout, t_end=0.1, qpos0=rng.uniform(-1, 1, (count, nv)))
    native = scene.native_model
    assert native.rhs_lanes is pl.planar_rhs_lanes
    bound = integrators.bind_rk4(native.rhs, count, 1e-3, 100, 10, lanes=native.rhs_lanes)
    assert isinstance(bound, integrators.LanesBound)
    ours, theirs = np.empty((11, count, 2 * nv)), np.empty((11, count, 2 * nv))
    failed = bound(np.ascontiguousarray(native.y0), np.ascontiguousarray(native.params), ours)
    assert np.all(failed == -1)
    integrators.run_rk4(native.rhs, native.y0, native.params, 1e-3, 100, 10, theirs)
    np.testing.assert_array_equal(ours, theirs)
    # and through simulate, which takes the lanes for this batch: each element as its single run
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    single = rbody.simulate(Scene.from_layout(layout, t_end=0.1, qpos0=scene.qpos0[count - 1]), dt=1e-3, method="rk4")
    np.testing.assert_array_equal(run["qpos"][:, count - 1], single["qpos"])


def test_rows_of_different_parameters_take_the_scalar_loop():
    rng = np.random.default_rng(5)
    layout = planar_tree(rng, 3, NORMALS["y"])
    native = Scene.from_layout(layout, t_end=0.1, qpos0=rng.uniform(-1, 1, (16, Multibody(layout).nv))).native_model
    params = np.array(native.params)
    params[3, pl.HEADER + pl.N_MASS] *= 2.0  # one element heavier: its lanes would read the wrong row
    bound = integrators.bind_rk4(native.rhs, 16, 1e-3, 20, 20, lanes=native.rhs_lanes)
    ours, theirs = (np.empty((2,) + native.y0.shape) for _ in range(2))
    bound(np.ascontiguousarray(native.y0), params, ours)
    integrators.run_rk4(native.rhs, native.y0, params, 1e-3, 20, 20, theirs)
    np.testing.assert_array_equal(ours, theirs)


def test_an_element_that_fails_is_reported_at_its_step_and_frozen_as_in_the_scalar_loop():
    rng = np.random.default_rng(2)
    layout = planar_tree(rng, 2, NORMALS["y"])
    native = Scene.from_layout(layout, t_end=0.1, qpos0=rng.uniform(-1, 1, (9, Multibody(layout).nv))).native_model
    y0 = np.array(native.y0)
    y0[4, -1] = 1e300  # a velocity that overflows within the first steps
    bound = integrators.bind_rk4(native.rhs, 9, 1e-3, 30, 5, lanes=native.rhs_lanes)
    ours, theirs = np.empty((7, 9, y0.shape[1])), np.empty((7, 9, y0.shape[1]))
    failed = bound(y0, np.ascontiguousarray(native.params), ours)
    expected = integrators.run_rk4(native.rhs, y0, native.params, 1e-3, 30, 5, theirs)
    np.testing.assert_array_equal(failed, expected)
    assert failed[4] > 0 and np.all(np.delete(failed, 4) == -1)
    np.testing.assert_array_equal(ours, theirs)


# ----- trees in 3-D without ball or free joints ----------------------------------------------------------

def hinge_states(rng, model: Multibody) -> np.ndarray:
    y = np.zeros((L, model.nq + model.nv))
    y[:, :model.nq] = model.qpos0 + rng.uniform(-2, 2, (L, model.nq))
    y[:, model.nq:] = rng.uniform(-3, 3, (L, model.nv))
    return y


@pytest.mark.parametrize("seed", range(8))
def test_the_3d_kernel_over_lanes_gives_each_lane_the_scalar_bits(seed):
    """Hinges, slides, several joints on one body, welds (and roll joints, from the planar trees)."""
    rng = np.random.default_rng(seed)
    layout = (random_tree(rng, int(rng.integers(1, 9)), kinds=("hinge", "slide", "weld", "multi")) if seed % 2
              else planar_tree(rng, int(rng.integers(1, 6)), NORMALS["x"]))
    model = Multibody(layout)
    assert mb.runs_in_lanes(model)
    p, y = np.array(model.params), hinge_states(rng, model)
    y[5, :model.nq] += 2e5  # beyond the polynomial sine's range in one lane: np.sin and np.cos there
    theirs = np.empty_like(y)
    for lane in range(L):
        mb.tree_rhs(np.array(y[lane]), p, theirs[lane])
    out = np.full(y.size, np.nan)
    mb.tree_rhs_lanes(to_lanes(y), p, out)
    np.testing.assert_array_equal(from_lanes(out, y.shape[1]), theirs)


def test_a_3d_lane_whose_pivot_vanishes_gets_nan_where_the_scalar_kernel_does():
    point = Inertia(1.0, np.zeros(3), np.zeros((3, 3)))
    held = Layout(bodies=(Body("p", point),), joints=(Joint("h", "hinge", "p", axis=(0.0, 1.0, 0.0), armature=0.1),))
    p = np.array(Multibody(held).params)
    p[int(p[mb.H_DOF]) + mb.D_ARMATURE] = 0.0
    y = np.column_stack([np.linspace(-1, 1, L), np.linspace(0, 2, L)])
    out = np.empty(2 * L)
    mb.tree_rhs_lanes(to_lanes(y), p, out)
    single = np.empty(2)
    mb.tree_rhs(np.array(y[3]), p, single)
    assert np.isnan(single[1]) and np.all(np.isnan(from_lanes(out, 2)[:, 1]))


def test_trees_with_ball_or_free_joints_have_no_lanes():
    ball = Layout(bodies=(Body("a", Inertia.box(1.0, [0.1, 0.2, 0.3])),), joints=(Joint("j", "ball", "a"),))
    free = Layout(bodies=(Body("a", Inertia.box(1.0, [0.1, 0.2, 0.3])),), joints=(Joint("j", "free", "a"),))
    for layout in (ball, free):
        scene = Scene.from_layout(layout, t_end=0.1)
        assert not mb.runs_in_lanes(scene.multibody) and scene.native_model.rhs_lanes is None


@pytest.mark.parametrize("count", [8, 21])
def test_a_3d_rk4_batch_over_lanes_equals_the_scalar_loop_bit_for_bit(count):
    rng = np.random.default_rng(count)
    layout = random_tree(rng, 5, kinds=("hinge", "slide", "weld"))
    model = Multibody(layout)
    scene = Scene.from_layout(layout, t_end=0.05, qpos0=model.qpos0 + rng.uniform(-1, 1, (count, model.nq)))
    native = scene.native_model
    if native.rhs is not mb.tree_rhs:
        pytest.skip("a planar tree: the planar path's lanes are tested above")
    assert native.rhs_lanes is mb.tree_rhs_lanes
    ours, theirs = np.empty((6, count, native.y0.shape[1])), np.empty((6, count, native.y0.shape[1]))
    bound = integrators.bind_rk4(native.rhs, count, 1e-3, 50, 10, lanes=native.rhs_lanes)
    assert isinstance(bound, integrators.LanesBound)
    bound(np.ascontiguousarray(native.y0), np.ascontiguousarray(native.params), ours)
    integrators.run_rk4(native.rhs, native.y0, native.params, 1e-3, 50, 10, theirs)
    np.testing.assert_array_equal(ours, theirs)


# ----- the lane operations --------------------------------------------------------------------------------

@njit
def _lane_sin_cos(x, s, c):
    X, S, C = address(x, 0), address(s, 0), address(c, 0)
    for g in range(x.size // simd.WIDTH):
        a, b = simd.sin_cos(simd.load(X, simd.WIDTH * g))
        simd.store(S, simd.WIDTH * g, a)
        simd.store(C, simd.WIDTH * g, b)


@njit
def _scalar_sin_cos(x, s, c):
    for i in range(x.size):
        s[i], c[i] = sin_cos(x[i])


def test_sin_cos_over_lanes_has_the_scalar_bits_within_two_ulp_of_numpy():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-r, r, 40_000) for r in (1e-7, 1.0, 10.0, 1e3, REDUCED_RANGE)])
    s, c, s1, c1 = (np.empty_like(x) for _ in range(4))
    _lane_sin_cos(x, s, c)
    _scalar_sin_cos(x, s1, c1)
    np.testing.assert_array_equal(s, s1)
    np.testing.assert_array_equal(c, c1)
    for ours, exact in ((s, np.sin(x)), (c, np.cos(x))):
        assert np.max(np.abs(ours - exact) / np.spacing(np.abs(exact))) <= 2.0


@njit
def _operations(a, b, out):
    A, B, O = address(a, 0), address(b, 0), address(out, 0)
    x, y = simd.load(A, 0), simd.load(B, 0)
    simd.store(O, 0, simd.greater(x, y))
    simd.store(O, 8, simd.where(simd.greater(x, y), x, y))
    simd.store(O, 16, abs(x - y))
    simd.store(O, 24, simd.maximum(x, y))
    simd.store6(O, 32, x * 2.0 - y / 4.0)
    return simd.total(x), simd.largest_abs(y)


def test_lane_operations_equal_numpy_lane_by_lane():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=8), rng.normal(size=8)
    b[3] = np.nan
    out = np.full(40, -7.0)
    total, largest = _operations(a, b, out)
    np.testing.assert_array_equal(out[0:8], (a > b).astype(float))  # NaN compares false
    np.testing.assert_array_equal(out[8:16], np.where(a > b, a, b))
    np.testing.assert_array_equal(out[16:24], np.abs(a - b))
    np.testing.assert_array_equal(out[24:32], np.where(b > a, b, a))  # numba's max: a NaN b keeps a
    np.testing.assert_array_equal(out[32:38], (a * 2.0 - b / 4.0)[:6])
    assert np.all(out[38:] == -7.0)  # store6 writes six numbers
    assert total == pytest.approx(a.sum(), rel=1e-15) and np.isnan(largest)
