"""The constraint rows (rbody.engine.constraints.jacobians) against finite differences on random trees, and the
complementarity solvers against their definition."""

from __future__ import annotations

import numpy as np
import pytest

from rbody import Body, Equality, Joint, Layout, Multibody
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.solver import mlcp_exact, mlcp_pgs, natural_residual
from rbody.engine.constraints.table import build_table
from rbody.motion import quat_normalize

from .trees import random_inertia


def constrained_tree(rng: np.random.Generator) -> Layout:
    """Five bodies (hinge, slide, ball, free, two hinges) with a limit on each kind, a cone, friction, a connect, a
    weld and a polynomial joint coupling."""
    bodies, joints = [], []
    spec = [("a", "world", ["hinge"]), ("b", "a", ["slide", "hinge"]), ("c", "b", ["ball"]), ("d", "world", ["free"]),
            ("e", "a", ["hinge"])]
    for name, parent, kinds in spec:
        bodies.append(Body(name, random_inertia(rng), parent=parent, pos=tuple(rng.uniform(-0.5, 0.5, 3)),
                           quat=tuple(quat_normalize(rng.normal(size=4)))))
        for k, kind in enumerate(kinds):
            extra = {}
            if kind in ("hinge", "slide"):
                extra = dict(range=(-2.0, 2.0), frictionloss=0.3, ref=float(rng.uniform(-0.2, 0.2)))
            elif kind == "ball":
                extra = dict(range=(0.0, 2.5), frictionloss=0.1)
            joints.append(Joint(f"{name}{k}", kind, name, axis=tuple(rng.normal(size=3)),
                                anchor=tuple(rng.uniform(-0.2, 0.2, 3)), **extra))
    equalities = (Equality("ring", "connect", body1="c", body2="d", anchor=(0.1, 0.2, 0.0)),
                  Equality("glue", "weld", body1="e", body2="world", anchor=(0.3, 0.0, 0.1)),
                  Equality("gear", "joint", joint1="e0", joint2="b1", polycoef=(0.1, 0.7, 0.2, -0.1, 0.05)))
    return Layout(bodies=tuple(bodies), joints=tuple(joints), equalities=equalities)


def random_state(rng, model: Multibody) -> tuple[np.ndarray, np.ndarray]:
    q = np.array(model.qpos0)
    for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
        if kind in ("hinge", "slide"):
            q[address] = rng.uniform(-1, 1)
        elif kind == "ball":
            q[address:address + 4] = quat_normalize(rng.normal(size=4))
        elif kind == "free":
            q[address:address + 3] = rng.normal(size=3)
            q[address + 3:address + 7] = quat_normalize(rng.normal(size=4))
    return q, rng.normal(size=model.nv)


def rows_at(p, table, model, q, v):
    nq, nv, n = dyn.sizes(p)
    y = np.zeros(n)
    y[:nq], y[nq:nq + nv] = q, v
    M, f = np.empty((nv, nv)), np.empty(nv)
    J, jdot, g = np.empty((table.rows, nv)), np.empty(table.rows), np.empty(table.rows)
    dyn.state_rows(p, y, M, f, J, jdot, g)
    return M, J, jdot, g


def moved(p, q, v, step):
    nq, nv, n = dyn.sizes(p)
    y = np.zeros(n)
    y[:nq] = q
    dyn.displace(p, y, step * v)
    return y[:nq]


@pytest.mark.parametrize("seed", range(4))
def test_rows_match_finite_differences_of_their_residuals(seed):
    """J v = dg/dt and J' v = d(J v)/dt at fixed v, by central differences along q (+) s v (every row kind: limits,
    a ball's cone, friction, connect, weld, a quartic joint coupling), on random states of a random tree."""
    rng = np.random.default_rng(seed)
    layout = constrained_tree(rng)
    model = Multibody(layout)
    table = build_table(layout, model)
    p = np.array(table.row(model.params))
    q, v = random_state(rng, model)
    _M, J, jdot, g = rows_at(p, table, model, q, v)
    s = 1e-6
    _, Jp, _, gp = rows_at(p, table, model, moved(p, q, v, s), v)
    _, Jm, _, gm = rows_at(p, table, model, moved(p, q, v, -s), v)
    weld = [i for i, (kind, _name, _c) in enumerate(table.labels()) if kind == "weld"][3:]  # its rotation rows
    friction = [i for i, (kind, _name, _c) in enumerate(table.labels()) if kind == "friction"]  # no position
    position = [i for i in range(table.rows) if i not in weld + friction]
    np.testing.assert_allclose((gp - gm)[position] / (2 * s), (J @ v)[position], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose((Jp @ v - Jm @ v) / (2 * s), jdot, rtol=1e-5, atol=1e-5)
    assert [u.kind for u in table.units].count("friction") == 7  # hinges, slide, and the ball's three dofs


@pytest.mark.parametrize("seed", range(3))
def test_every_units_rows_at_once_are_each_units_own(seed):
    """all_rows (which writes a joint's stop and friction rows in its own loop, not by unit_rows) and state_gaps give
    every unit's rows exactly as unit_rows gives them one unit at a time: limits, a cone, friction, connect, weld
    and a coupling, on random states of a random tree."""
    from rbody.engine import multibody
    from rbody.engine.constraints.jacobians import unit_at, unit_count, unit_rows
    from rbody.engine.constraints.table import U_ROW0

    rng = np.random.default_rng(seed)
    layout = constrained_tree(rng)
    model = Multibody(layout)
    table = build_table(layout, model)
    p = np.array(table.row(model.params))
    nq, nv, n = dyn.sizes(p)
    q, v = random_state(rng, model)
    M, f = np.empty((nv, nv)), np.empty(nv)
    J, jdot, g = np.full((table.rows, nv), np.nan), np.full(table.rows, np.nan), np.full(table.rows, np.nan)
    w = np.empty(multibody.workspace_size(p))
    acc = np.empty((int(p[multibody.H_BODIES]), 6))
    dyn.snapshot(p, q, v, np.zeros(0), M, f, J, jdot, g, w, acc)
    Ju, jdotu, gu = np.full_like(J, np.nan), np.full_like(jdot, np.nan), np.full_like(g, np.nan)
    for k in range(unit_count(p)):
        unit_rows(p, k, q, v, w, acc, Ju, jdotu, gu, int(p[unit_at(p, k) + U_ROW0]))
    assert np.array_equal(J, Ju) and np.array_equal(jdot, jdotu) and np.array_equal(g, gu)
    kinds = [u.kind for u in table.units]
    assert kinds.count("friction") == 7 and kinds.count("limit") == 9  # two stops on each hinge and slide, a cone
    y = np.zeros(n)
    y[:nq], y[nq:nq + nv] = q, v
    gaps = np.full(table.rows, np.nan)
    dyn.state_gaps(p, y, gaps)
    assert np.array_equal(gaps, g)


@pytest.mark.parametrize("seed", range(3))
def test_stops_and_dry_friction_alone_take_their_gaps_from_qpos_and_m_from_the_steps_frames(seed):
    """A tree whose units are all joints' stops and dry friction (hinges and slides): state_gaps reads their gaps
    from qpos without the tree's frames, and gives snapshot's g bit for bit; snapshot's M (the composite-rigid-body
    algorithm on the frames of its one outward pass, at v) is mass_matrix_one's (its own pass at v = 0) bit for
    bit, and its workspace keeps each body's own inertia (force elements read it after)."""
    from rbody.engine import multibody

    rng = np.random.default_rng(seed)
    bodies, joints = [], []
    for name, parent, kinds in (("a", "world", ["hinge"]), ("b", "a", ["slide", "hinge"]), ("c", "b", ["hinge"]),
                                ("d", "a", ["hinge", "hinge"])):
        bodies.append(Body(name, random_inertia(rng), parent=parent, pos=tuple(rng.uniform(-0.5, 0.5, 3)),
                           quat=tuple(quat_normalize(rng.normal(size=4)))))
        for k, kind in enumerate(kinds):
            joints.append(Joint(f"{name}{k}", kind, name, axis=tuple(rng.normal(size=3)),
                                anchor=tuple(rng.uniform(-0.2, 0.2, 3)), range=(-0.5, 0.5), frictionloss=0.2))
    layout = Layout(bodies=tuple(bodies), joints=tuple(joints))
    model = Multibody(layout)
    table = build_table(layout, model)
    p = np.array(table.row(model.params))
    nq, nv, n = dyn.sizes(p)
    q, v = rng.uniform(-1, 1, nq), rng.normal(size=nv)  # stops passed and apart
    M, f = np.empty((nv, nv)), np.empty(nv)
    J, jdot, g = np.empty((table.rows, nv)), np.empty(table.rows), np.empty(table.rows)
    w = np.empty(multibody.workspace_size(p))
    acc = np.empty((int(p[multibody.H_BODIES]), 6))
    dyn.snapshot(p, q, v, np.zeros(0), M, f, J, jdot, g, w, acc)
    y = np.zeros(n)
    y[:nq], y[nq:nq + nv] = q, v
    gaps = np.full(table.rows, np.nan)
    dyn.state_gaps(p, y, gaps)
    assert np.array_equal(gaps, g) and np.any(g < 0) and np.any(g > 0)
    assert [u.kind for u in table.units].count("limit") == 12
    own = np.empty_like(M)
    w_own = np.empty_like(w)
    multibody.mass_matrix_one(p, q, own, w_own)
    assert np.array_equal(M, own) and np.array_equal(M, M.T)
    views, views_own = multibody._views(p, w), multibody._views(p, w_own)
    assert np.array_equal(views.h, views_own.h) and np.array_equal(views.Ibar, views_own.Ibar)
    np.testing.assert_allclose(views.h[0], bodies[0].inertia.mass * (views.xpos[0] + views.xmat[0] @ np.asarray(
        bodies[0].inertia.com)), rtol=1e-12, atol=1e-12)  # body a's own m c, not its subtree's


def test_weld_rotation_rows_are_the_rate_of_its_error_where_it_holds():
    """At a state where the weld holds (E = identity), d/dt of E's rotation vector is omega1 - omega2 = J v."""
    rng = np.random.default_rng(7)
    a = Body("a", random_inertia(rng), quat=tuple(quat_normalize(rng.normal(size=4))))
    layout = Layout(bodies=(a,), joints=(Joint("f", "free", "a"),),
                    equalities=(Equality("w", "weld", body1="a", anchor=(0.2, 0.1, 0.0)),))
    model = Multibody(layout)
    table = build_table(layout, model)
    p = np.array(table.row(model.params))
    q, v = np.array(model.qpos0), rng.normal(size=6)
    _M, J, _jdot, g = rows_at(p, table, model, q, v)
    assert np.abs(g).max() < 1e-15  # completed at the reference pose
    s = 1e-6
    gp = rows_at(p, table, model, moved(p, q, v, s), v)[3]
    gm = rows_at(p, table, model, moved(p, q, v, -s), v)[3]
    np.testing.assert_allclose((gp - gm) / (2 * s), J @ v, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("seed", range(20))
def test_exact_and_gauss_seidel_solve_the_mixed_complementarity_problem(seed):
    """Random positive (semi-)definite W, bilateral, unilateral and box rows: both solvers meet every condition,
    and give the same w = W lambda + b (unique where lambda is not)."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 9))
    A = rng.normal(size=(m, m if seed % 2 else m + 2))
    W = A @ A.T
    lo = rng.choice([0.0, -1.0, -np.inf], size=m)
    hi = np.where(lo == -1.0, 1.0, np.inf)
    lo[lo == -np.inf] = np.where(seed % 2, 0.0, -np.inf)  # singular W: no free rows (they could contradict)
    b = rng.normal(size=m)
    lam = np.empty(m)
    status, _steps = mlcp_exact(W, b, lo, hi, lam)
    assert status == 0
    w = W @ lam + b
    tol = 1e-9 * (1 + np.abs(b).max())
    assert np.all(lam >= lo - tol) and np.all(lam <= hi + tol)
    at_lo, at_hi = np.isclose(lam, lo, atol=tol), np.isclose(lam, hi, atol=tol)
    inside = ~at_lo & ~at_hi
    assert np.all(np.abs(w[inside]) <= tol) and np.all(w[at_lo] >= -tol) and np.all(w[at_hi] <= tol)
    assert natural_residual(W, b, lo, hi, lam) <= tol
    gs = np.zeros(m)
    sweeps, residual = mlcp_pgs(W, b, lo, hi, gs, 1e-11, 200000)
    assert residual <= 1e-11
    np.testing.assert_allclose(W @ gs + b, w, rtol=0, atol=1e-7 * (1 + np.abs(b).max()))


def test_the_row_labels_are_found_once_and_handed_out_anew():
    """The table's labels (a run's meta["constraint_rows"]) and row count are found once: each call hands out a new
    list with a label per row, each unit's rows in order, so that a caller's change to one list leaves the next."""
    layout = constrained_tree(np.random.default_rng(0))
    table = build_table(layout, Multibody(layout))
    first = table.labels()
    expected = [(unit.kind, unit.name, k) for unit in table.units for k in range(unit.rows)]
    assert first == expected and len(first) == table.rows == sum(unit.rows for unit in table.units)
    first.append(("weld", "changed", 0))
    first[0] = ("limit", "changed", 0)
    assert table.labels() == expected and table.labels() is not table.labels()


def test_the_units_maps_kept_by_the_table_agree_with_its_units():
    """unit_rows, unit_of_first_row and names(which), found once per table for a run's observables, agree with the
    units they are read from: each unit's row count, the unit whose first row each row is (-1 for the others), the
    names of the units asked for, in the order asked; the arrays are read-only, the lists new each call."""
    layout = constrained_tree(np.random.default_rng(0))
    table = build_table(layout, Multibody(layout))
    assert table.unit_rows.tolist() == [unit.rows for unit in table.units]
    expected = [-1] * table.rows
    for k, unit in enumerate(table.units):
        expected[unit.row0] = k
    assert table.unit_of_first_row.tolist() == expected and max(unit.rows for unit in table.units) > 1
    which = np.arange(len(table.units))[::-2]
    assert table.names(which) == [table.units[k].name for k in which] and table.names([]) == []
    names = table.names(which)
    names.append("changed")
    assert table.names(which) == [table.units[k].name for k in which]
    with pytest.raises(ValueError):
        table.unit_rows[0] = 7
