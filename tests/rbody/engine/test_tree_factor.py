"""The mass matrix's factor along the tree (rbody.engine.constraints.tree_factor), against the dense algebra on
random trees, and the time-stepping that runs on it against closed forms on a pile of bodies."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import rbody
from rbody import Multibody
from rbody.engine import multibody as mb
from rbody.engine.constraints.cone import NORMAL, ROW, TANGENT, TANGENT2, cone_residual
from rbody.engine.constraints.islands import label_islands
from rbody.engine.constraints.stepping import SUPPORT_DOFS, _solve_islands, solve_problem
from rbody.engine.constraints.tree_factor import (dof_columns, gram_by_dofs, gram_by_scan, gram_of_few_dofs,
                                                  product_by_dofs,
                                                  tree_solve_rows_into, tree_solve_supports_into)
from rbody.engine.mass_factor import tree_factor, tree_solve, tree_solve_transposed

sys.path.insert(0, str(Path(__file__).parent))
from trees import random_tree  # noqa: E402

KINDS = ("hinge", "slide", "ball", "free", "weld", "multi")


def tree_and_mass_matrix(seed: int):
    """A random tree's dof parents (nv,) and M (nv, nv) at a random configuration."""
    rng = np.random.default_rng(seed)
    model = Multibody(random_tree(rng, int(rng.integers(3, 14)), kinds=KINDS))
    p = model._kernel_params
    do = int(p[mb.H_DOF])
    parent = np.array([int(p[do + d * mb.DOF_SIZE + mb.D_PARENT]) for d in range(model.nv)], dtype=np.int64)
    q = model.qpos0 + 0.0
    return rng, parent, model.mass_matrix(q)


def path_to_root(parent, d):
    out = []
    while d >= 0:
        out.append(d)
        d = parent[d]
    return out


def rows_on_paths(rng, parent, m):
    """m rows (m, nv), each nonzero on one dof's path to its root (a point's Jacobian on that body)."""
    J = np.zeros((m, parent.size))
    for r in range(m):
        for d in path_to_root(parent, int(rng.integers(parent.size))):
            J[r, d] = rng.normal()
    return J


def ancestors_mask(parent):
    """(nv, nv) True where column j is row i or one of its ancestors: the factor's pattern."""
    mask = np.zeros((parent.size, parent.size), dtype=bool)
    for i in range(parent.size):
        mask[i, path_to_root(parent, i)] = True
    return mask


@pytest.mark.parametrize("seed", range(8))
def test_the_factor_reproduces_M_from_the_ancestors_entries_alone(seed):
    _rng, parent, M = tree_and_mass_matrix(seed)
    assert np.all(parent < np.arange(parent.size))  # the tree's dof order the factor relies on
    L = np.full(M.shape, np.nan)  # entries off the ancestors must be neither written nor read
    assert tree_factor(M, parent, L)
    mask = ancestors_mask(parent)
    assert np.all(np.isnan(L[~mask])) and np.all(np.isfinite(L[mask]))
    factor = np.where(mask, L, 0.0)
    assert np.max(np.abs(factor.T @ factor - M)) < 1e-13 * np.max(np.abs(M))
    assert np.all(np.diag(factor) > 0)


@pytest.mark.parametrize("seed", range(8))
def test_the_solves_invert_M_and_its_factor(seed):
    rng, parent, M = tree_and_mass_matrix(seed)
    L = np.zeros(M.shape)
    assert tree_factor(M, parent, L)
    b = rng.normal(size=parent.size)
    x = b.copy()
    tree_solve_transposed(L, parent, x)
    np.testing.assert_allclose(L.T @ x, b, rtol=0, atol=1e-12 * np.max(np.abs(b)))
    tree_solve(L, parent, x)  # L^-1 L^-T b = M^-1 b
    expected = np.linalg.solve(M, b)
    assert np.max(np.abs(x - expected)) < 1e-10 * np.max(np.abs(expected))


def supports_of(J):
    """(support, start, length) of rows J (m, nv): each row's nonzero dofs, ascending (a path: closed under parents)."""
    lists = [np.flatnonzero(row) for row in J]
    start = np.cumsum([0] + [len(x) for x in lists[:-1]]).astype(np.int64)
    return (np.concatenate(lists).astype(np.int64), start, np.array([len(x) for x in lists], dtype=np.int64))


def metric_by_dofs(A, m, support, start, length):
    """(W, island, first, columns) of A through dof_columns and gram_by_dofs."""
    first = np.empty(A.shape[0] + 1, dtype=np.int64)
    short = np.empty(1, dtype=np.int64)
    listed = dof_columns(A, m, support, start, length, first, short)
    columns = np.empty(listed, dtype=np.int64)
    assert dof_columns(A, m, support, start, length, first, columns) == listed
    W = np.empty((m, m))
    island = np.empty(m, dtype=np.int64)
    gram_by_dofs(A, m, W, first, columns, island)
    return W, island, first, columns


@pytest.mark.parametrize("seed", range(8))
def test_the_metric_of_rows_on_paths_equals_J_Minv_JT_and_keeps_their_sparsity(seed):
    rng, parent, M = tree_and_mass_matrix(seed)
    L = np.zeros(M.shape)
    assert tree_factor(M, parent, L)
    m = 7
    J = np.vstack([np.zeros((2, parent.size)), rows_on_paths(rng, parent, m)])  # rows picked by index
    index = np.arange(2, 2 + m)
    A = np.empty((parent.size, m))
    tree_solve_rows_into(L, parent, J, index, m, A)
    assert np.all(A[J[index].T == 0.0] == 0.0)  # a column as sparse as its row (a path is closed under parents)
    dense = np.full(m, -1, dtype=np.int64)  # every dof
    by_column = np.empty(A.shape)
    tree_solve_supports_into(L, parent, J, index, m, by_column, dense, np.zeros(m, dtype=np.int64), dense)
    assert np.array_equal(by_column, A)
    support, start, length = supports_of(J[index])
    on_support = np.full(A.shape, np.nan)  # each column on its row's support alone: the same bits there, nothing off it
    tree_solve_supports_into(L, parent, J, index, m, on_support, support, start, length)
    mask = J[index].T != 0.0
    assert np.array_equal(on_support[mask], A[mask]) and np.all(np.isnan(on_support[~mask]))
    W, island, first, columns = metric_by_dofs(on_support, m, support, start, length)
    expected = J[index] @ np.linalg.solve(M, J[index].T)
    assert np.max(np.abs(W - expected)) < 1e-10 * np.max(np.abs(expected))
    np.testing.assert_allclose(W, A.T @ A, rtol=1e-14, atol=1e-14 * np.max(np.abs(W)))
    assert np.array_equal(W, W.T)
    W_dense, island_dense, _first, _columns = metric_by_dofs(A, m, support, start, np.full(m, -1, dtype=np.int64))
    assert np.array_equal(W, W_dense) and np.array_equal(island, island_dense)  # the lists: A's nonzeros either way
    W_scan, island_scan = np.empty((m, m)), np.empty(m, dtype=np.int64)
    gram_by_scan(A, m, W_scan, np.empty(m, dtype=np.int64), island_scan)  # a few dofs' rows read whole: the same
    assert np.array_equal(W, W_scan) and np.array_equal(island, island_scan)
    lam = rng.normal(size=m)
    x = np.empty(parent.size)
    product_by_dofs(on_support, lam, first, columns, x)
    np.testing.assert_allclose(x, A @ lam, rtol=1e-14, atol=1e-14 * np.max(np.abs(A @ lam)))
    # the islands: rows joined exactly where a chain of shared dofs links them (W's blocks)
    count = label_islands(island, np.full(m, ROW, dtype=np.int64), m)
    linked = (A != 0.0).T.astype(int) @ (A != 0.0).astype(int) > 0
    for _ in range(m):
        linked = (linked.astype(int) @ linked.astype(int)) > 0
    assert np.array_equal(island[:, None] == island[None, :], linked)
    assert count == np.unique(island).size and sorted(set(island.tolist())) == list(range(count))
    assert np.all(np.diff([np.argmax(island == k) for k in range(count)]) > 0)  # labelled in order of first rows


def test_the_metric_of_few_dofs_is_blas_where_every_row_shares_the_dofs_and_the_sums_by_dof_where_few_do():
    """gram_of_few_dofs: W = A^T A and the rows' islands. Rows that share every dof (a robot's feet on its base)
    take BLAS's product, W within round-off of A^T A, one island; ten free bodies' contacts, three rows each on
    their own body's six dofs, take gram_by_scan's sums, its bits and its ten islands."""
    rng = np.random.default_rng(3)
    for shared, (nv, m) in ((True, (26, 68)), (False, (60, 30))):
        if shared:
            A = rng.normal(size=(nv, m))
        else:
            A = np.zeros((nv, m))
            for body in range(10):
                A[6 * body:6 * body + 6, 3 * body:3 * body + 3] = rng.normal(size=(6, 3))
        W, island = np.full((m, m), np.nan), np.empty(m, dtype=np.int64)
        assert gram_of_few_dofs(A, m, W, np.empty(m, dtype=np.int64), island) == shared
        W_scan, island_scan = np.empty((m, m)), np.empty(m, dtype=np.int64)
        gram_by_scan(A, m, W_scan, np.empty(m, dtype=np.int64), island_scan)
        assert np.array_equal(island, island_scan)
        count = label_islands(island, np.full(m, ROW, dtype=np.int64), m)
        assert count == (1 if shared else 10)
        if shared:
            np.testing.assert_allclose(W, A.T @ A, rtol=1e-13, atol=1e-13 * np.max(np.abs(W)))
        else:
            assert np.array_equal(W, W_scan)


def test_a_pivot_not_positive_is_reported():
    parent = np.array([-1, 0, 1], dtype=np.int64)
    M = np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.5], [0.0, 0.5, 2.0]])  # indefinite: its Schur complement < 0
    assert not tree_factor(M, parent, np.zeros((3, 3)))


def test_a_contact_s_rows_stay_in_one_island_whatever_their_jacobians():
    role = np.array([ROW, NORMAL, TANGENT, TANGENT2, NORMAL, ROW], dtype=np.int64)
    island = np.arange(6, dtype=np.int64)  # nothing shared: every row apart but the cone's
    assert label_islands(island, role, 6) == 4
    assert island.tolist() == [0, 1, 1, 1, 2, 3]


def block_cone_problem(rng, blocks):
    """A problem of `blocks` independent contacts (condim 3), each beside a limit row it is coupled with: W
    block-diagonal, definite."""
    b, lo, hi, role, mu = [], [], [], [], []
    size = 4 * blocks
    W = np.zeros((size, size))
    for k in range(blocks):
        B = rng.normal(size=(4, 6))
        W[4 * k:4 * k + 4, 4 * k:4 * k + 4] = B @ B.T
        b += [rng.normal(), -abs(rng.normal()), rng.normal(), rng.normal()]
        lo += [0.0, 0.0, -np.inf, -np.inf]
        hi += [np.inf] * 4
        role += [ROW, NORMAL, TANGENT, TANGENT2]
        mu += [0.0, 0.0, rng.uniform(0.1, 1.0), rng.uniform(0.1, 1.0)]
    order = rng.permutation(blocks)  # the blocks' rows interleaved by block order only (a cone's rows contiguous)
    rows = np.concatenate([np.arange(4 * k, 4 * k + 4) for k in order])
    return (W[np.ix_(rows, rows)], np.array(b)[rows], np.array(lo)[rows], np.array(hi)[rows],
            np.array(role, dtype=np.int64)[rows], np.array(mu)[rows])


@pytest.mark.parametrize("seed", range(4))
def test_islands_solved_apart_give_the_whole_problem_s_solution(seed):
    rng = np.random.default_rng(seed)
    W, b, lo, hi, role, mu = block_cone_problem(rng, 5)
    m = b.size
    whole = np.zeros(m)
    status, residual = solve_problem(W, b, lo, hi, role, mu, whole, True, 64, 2000, 1e-10)
    assert status == 0 and residual <= 1e-10
    island = np.arange(m, dtype=np.int64)
    for c in range(m):  # joined by W's blocks, as gram_by_dofs joins them
        for z in range(c):
            if W[c, z] != 0.0:
                island[island == island[c]] = island[z]
    island = np.unique(island, return_inverse=True)[1].astype(np.int64)  # 0.. in order of first rows
    assert island.max() + 1 == 5  # a block each
    apart = np.zeros(m)
    status, residual = _solve_islands(W, b, lo, hi, role, mu, apart, island, 5, 64, 2000, 1e-10)
    assert status == 0 and cone_residual(W, b, lo, hi, role, mu, apart) <= 1e-10
    np.testing.assert_allclose(apart, whole, rtol=0, atol=1e-8)


def pile_xml(columns: int, height: int, radius: float = 0.1) -> str:
    """columns x columns towers of `height` spheres s{i}_{k}, each touching the one below (the lowest the floor)."""
    bodies = []
    for i in range(columns * columns):
        for k in range(height):
            x, y = 3 * radius * (i % columns), 3 * radius * (i // columns)
            bodies.append(f'<body name="s{i}_{k}" pos="{x} {y} {radius * (1 + 2 * k)}"><freejoint/>'
                          f'<geom type="sphere" size="{radius}" mass="1"/></body>')
    return (f'<mujoco><option timestep="0.01"/><worldbody><geom type="plane" size="5 5 0.1"/>{"".join(bodies)}'
            f'</worldbody></mujoco>')


def test_a_pile_of_sphere_towers_rests_where_it_stands(tmp_path):
    """Nine towers of three spheres (nv = 162): each sphere stays at (2k + 1) r, to round-off, for 2 s."""
    path = tmp_path / "pile.xml"
    path.write_text(pile_xml(3, 3))
    run = rbody.simulate(rbody.from_mjcf(path, t_end=2.0), dt=0.01)
    for i in range(9):
        for k in range(3):
            com = run[f"s{i}_{k}.com"]
            assert np.max(np.abs(com - com[0])) < 1e-13
            assert abs(com[-1, 2] - 0.1 * (2 * k + 1)) < 1e-13


def test_a_sphere_thrown_in_a_pile_rolls_at_five_sevenths_from_t_star(tmp_path):
    """Beside eleven resting spheres, one thrown sliding without spin at v0 on mu: v0 - mu g t until
    t* = 2 v0 / (7 mu g), then 5/7 v0 (the chapter's rolling), with the step's factor along a tree of 73 dofs, more
    than SUPPORT_DOFS: each contact's rows on their support, beside an arm held on its stop by a limit's row (a row
    of every dof)."""
    v0, mu, radius, dt = 2.0, 0.4, 0.1, 1e-3
    bodies = [f'<body name="rest{k}" pos="{x} 3 {radius}"><freejoint/><geom type="sphere" size="{radius}" '
              f'mass="1"/></body>' for k, x in enumerate(np.arange(11) * 0.5)]
    arm = ('<body name="arm" pos="0 -3 2"><joint name="stop" type="hinge" axis="0 1 0" limited="true" range="-30 0"/>'
           '<geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02" mass="1" contype="0" conaffinity="0"/></body>')
    xml = (f'<mujoco><option timestep="{dt}" gravity="0 0 -9.81"/><worldbody>'
           f'<geom type="plane" size="50 50 0.1" friction="{mu} 0 0"/>'
           f'<body name="thrown" pos="0 0 {radius}"><freejoint/>'
           f'<geom type="sphere" size="{radius}" mass="1" friction="{mu} 0 0"/></body>{"".join(bodies)}{arm}'
           f'</worldbody></mujoco>')
    path = tmp_path / "thrown.xml"
    path.write_text(xml)
    scene = rbody.from_mjcf(path, t_end=0.5, qvel0=np.r_[v0, np.zeros(5 + 6 * 11 + 1)])
    assert scene.multibody.nv > SUPPORT_DOFS
    run = rbody.simulate(scene, dt=dt)
    v = run["thrown.velocity"][:, 0]
    t_star = 2 * v0 / (7 * mu * 9.81)
    sliding, rolling = run.t < t_star - dt, run.t > t_star + dt
    np.testing.assert_allclose(v[sliding], v0 - mu * 9.81 * run.t[sliding], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[rolling], 5 / 7 * v0, rtol=0, atol=1e-12)
    assert np.max(np.abs(run["thrown.com"][:, 2] - radius)) < 1e-15
    for k in range(11):
        assert np.max(np.abs(run[f"rest{k}.velocity"])) < 1e-13
    arm_com = run["arm.com"]  # gravity pushes the arm onto its stop at 0, where the limit holds it
    assert np.max(np.abs(arm_com - arm_com[0])) < 1e-13 and abs(arm_com[0, 2] - 2.0) < 1e-15


def cantilever_xml(links: int, length: float = 0.05) -> str:
    """A horizontal chain of `links` hinged links along x, each hinge's upper stop at 0 (gravity turns a link down,
    +y): every stop holds, the chain a cantilever of stops."""
    body = ""
    for k in reversed(range(links)):
        body = (f'<body name="l{k}" pos="{0 if k == 0 else length} 0 {1 if k == 0 else 0}">'
                f'<joint name="j{k}" type="hinge" axis="0 1 0" limited="true" range="-30 0"/>'
                f'<geom type="capsule" fromto="0 0 0 {length} 0 0" size="0.01" mass="0.1"/>{body}</body>')
    return (f'<mujoco><option timestep="0.001"><flag contact="disable"/></option><worldbody>{body}</worldbody>'
            f'</mujoco>')


def test_a_cantilever_of_seventy_stops_holds_on_them(tmp_path):
    """Seventy hinges in one chain (nv = 70, more than SUPPORT_DOFS), each held by its stop against gravity: every
    stop's row is taken on its dof's path to the root (the one dof it acts on and its ancestors, up to all seventy),
    the rows past the supports' room on every dof. Each joint stays on its stop within the projection's tolerance
    for 0.5 s, so the tip's centre within that tolerance times the sum of its lever arms (1.2e-11 m); a support that
    missed an ancestor would leave that stop's impulse acting on the wrong dofs, and the chain would sag (gravity
    alone moves it 5e-6 m in a step)."""
    from rbody.engine.constraints.dynamics import PROJECTION_TOLERANCE

    links, length = 70, 0.05
    path = tmp_path / "cantilever.xml"
    path.write_text(cantilever_xml(links, length))
    scene = rbody.from_mjcf(path, t_end=0.5)
    assert scene.multibody.nv == links > SUPPORT_DOFS
    run = rbody.simulate(scene, dt=1e-3)
    assert np.max(np.abs(run["qpos"])) <= PROJECTION_TOLERANCE
    tip = run[f"l{links - 1}.com"]
    arms = length * (links - 0.5 - np.arange(links))  # each hinge to the tip's centre [m]
    assert np.max(np.abs(tip - tip[0])) <= PROJECTION_TOLERANCE * arms.sum()
    assert abs(tip[0, 0] - arms[0]) < 1e-12
