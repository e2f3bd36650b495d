"""The broad phase (rbody.engine.contacts.broadphase): each geom's bounding sphere found once per call, a pair's
bound on its candidates' gaps from two of them, the same to the bit as contacts.kinematics.clearance, which
computes it pair by pair; the constraint table's pair and geom records that it reads."""

import numpy as np
import pytest

import rbody
from rbody.engine import multibody as mb
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.jacobians import row_count, unit_at, unit_count
from rbody.engine.constraints.stepping import (EXACT_ROWS, MODES, PGS_SWEEPS, STEP_TOLERANCE, MoreauRun, moreau_step,
                                               step_arena)
from rbody.engine.constraints.table import (C_GEOM, CONTACT_KINDS, G_TYPE, GEOM_SIZE, P_GEOM_A, P_GEOM_B, P_MARGIN,
                                            PAIR_SIZE,
                                            U_BODY1, U_BODY2, U_DOF, U_GPOS_A, U_GPOS_B, U_GSIZE_A, U_GSIZE_B,
                                            U_GTYPE_A, U_GTYPE_B, U_KIND, U_MARGIN, U_ROW0, U_ROWS, UNIT_SIZE)
from rbody.engine.contacts.broadphase import (N_BUILT, N_CENTRES, N_COUNT, NEIGHBOUR_SKIN, S_NORMAL, S_RADIUS,
                                              SPHERE_SIZE, _tight_at, contact0, contact_row0, first_unit_at, geom_at,
                                              geom_count, geom_spheres, kept_size, neighbours_size, pair_at,
                                              pair_count, pair_reaches, pair_span)
from rbody.engine.contacts.geometry import TYPE_CODES
from rbody.engine.contacts.kinematics import TIGHTEN_BELOW, clearance
from rbody.engine.contacts.terrain import HFIELD
from rbody.engine.contacts.rows import GEOMETRY_WORK, candidate, kept_geometry_size, pair_candidates
from rbody.engine.multibody import _effective_qpos

CUBE = " ".join(f"{v:g}" for x in (-0.1, 0.1) for y in (-0.07, 0.07) for z in (-0.05, 0.05) for v in (x, y, z))

# a floor, a height field and seven free bodies of every kind rbody collides, two geoms on one of them (a geom in
# several pairs has one geom record), a hinge with a limit before the contacts, margins on two geoms
XML = f"""<mujoco>
  <asset><mesh name="brick" vertex="{CUBE}"/>
    <hfield name="bumps" nrow="3" ncol="4" size="0.6 0.4 0.1 0.05"
            elevation="0 1 0 1  1 0 1 0  0 1 0 1"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <geom name="terrain" type="hfield" hfield="bumps" pos="3 3 0"/>
    <body name="arm" pos="0 0 1.2"><joint name="hinge" type="hinge" axis="0 1 0" range="-1 1"/>
      <geom name="arm" type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/></body>
    <body name="ball" pos="0.3 0 0.5"><freejoint/><geom name="ball" type="sphere" size="0.1" margin="0.01"/></body>
    <body name="rod" pos="-0.3 0.2 0.4"><freejoint/><geom name="rod" type="capsule" size="0.05 0.2"/></body>
    <body name="crate" pos="0 -0.3 0.3"><freejoint/><geom name="crate" type="box" size="0.2 0.1 0.05"/>
      <geom name="lid" type="box" pos="0 0 0.08" size="0.05 0.05 0.03"/></body>
    <body name="drum" pos="0.4 0.4 0.3"><freejoint/><geom name="drum" type="cylinder" size="0.1 0.06"/></body>
    <body name="egg" pos="-0.4 -0.4 0.3"><freejoint/><geom name="egg" type="ellipsoid" size="0.12 0.08 0.06"
      margin="0.005"/></body>
    <body name="brick" pos="0 0.5 0.3"><freejoint/><geom name="brick" type="mesh" mesh="brick"/></body>
  </worldbody>
</mujoco>"""


@pytest.fixture(scope="module")
def model():
    scene = rbody.from_mjcf(XML, t_end=0.1)
    prepared = rbody.prepare(scene, dt=0.01, method="moreau")
    table = prepared.model.constraints
    run = MoreauRun(table, prepared.params[0], "broad phase")
    return scene, table, run.p, np.array(prepared.y0[0])


def _workspace(p, y):
    """The tree's workspace at the state y (its frames and body velocities), as the step's kernels read it."""
    nq, nv, _n = dyn.sizes(p)
    q = np.empty(nq)
    _effective_qpos(p, y, q, 0)
    w = np.empty(mb.workspace_size(p))
    dyn._frames(p, q, y[nq:nq + nv], w)
    mb.velocities(p, np.ascontiguousarray(y[nq:nq + nv]), w)
    return w


def test_the_table_lists_each_pair_once_with_its_candidates_rows_and_geoms(model):
    _scene, table, p, _y = model
    codes = table.codes
    first_contact = int(np.flatnonzero(np.isin(codes, CONTACT_KINDS))[0])
    assert contact0(p) == first_contact and np.isin(codes[first_contact:], CONTACT_KINDS).all()  # contacts last
    assert contact_row0(p) == table.units[first_contact].row0
    units = np.asarray(p[unit_at(p, 0):unit_at(p, 0) + UNIT_SIZE * unit_count(p)]).reshape(-1, UNIT_SIZE)
    assert U_GSIZE_A == U_GPOS_A + 12 and U_GSIZE_B == U_GPOS_B + 12  # a geom record's pose: position, axes, size
    covered = []
    geoms = {}
    geom_start = int(p[table.offset + C_GEOM])
    for i in range(pair_count(p)):
        first, slots, row0, width = pair_span(p, pair_at(p, i))
        record = units[first]
        assert first_unit_at(p, pair_at(p, i)) == unit_at(p, first)
        assert record[U_DOF] == 0 and record[U_ROW0] == row0 and record[U_ROWS] == width
        for j in range(slots):  # its candidates: consecutive units, slots 0.., rows one after another
            unit = units[first + j]
            assert unit[U_KIND] in CONTACT_KINDS and unit[U_DOF] == j and unit[U_ROW0] == row0 + j * width
            assert np.array_equal(unit[U_GPOS_A:U_GSIZE_B + 3], record[U_GPOS_A:U_GSIZE_B + 3])
            covered.append(first + j)
        for side, body_at, type_at, pos_at in ((P_GEOM_A, U_BODY1, U_GTYPE_A, U_GPOS_A),
                                               (P_GEOM_B, U_BODY2, U_GTYPE_B, U_GPOS_B)):
            g = int(p[pair_at(p, i) + side])
            body, kind, pose = p[geom_start + g * GEOM_SIZE:geom_start + (g + 1) * GEOM_SIZE]
            assert (body, kind) == (record[body_at], record[type_at])
            # the geom's pose and size, read where its record points, are this pair's geom's
            assert np.array_equal(p[int(pose):int(pose) + 15], record[pos_at:pos_at + 15])
            key = (body, kind, tuple(record[pos_at:pos_at + 15]))
            assert geoms.setdefault(key, g) == g  # one record per geom
        assert p[pair_at(p, i) + P_MARGIN] == record[U_MARGIN]
    assert covered == list(range(first_contact, unit_count(p)))  # every contact unit in exactly one pair
    assert geom_count(p) == len(geoms) == 10  # floor, terrain, arm, ball, rod, crate, lid, drum, egg, brick
    assert pair_at(p, 1) - pair_at(p, 0) == PAIR_SIZE


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("h", [0.0, 0.01, 0.5])
def test_a_pairs_bound_is_clearances_to_the_bit(model, seed, h):
    """Random configurations and velocities, the bodies gathered near the origin so that some pairs overlap, some
    are near and some far: pair_reaches's (reach, motion) from the geoms' spheres equals clearance's, computed from
    the pair's first unit, exactly (pairs whose axes may part them hand the near ones to clearance; the rest is one
    formula)."""
    _scene, table, p, y0 = model
    rng = np.random.default_rng(seed)
    nq, nv, _n = dyn.sizes(p)
    y = y0.copy()
    for body in range(7):  # the free bodies' qpos (7 each) after the hinge's one
        at = 1 + 7 * body
        y[at:at + 3] = rng.uniform(-0.35, 0.35, 3) + (0.0, 0.0, 0.35)
        quat = rng.normal(size=4)
        y[at + 3:at + 7] = quat / np.linalg.norm(quat)
    y[0] = rng.uniform(-1, 1)
    y[nq:nq + nv] = rng.normal(scale=2.0, size=nv)
    w = _workspace(p, y)
    reach, motion = np.full(pair_count(p), np.nan), np.full(pair_count(p), np.nan)
    pair_reaches(p, w, h, reach, motion, np.empty(0))
    scratch = np.empty(GEOMETRY_WORK)
    near = 0
    for i in range(pair_count(p)):
        got = (reach[i], motion[i])
        expected = clearance(p, w, first_unit_at(p, pair_at(p, i)), h, scratch)[:2]
        assert got == expected, (i, got, expected)
        near += got[0] <= 0.0
    assert 0 < near < pair_count(p)  # the draw has pairs on both sides of the bound


def _gathered(p, y0, rng, spread):
    """A state with the seven free bodies placed at random within `spread` [m] of a point above the origin, turned
    at random, the hinge anywhere in its range; velocities 0."""
    nq, _nv, _n = dyn.sizes(p)
    y = y0.copy()
    for body in range(7):
        at = 1 + 7 * body
        y[at:at + 3] = rng.uniform(-spread, spread, 3) + (0.0, 0.0, spread)
        quat = rng.normal(size=4)
        y[at + 3:at + 7] = quat / np.linalg.norm(quat)
    y[0] = rng.uniform(-1, 1)
    y[nq:] = 0.0
    return y


def _nudged(p, y, rng, shift, speed):
    """y with each free body moved by up to `shift` [m] along each axis (orientation kept) and given velocities of
    about `speed` [m/s, rad/s]."""
    nq, nv, _n = dyn.sizes(p)
    z = y.copy()
    for body in range(7):
        z[1 + 7 * body:4 + 7 * body] += rng.uniform(-shift, shift, 3)
    z[nq:nq + nv] = rng.normal(scale=speed, size=nv)
    return z


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("h", [0.0, 0.002])
def test_the_neighbour_list_gives_every_near_pair_to_the_bit(model, seed, h):
    """The list built at a gathered configuration, then the bodies nudged by at most 2 mm an axis with speeds of
    about 0.3 m/s: within the skin, so the list is read, not built again (its centres stay the first
    configuration's). Every pair the full pass bounds at most TIGHTEN_BELOW is listed and bounded to the same bits
    (its tightened gap forgotten: clearance itself answers); every other pair gets a lower bound of its own, above
    TIGHTEN_BELOW; and some pairs are not listed at all."""
    _scene, table, p, y0 = model
    rng = np.random.default_rng(20 + seed)
    y = _gathered(p, y0, rng, 0.35)
    neighbours = np.zeros(neighbours_size(p))
    reach, motion = np.empty(pair_count(p)), np.empty(pair_count(p))
    pair_reaches(p, _workspace(p, y), h, reach, motion, neighbours)
    assert neighbours[N_BUILT] == 1.0
    neighbours[_tight_at(p):] = 0.0
    built = neighbours.copy()
    z = _nudged(p, y, rng, 0.002, 0.3)
    w = _workspace(p, z)
    full_reach, full_motion = np.empty(pair_count(p)), np.empty(pair_count(p))
    pair_reaches(p, w, h, full_reach, full_motion, np.empty(0))
    pair_reaches(p, w, h, reach, motion, neighbours)
    assert np.array_equal(neighbours[:_tight_at(p)], built[:_tight_at(p)])  # read, not built again
    listed = neighbours[N_CENTRES + 3 * geom_count(p):][:int(neighbours[N_COUNT])].astype(int)
    same = (reach == full_reach) & (motion == full_motion)
    assert same[listed].all()
    assert (full_reach[~same] > TIGHTEN_BELOW).all() and (reach[~same] <= full_reach[~same]).all()
    assert (reach[~same] > TIGHTEN_BELOW).all()
    assert 0 < len(listed) < pair_count(p) and (full_reach <= TIGHTEN_BELOW).any()


def _turned(p, y, rng, shift, angle):
    """y with each free body moved by up to `shift` [m] along each axis and turned by up to `angle` [rad] about a
    random axis."""
    z = y.copy()
    for body in range(7):
        at = 1 + 7 * body
        z[at:at + 3] += rng.uniform(-shift, shift, 3)
        axis = rng.normal(size=3)
        half = 0.5 * rng.uniform(0.0, angle)
        turn = np.concatenate(([np.cos(half)], np.sin(half) * axis / np.linalg.norm(axis)))
        w0, v0 = turn[0], turn[1:]
        w1, v1 = z[at + 3], z[at + 4:at + 7]
        z[at + 3], z[at + 4:at + 7] = w0 * w1 - v0 @ v1, w0 * v1 + w1 * v0 + np.cross(v0, v1)
    return z


def _least_gaps(p, w):
    """(pairs,) each pair's least candidate gap as the narrow phase finds it (less the margin)."""
    work = np.empty(GEOMETRY_WORK)
    normal, point = np.empty(3), np.empty(3)
    least = np.empty(pair_count(p))
    for i in range(pair_count(p)):
        count = pair_candidates(p, w, first_unit_at(p, pair_at(p, i)), work)
        least[i] = min(candidate(work, j, normal, point) for j in range(count))
    return least


def test_a_pairs_tightened_gap_bounds_it_as_its_geoms_move_and_turn(model):
    """Eight gathered configurations, the list built at each, then the bodies moved by up to 1 mm an axis and
    turned by up to 0.03 rad, five times over (within the skin: the list is read): every pair's bound stays at most
    the least gap of its candidates as the narrow phase finds them. Some listed pairs are bounded from their tightened
    gap (the gap less how far geom b has moved and turned in geom a's frame since it was found: not the full pass's
    bits), each above TIGHTEN_BELOW."""
    _scene, table, p, y0 = model
    remembered = 0
    for seed in range(8):
        rng = np.random.default_rng(40 + seed)
        y = _gathered(p, y0, rng, 0.3)
        neighbours = np.zeros(neighbours_size(p))
        reach, motion = np.empty(pair_count(p)), np.empty(pair_count(p))
        pair_reaches(p, _workspace(p, y), 0.0, reach, motion, neighbours)
        for _move in range(5):
            y = _turned(p, y, rng, 0.001, 0.03)
            w = _workspace(p, y)
            full_reach, full_motion = np.empty(pair_count(p)), np.empty(pair_count(p))
            pair_reaches(p, w, 0.0, full_reach, full_motion, np.empty(0))
            pair_reaches(p, w, 0.0, reach, motion, neighbours)
            assert (reach <= _least_gaps(p, w) + 1e-12).all()
            listed = np.zeros(pair_count(p), dtype=bool)
            listed[neighbours[N_CENTRES + 3 * geom_count(p):][:int(neighbours[N_COUNT])].astype(int)] = True
            from_memory = listed & (reach != full_reach)
            assert (reach[from_memory] > TIGHTEN_BELOW).all()
            remembered += int(from_memory.sum())
    assert remembered > 0


def test_a_tightened_gap_is_forgotten_where_the_geoms_have_turned_too_far():
    """Two boxes 0.1 m long side by side, 10 mm apart, their bounding spheres overlapping: the first call finds their
    gap by the separating axes and keeps it. Box b turned by 0.05 rad about its centre: the bound from the kept gap,
    10 mm less r_b |Q - Q0|_F = 3.7 mm, answers (below the boxes' new gap, 7.5 mm). Turned by 0.2 rad (14.7 mm): the
    kept gap says nothing and clearance answers again, the boxes' new gap (0.3 mm)."""
    scene = rbody.from_mjcf(BOXES, t_end=0.1)
    prepared = rbody.prepare(scene, dt=0.01, method="moreau")
    run = MoreauRun(prepared.model.constraints, prepared.params[0], "boxes")
    p, y = run.p, np.array(prepared.y0[0])
    assert pair_count(p) == 1
    neighbours = np.zeros(neighbours_size(p))
    reach, motion = np.empty(1), np.empty(1)
    scratch = np.empty(GEOMETRY_WORK)
    w = _workspace(p, y)
    pair_reaches(p, w, 0.0, reach, motion, neighbours)
    assert reach[0] == clearance(p, w, first_unit_at(p, pair_at(p, 0)), 0.0, scratch)[0]
    assert abs(reach[0] - 0.01) < 1e-12
    for angle, remembered in ((0.05, True), (0.2, False)):
        z = y.copy()
        z[10:14] = np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)  # box b (the second free body) about z
        w = _workspace(p, z)
        pair_reaches(p, w, 0.0, reach, motion, neighbours)
        fresh = clearance(p, w, first_unit_at(p, pair_at(p, 0)), 0.0, scratch)[0]
        drift = np.sqrt(0.05 ** 2 + 2 * 0.01 ** 2) * np.sqrt(8.0) * np.sin(angle / 2)  # r_b |Q - Q0|_F
        if remembered:
            assert reach[0] < fresh and abs(reach[0] - (0.01 - drift)) < 1e-12
        else:
            assert reach[0] == fresh
        assert 0.0 < reach[0] <= _least_gaps(p, w)[0] + 1e-12


def test_the_neighbour_list_is_built_again_when_a_geom_moves_beyond_the_skin(model):
    """Two bodies moved by 0.6 of the skin each (together more than it: they may have closed by that, though each
    alone is within it): the list is built again at the new configuration (its centres the new ones) and every pair
    is bounded as the full pass bounds it; a list of NaN centres is never read. (The pairs' tightened gaps are
    forgotten before each call: from them a pair's bound is not clearance's bits.)"""
    _scene, table, p, y0 = model
    rng = np.random.default_rng(3)
    y = _gathered(p, y0, rng, 0.35)
    neighbours = np.zeros(neighbours_size(p))
    reach, motion = np.empty(pair_count(p)), np.empty(pair_count(p))
    pair_reaches(p, _workspace(p, y), 0.0, reach, motion, neighbours)
    neighbours[_tight_at(p):] = 0.0
    z = y.copy()
    z[1:4] += (0.6 * NEIGHBOUR_SKIN, 0.0, 0.0)  # the ball (the first free body)
    z[8:11] -= (0.6 * NEIGHBOUR_SKIN, 0.0, 0.0)  # the rod
    w = _workspace(p, z)
    full_reach, full_motion = np.empty(pair_count(p)), np.empty(pair_count(p))
    pair_reaches(p, w, 0.0, full_reach, full_motion, np.empty(0))
    before = neighbours.copy()
    pair_reaches(p, w, 0.0, reach, motion, neighbours)
    assert not np.array_equal(neighbours, before)
    assert np.array_equal(reach, full_reach) and np.array_equal(motion, full_motion)
    ball = [int(p[geom_at(p, i) + G_TYPE]) for i in range(geom_count(p))].index(TYPE_CODES["sphere"])
    centre = slice(N_CENTRES + 3 * ball, N_CENTRES + 3 * ball + 3)
    neighbours[centre] = np.nan
    neighbours[_tight_at(p):] = 0.0
    pair_reaches(p, w, 0.0, reach, motion, neighbours)
    assert np.array_equal(reach, full_reach) and not np.isnan(neighbours[centre]).any()


def test_a_step_with_the_neighbour_list_is_the_step_without_it(model):
    """The bodies dropped from their places onto the floor and each other for 0.6 s: moreau_step given the whole
    kept memory (kept_size: the list read while they start and rest, built again as they fall) and given the kept
    geometry alone (no list: every pair bounded each call) give the same states, bit for bit."""
    _scene, table, p, y_start = model
    nq, rows = int(p[mb.H_NQ]), row_count(p)
    states = []
    arena = step_arena(p)
    for size in (kept_size(p), kept_geometry_size(nq, unit_count(p), pair_count(p))):
        y, P = y_start.copy(), np.zeros(rows)
        problem_rows, kept = np.zeros(rows + 1, dtype=np.int64), np.zeros(size)
        trajectory, lists = [], []
        for _ in range(60):
            status, _residual, _m = moreau_step(p, y, 0.01, P, EXACT_ROWS, PGS_SWEEPS, STEP_TOLERANCE, problem_rows,
                                                MODES["moreau"], kept, *arena)
            assert status == 0
            trajectory.append(y.copy())
            lists.append(kept[kept_geometry_size(nq, unit_count(p), pair_count(p)):].copy())
        states.append(np.array(trajectory))
        if size == kept_size(p):
            kept_again = sum(np.array_equal(a, b) for a, b in zip(lists, lists[1:]))
            assert 0 < kept_again < len(lists) - 1  # the list read over some steps, built again in others
    assert np.array_equal(states[0], states[1])
    assert not np.array_equal(states[0][0], states[0][-1])  # (they fell)


@pytest.mark.parametrize("beyond", [np.inf, 0.05])
def test_the_end_gaps_give_each_pairs_least_gap(model, beyond):
    """state_gaps's least (pairs,): a pair's least gap, the least of its candidates' rows where they were computed,
    the pair's bound where its spheres are apart (every row of the pair then at least that). With least, only the
    candidates' normal rows are written, and not those of a pair the broad phase finds apart by more than beyond
    (the step reads least there): the rest are left as they were."""
    _scene, table, p, y0 = model
    rng = np.random.default_rng(7)
    nq, nv, _n = dyn.sizes(p)
    y = y0.copy()
    for body in range(7):
        y[1 + 7 * body:4 + 7 * body] = rng.uniform(-0.3, 0.3, 3) + (0.0, 0.0, 0.3)
    g = np.full(row_count(p), np.nan)
    least = np.full(pair_count(p), np.nan)
    dyn.state_gaps(p, y, g, beyond, None, least)
    assert not np.isnan(least).any()  # every pair's written (+inf: a geom beside the height field's footprint)
    for i in range(pair_count(p)):
        _first, slots, row0, width = pair_span(p, pair_at(p, i))
        normals = g[row0:row0 + slots * width:width]
        if least[i] > beyond:  # apart by more than beyond (the bound or the candidates' least): nothing or all
            assert np.isnan(normals).all() or least[i] == normals.min()
        else:
            assert least[i] == normals.min()
        tangents = np.delete(g[row0:row0 + slots * width], np.arange(0, slots * width, width))
        assert np.isnan(tangents).all()
    assert (least <= 0.0).any() and (least > 0.0).any()
    if beyond < np.inf:
        normal_rows = [pair_span(p, pair_at(p, i))[2] for i in range(pair_count(p))]
        assert np.isnan(g[normal_rows]).any()  # a far pair's rows not written at all


@pytest.mark.parametrize("seed", range(4))
def test_a_pairs_bound_never_exceeds_its_candidates_gaps(model, seed):
    """Random configurations of the bodies gathered near the origin: clearance's bound (h = 0) is at most every
    candidate's gap, as the narrow phase computes them, and the gap it returns is that bound with the margin added
    back; and the geoms' axes (the separating axes, a geom's lowest
    point above the floor) part pairs without a box whose bounding spheres overlap, which the narrow phase would
    otherwise pose."""
    _scene, table, p, y0 = model
    rng = np.random.default_rng(10 + seed)
    nq, nv, _n = dyn.sizes(p)
    parted = 0
    for _draw in range(10):
        y = y0.copy()
        for body in range(7):
            at = 1 + 7 * body
            y[at:at + 3] = rng.uniform(-0.4, 0.4, 3) + (0.0, 0.0, 0.4)
            quat = rng.normal(size=4)
            y[at + 3:at + 7] = quat / np.linalg.norm(quat)
        w = _workspace(p, y)
        spheres = np.empty((geom_count(p), SPHERE_SIZE))
        geom_spheres(p, w, 0.0, spheres)
        work, scratch = np.empty(GEOMETRY_WORK), np.empty(GEOMETRY_WORK)
        normal, point = np.empty(3), np.empty(3)
        for i in range(pair_count(p)):
            u = first_unit_at(p, pair_at(p, i))
            bound, motion, gap = clearance(p, w, u, 0.0, scratch)
            assert motion == 0.0 and bound == gap - p[u + U_MARGIN], (i, bound, gap)  # (h = 0: the gap less the margin)
            count = pair_candidates(p, w, u, work)
            nearest = min(candidate(work, j, normal, point) for j in range(count))
            assert bound <= nearest + 1e-12, (i, bound, nearest)
            ga = int(p[pair_at(p, i) + P_GEOM_A])
            kind = int(p[geom_at(p, ga) + G_TYPE])
            gb = int(p[pair_at(p, i) + P_GEOM_B])
            kind_b = int(p[geom_at(p, gb) + G_TYPE])
            a, b = spheres[ga], spheres[gb]
            if kind == HFIELD:  # (its own bound)
                continue
            if kind == TYPE_CODES["plane"]:
                apart = a[S_NORMAL:S_NORMAL + 3] @ (b[:3] - a[:3]) - b[S_RADIUS]
            else:
                apart = np.linalg.norm(b[:3] - a[:3]) - a[S_RADIUS] - b[S_RADIUS]
            boxes = TYPE_CODES["box"] in (kind, kind_b) or kind_b == TYPE_CODES["mesh"]  # (faces' axes before)
            parted += apart - p[pair_at(p, i) + P_MARGIN] <= 0.0 < bound and not boxes
    assert parted > 0


# two shins side by side, 0.245 m apart between their axes, with margins of 0.01 m: their bounding spheres (0.12 m)
# are 5 mm apart, less than the pair's margin of 0.02 m
SHINS = """<mujoco>
  <worldbody>
    <body name="left" pos="0 0 1"><freejoint/><geom type="capsule" size="0.02 0.1" margin="0.01"/></body>
    <body name="right" pos="0.245 0 1"><freejoint/><geom type="capsule" size="0.02 0.1" margin="0.01"/></body>
  </worldbody>
</mujoco>"""


# two boxes 0.1 by 0.02 by 0.02 m side by side along y, 10 mm apart: their bounding spheres (0.0524 m) overlap
BOXES = """<mujoco>
  <worldbody>
    <body name="a" pos="0 0 1"><freejoint/><geom type="box" size="0.05 0.01 0.01"/></body>
    <body name="b" pos="0 0.03 1"><freejoint/><geom type="box" size="0.05 0.01 0.01"/></body>
  </worldbody>
</mujoco>"""


def test_spheres_within_the_margin_are_tightened_by_the_axes():
    """Bounding spheres apart by less than the pair's margin: the bound is tightened as where they overlap, to the
    capsules' distance less the margin, 0.245 - 0.04 - 0.02 m (the spheres alone gave 0.005 - 0.02 < 0, and the
    step posed the pair's candidates every step)."""
    scene = rbody.from_mjcf(SHINS, t_end=0.1)
    prepared = rbody.prepare(scene, dt=0.01, method="moreau")
    run = MoreauRun(prepared.model.constraints, prepared.params[0], "shins")
    p, y = run.p, np.array(prepared.y0[0])
    assert pair_count(p) == 1
    w = _workspace(p, y)
    spheres = np.empty((geom_count(p), SPHERE_SIZE))
    geom_spheres(p, w, 0.0, spheres)
    apart = np.linalg.norm(spheres[1, :3] - spheres[0, :3]) - spheres[0, S_RADIUS] - spheres[1, S_RADIUS]
    assert abs(apart - 0.005) < 1e-12 and p[pair_at(p, 0) + P_MARGIN] == 0.02
    reach, motion = np.empty(1), np.empty(1)
    pair_reaches(p, w, 0.0, reach, motion, np.empty(0))
    assert abs(reach[0] - (0.245 - 0.04 - 0.02)) < 1e-12
