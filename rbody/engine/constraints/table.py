"""The constraint table: a Layout's limits, dry friction and equalities as units of rows, packed after the tree.

A *unit* is one constraint with its rows (its components): a limit side, a ball's cone, one degree of freedom's
dry friction, a connect (3 rows), a weld (6) or a joint coupling (1). The units are packed as one float block
appended to the tree's params row (rbody.engine.multibody), so that every compiled kernel, and the NativeModel's
rhs that the integrators and the stability check call, reads (tree, constraints, mode) from one row:

    [ tree row | force elements (rbody.engine.elements; empty where the tree has none) | C_HEADER |
      unit records (UNIT_SIZE each) | mode (one per unit) ]

The force-element section's X_BLOCK records where the block starts, so that the constraint kernels and the force
elements' (actuators, tendons, gravity compensation, fluid: in the smooth forces of every constrained step) read
one row.

Unit kinds and their rows (g >= 0 feasible for unilateral rows; the force on the tree is J^T lambda):

    LOWER   qpos - lo >= 0                     J = +e_dof            (hinge, slide, roll)
    UPPER   hi - qpos >= 0                     J = -e_dof
    CONE    theta_max - theta >= 0             J = -u on the ball's 3 dofs, theta = 2 atan2(|v|, |w|), u the axis
    FRICTION  |lambda| <= frictionloss         J = e_dof (lambda: the dof's friction force)
    CONNECT p1 - p2 = 0 (3 rows, world)        J = J_p1 - J_p2
    WELD    p1 - p2 = 0, log(q1 qrel q2^-1) = 0 (6 rows, world)
    COUPLING (qpos1 - ref1) - P(qpos2 - ref2) = 0 (1 row)
    TENDON_LOWER  L - lower >= 0               J = +dL/dq (the tendon's Jacobian, rbody.engine.actuation)
    TENDON_UPPER  upper - L >= 0               J = -dL/dq
    TENDON_FRICTION  |lambda| <= frictionloss  J = dL/dq (lambda: the force along the tendon)
    TENDON_EQUALITY (L1 - L1_0) - P(L2 - L2_0) = 0 (1 row), L_0 the lengths at the reference pose (MuJoCo's)

    CONTACT  the signed distance g >= 0 of a candidate contact of two geoms (rbody.engine.contacts.geometry), 3 rows:
             the normal (J = n . (J_b - J_a) at the contact point, lambda >= 0) and two tangents whose forces stay
             within the circular cone |lambda_t| <= mu lambda_n (Coulomb); CONTACT1 the normal row alone (condim 1).
             condim 4 adds a spin row (J = n . (W_b - W_a), the relative angular velocity about the normal,
             |lambda_s| <= mu_s lambda_n), condim 6 two rolling rows after it (t1, t2 . (W_b - W_a), in the disc
             |lambda_r| <= mu_r lambda_n): 4 or 6 rows (rbody.engine.constraints.cone)

The tendon kinds are the joint kinds with a tendon's length in place of a coordinate (rows: tendon_rows.py), and
every scheme treats them as it treats their joint twins (UNILATERAL, FRICTION_KINDS, EQUALITY_KINDS below).

mode, per unit: limits, cones and contacts 1 active (held as an equality, lambda >= 0), 0 inactive; friction 0 sticking,
+1 / -1 sliding with the dof's velocity of that sign (force -frictionloss sign); equalities 1 (always active); a
contact with friction in the event-driven scheme 1 held and sticking (its three rows held), 2 held and sliding (its
normal row held, its friction -mu lambda_n along the slip: rbody.engine.constraints.sliding).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rbody.engine.mujoco_steps import MUJOCO_METHODS
from rbody.engine.schema import FLOAT, INT, Record
from rbody.layout import JOINTS, WORLD, Layout

(LOWER, UPPER, CONE, FRICTION, CONNECT, WELD, COUPLING, CONTACT, CONTACT1, TENDON_LOWER, TENDON_UPPER,
 TENDON_FRICTION, TENDON_EQUALITY) = range(13)
KIND_ROWS = {LOWER: 1, UPPER: 1, CONE: 1, FRICTION: 1, CONNECT: 3, WELD: 6, COUPLING: 1, CONTACT: 3, CONTACT1: 1,
             TENDON_LOWER: 1, TENDON_UPPER: 1, TENDON_FRICTION: 1, TENDON_EQUALITY: 1}
KIND_NAMES = {LOWER: "limit", UPPER: "limit", CONE: "limit", FRICTION: "friction", CONNECT: "connect",
              WELD: "weld", COUPLING: "joint", CONTACT: "contact", CONTACT1: "contact", TENDON_LOWER: "tendon limit",
              TENDON_UPPER: "tendon limit", TENDON_FRICTION: "tendon friction", TENDON_EQUALITY: "tendon"}
CONTACT_KINDS = (CONTACT, CONTACT1)
UNILATERAL = (LOWER, UPPER, CONE, TENDON_LOWER, TENDON_UPPER)
LOWER_KINDS = (LOWER, TENDON_LOWER)        # a stop below: the row's J is +dx/dq
STOP_KINDS = (LOWER, UPPER, TENDON_LOWER, TENDON_UPPER)  # one-row stops (a cone aside)
FRICTION_KINDS = (FRICTION, TENDON_FRICTION)
EQUALITY_KINDS = (CONNECT, WELD, COUPLING, TENDON_EQUALITY)
TENDON_KINDS = (TENDON_LOWER, TENDON_UPPER, TENDON_FRICTION, TENDON_EQUALITY)

# The constraint block appended to the tree's row (rbody.engine.schema): a header of absolute offsets, one
# record per unit, then the mode of every unit.
CONSTRAINT_HEADER = Record("constraint header", [
    ("units", 1, INT, "constraint units"),
    ("rows", 1, INT, "constraint rows"),
    ("unit", 1, INT, "where the unit records start (absolute)"),
    ("mode", 1, INT, "where the modes start (absolute)"),
    ("contact0", 1, INT, "the first contact unit (the contacts follow every other unit; units: none)"),
    ("pairs", 1, INT, "contact pairs (two geoms each, their candidates consecutive units)"),
    ("pair", 1, INT, "where the pair records start (absolute)"),
    ("geoms", 1, INT, "geoms in a contact pair"),
    ("geom", 1, INT, "where the geom records start (absolute)"),
])
C_UNITS, C_ROWS, C_UNIT, C_MODE, C_CONTACT0, C_PAIRS, C_PAIR, C_GEOMS, C_GEOM = CONSTRAINT_HEADER.offsets()
C_HEADER = CONSTRAINT_HEADER.size
UNIT = Record("constraint unit", [
    ("kind", 1, INT, "LOWER, UPPER, CONE, FRICTION, CONNECT, WELD, COUPLING, CONTACT, CONTACT1, TENDON_LOWER, "
                     "TENDON_UPPER, TENDON_FRICTION or TENDON_EQUALITY"),
    ("rows", 1, INT, "its rows"),
    ("row0", 1, INT, "its first row among all rows"),
    ("dof", 1, INT, "its degree of freedom (limits, friction, joint coupling); a contact's candidate slot"),
    ("qadr", 1, INT, "its qpos address"),
    ("bound", 1, FLOAT, "lower or upper limit, a cone's largest angle [rad | m], frictionloss [N m | N], or a "
                                "contact's friction coefficient mu; a tendon's limit or frictionloss"),
    ("restitution", 1, FLOAT, "Newton's coefficient at an impact"),
    ("body1", 1, INT, "first body (-1: the world)"),
    ("body2", 1, INT, "second body (-1: the world)"),
    ("anchor1", 3, FLOAT, "anchor in body1's frame [m]"),
    ("anchor2", 3, FLOAT, "anchor in body2's frame [m]"),
    ("relquat", 4, FLOAT, "a weld's relative orientation"),
    ("dof2", 1, INT, "a coupling's second dof (-1: none)"),
    ("qadr2", 1, INT, "its qpos address (-1: none)"),
    ("ref1", 1, FLOAT, "reference coordinate of the first joint (a tendon equality: tendon1's length at the "
                       "reference pose)"),
    ("ref2", 1, FLOAT, "of the second"),
    ("polycoef", 5, FLOAT, "a joint or tendon coupling's polynomial"),
    ("gtype_a", 1, INT, "a contact's geom a: its type (MuJoCo's code)"),
    ("gpos_a", 3, FLOAT, "its position in its body's frame [m]"),
    ("gmat_a", 9, FLOAT, "its axes in its body's frame (row-major)"),
    ("gsize_a", 3, FLOAT, "its size (MuJoCo's) [m]"),
    ("gtype_b", 1, INT, "geom b: its type"),
    ("gpos_b", 3, FLOAT, "its position [m]"),
    ("gmat_b", 9, FLOAT, "its axes"),
    ("gsize_b", 3, FLOAT, "its size [m]"),
    ("slip", 3, FLOAT, "a contact sliding in the event-driven scheme: its slip direction when its mode began "
                       "(world, unit)"),
    ("tendon", 1, INT, "a tendon unit's tendon (its index among the tendons; -1: none)"),
    ("tendon2", 1, INT, "a tendon equality's second tendon (-1: none)"),
    ("spin", 1, FLOAT, "a contact's torsional friction coefficient [m] (condim 4 and 6)"),
    ("roll", 1, FLOAT, "a contact's rolling friction coefficient [m] (condim 6)"),
    ("margin", 1, FLOAT, "a contact's margin [m]: its gap is the geoms' distance less this"),
    ("hull_a", 1, INT, "a contact's geom a, a mesh: where its convex hull's record starts (absolute; -1: not a mesh)"),
    ("hull_b", 1, INT, "geom b's (-1: not a mesh)"),
    ("window", 3, FLOAT, "a height field's contact (geom a the field, hull_a its record): the window's cells along x "
                         "and y and geom b's bounding radius [m] (rbody.engine.contacts.terrain)"),
])
(U_KIND, U_ROWS, U_ROW0, U_DOF, U_QADR, U_BOUND, U_RESTITUTION, U_BODY1, U_BODY2, U_A1, U_A2, U_QUAT, U_DOF2,
 U_QADR2, U_REF1, U_REF2, U_POLY) = UNIT.offsets(
    "kind", "rows", "row0", "dof", "qadr", "bound", "restitution", "body1", "body2", "anchor1", "anchor2", "relquat",
    "dof2", "qadr2", "ref1", "ref2", "polycoef")
# Contacts (rbody.engine.contacts.rows) reuse U_DOF as the candidate's slot, U_BOUND as the friction coefficient mu,
# U_RESTITUTION, U_BODY1/U_BODY2 as the bodies of geoms a and b (-1: the world), and hold per geom its type code,
# its pose in its body's frame and its size:
U_GTYPE_A, U_GPOS_A, U_GMAT_A, U_GSIZE_A = UNIT.offsets("gtype_a", "gpos_a", "gmat_a", "gsize_a")
U_GTYPE_B, U_GPOS_B, U_GMAT_B, U_GSIZE_B = UNIT.offsets("gtype_b", "gpos_b", "gmat_b", "gsize_b")
(U_SLIP,) = UNIT.offsets("slip")
U_TENDON, U_TENDON2 = UNIT.offsets("tendon", "tendon2")
U_SPIN, U_ROLL, U_MARGIN = UNIT.offsets("spin", "roll", "margin")
U_HULL_A, U_HULL_B = UNIT.offsets("hull_a", "hull_b")
(U_WINDOW,) = UNIT.offsets("window")
UNIT_SIZE = UNIT.size
# The broad phase's records (rbody.engine.contacts.broadphase): a step tests each pair of geoms once, from each geom's
# bounding sphere found once, and reads its candidates' unit records only when the pair is near.
PAIR = Record("contact pair", [
    ("unit", 1, INT, "its first candidate's unit (the others follow it)"),
    ("slots", 1, INT, "its candidates (units)"),
    ("row", 1, INT, "its first candidate's first row (each candidate's rows follow the last's)"),
    ("width", 1, INT, "rows per candidate (its condim; 1 for condim 1 or no friction)"),
    ("geom_a", 1, INT, "geom a's record (its index among the geoms)"),
    ("geom_b", 1, INT, "geom b's"),
    ("margin", 1, FLOAT, "the pair's margin [m]"),
])
P_UNIT, P_SLOTS, P_ROW, P_WIDTH, P_GEOM_A, P_GEOM_B, P_MARGIN = PAIR.offsets()
PAIR_SIZE = PAIR.size
GEOM = Record("contact geom", [
    ("body", 1, INT, "its body (-1: the world)"),
    ("type", 1, INT, "its type (MuJoCo's code)"),
    ("pose", 1, INT, "where its position (3), axes (9) and size (3) start in a unit record that holds it "
                     "(absolute: U_GPOS_A or U_GPOS_B of one of its pairs' first units)"),
])
G_BODY, G_TYPE, G_POSE = GEOM.offsets()
GEOM_SIZE = GEOM.size


@dataclass(frozen=True)
class Unit:
    """One constraint as users see it: kind ("limit", "friction", "connect", "weld", "joint", "contact", "tendon
    limit", "tendon friction", "tendon"), name (the joint's, the tendon's or the equality's, a limit's side as
    "<joint>.lower" / ".upper" (a tendon's likewise), a multi-dof joint's friction as "<joint>[k]"), its rows and
    where they start among all rows."""

    code: int
    kind: str
    name: str
    rows: int
    row0: int


@dataclass(frozen=True)
class ConstraintTable:
    """The compiled constraints of a tree (module docstring).

    units: the Unit of every record, in order; block (C_HEADER + UNIT_SIZE units + units + hulls,) the floats
    appended to the tree's row and its force-element section (the header, the unit records, the modes, then the
    packed convex hull of every mesh geom in a contact, rbody.engine.contacts.convex.pack_hull) (offsets absolute: valid after a row of length `offset`); mode0
    (units,) the mode every run starts from before its first consistent mode is found; methods: the methods a
    constrained run takes; tree_size the tree's row length, section the force-element section a tree row without
    one is given (row())."""

    units: tuple[Unit, ...]
    block: np.ndarray
    offset: int
    mode0: np.ndarray
    methods: tuple[str, ...] = ("rk4", "moreau") + MUJOCO_METHODS
    equalities: tuple = ()  # every equality, each made explicit (a connect's anchor2, a weld's relpose)
    tree_size: int = 0
    section: np.ndarray | None = None
    events_refused: str = ""  # why the event-driven scheme (rk4) does not run these constraints, if it does not

    @cached_property
    def rows(self) -> int:
        """The rows of every unit (found once: a quadruped's file has 8,152 units)."""
        return sum(unit.rows for unit in self.units)

    def labels(self) -> list[tuple[str, str, int]]:
        """(kind, name, component) of every row, in row order: the columns of the constraint_force observable (a
        new list of the labels found once: a run's meta gives them, and a robot's file has tens of thousands)."""
        return list(self._labels)

    @cached_property
    def _labels(self) -> tuple[tuple[str, str, int], ...]:
        return tuple((unit.kind, unit.name, k) for unit in self.units for k in range(unit.rows))

    def row(self, params: np.ndarray) -> np.ndarray:
        """The tree's params row (p,), with its force-element section or without one (the empty section is then
        added), with the block appended and its offset recorded: the row every constraint kernel reads."""
        from rbody.engine.elements import X_BLOCK

        params = np.asarray(params, dtype=np.float64)
        if params.size == self.tree_size and self.section is not None:
            params = np.concatenate([params, self.section])
        if params.size != self.offset:
            raise ValueError(f"params of {params.size} numbers: expected the tree's row ({self.tree_size}) or the tree's "
                             f"row with its force elements ({self.offset})")
        out = np.concatenate([params, self.block])
        out[self.tree_size + X_BLOCK] = self.offset
        return out

    @property
    def contact0(self) -> int:
        """The first contact unit (every unit before it a limit, friction or an equality); the unit count if none: the
        block header's, which build_table wrote."""
        return int(self.block[C_CONTACT0])

    def without_contacts(self, row: np.ndarray) -> np.ndarray:
        """A copy of a constraint row (row(), or a batch of them (B, p)) whose header holds the units before the
        contacts only: no contact unit, row or pair. In a mode where every contact is apart (mode0: every run's
        start) a kernel reads the same motion from it as from `row`, without passing over the contacts'
        candidates (rows by the tens of thousands in a model of many bodies, each evaluation's J one row of nv
        numbers apiece: the stability check's cost)."""
        out = np.array(row, dtype=np.float64)
        rows = int(self.first_rows[self.contact0]) if self.contact0 < len(self.units) else self.rows
        header = self.offset + np.array([C_UNITS, C_ROWS, C_PAIRS, C_GEOMS])
        out[..., header] = self.contact0, rows, 0, 0
        return out

    def mode_slice(self) -> slice:
        start = self.offset + C_HEADER + UNIT_SIZE * len(self.units)
        return slice(start, start + len(self.units))

    @cached_property
    def codes(self) -> np.ndarray:
        """(units,) every unit's kind code, read-only (kept: a run reads it once per batch element)."""
        return _read_only(np.array([unit.code for unit in self.units], dtype=np.int64))

    @cached_property
    def first_rows(self) -> np.ndarray:
        """(units,) the row each unit's rows start at, read-only."""
        return _read_only(np.array([unit.row0 for unit in self.units], dtype=np.int64))

    @cached_property
    def unit_rows(self) -> np.ndarray:
        """(units,) each unit's row count (a contact's condim), read-only."""
        return _read_only(np.array([unit.rows for unit in self.units], dtype=np.int64))

    @cached_property
    def unit_of_first_row(self) -> np.ndarray:
        """(rows,) the unit whose first row each row is, -1 for a unit's later rows, read-only."""
        first_of = np.full(self.rows, -1, dtype=np.int64)
        first_of[self.first_rows] = np.arange(len(self.units))
        return _read_only(first_of)

    def names(self, which: np.ndarray) -> list[str]:
        """The names of units `which` (indices), in order (a run's meta lists its contacts': thousands)."""
        return [self._names[k] for k in np.asarray(which, dtype=np.int64).tolist()]

    @cached_property
    def _names(self) -> tuple[str, ...]:
        return tuple(unit.name for unit in self.units)

    def units_of_kinds(self, kinds: tuple[int, ...]) -> np.ndarray:
        """(k,) int64, read-only: the indices of the units whose code is one of `kinds`, ascending, kept per kinds
        (a run's observables and meta read them on every call)."""
        kept = self.__dict__.setdefault("_units_of_kinds", {})
        found = kept.get(kinds)
        if found is None:
            found = kept[kinds] = _read_only(np.flatnonzero(self.of_kinds(kinds)))
        return found

    def of_kinds(self, kinds: tuple[int, ...]) -> np.ndarray:
        """(units,) bool, read-only: True for the units whose code is one of `kinds` (e.g. FRICTION_KINDS), kept per
        kinds."""
        kept = self.__dict__.setdefault("_of_kinds", {})  # frozen: no setattr, but __dict__ is writable
        mask = kept.get(kinds)
        if mask is None:
            mask = kept[kinds] = _read_only(np.isin(self.codes, kinds))
        return mask


def _read_only(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def _quat_conjugate(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _quat_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def reference_qpos(layout: Layout, multibody) -> np.ndarray:
    """(nq,) MuJoCo's qpos0 of the layout: every scalar joint at its ref, balls at identity, free bodies at their
    pos/quat (the configuration in which equalities are completed)."""
    bodies = {body.name: body for body in layout.bodies}
    joints = {joint.name: joint for joint in layout.joints}
    q = np.zeros(multibody.nq)
    for name, kind, address in zip(multibody.joint_names, multibody.arrays.joint_kinds, multibody.arrays.qposadr):
        joint = joints[name]
        if JOINTS[kind].scalar:
            q[address] = joint.ref
        elif kind == "ball":
            q[address:address + 4] = (1.0, 0.0, 0.0, 0.0)
        else:
            body = bodies[joint.body]
            quat = np.asarray(body.quat, dtype=float)
            q[address:address + 3] = body.pos
            q[address + 3:address + 7] = quat / np.linalg.norm(quat)
    return q


def _frames_at(layout: Layout, multibody, q: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """body name -> (origin (3,), quat (4,)) of every body frame in the world at qpos q, and the world's."""
    com, quat = multibody.body_poses(q)
    from rbody.motion import quat_to_matrix

    inertia = {body.name: body.inertia for body in layout.bodies}
    frames = {WORLD: (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))}
    for i, name in enumerate(multibody.body_names):
        frames[name] = (com[i] - quat_to_matrix(quat[i]) @ np.asarray(inertia[name].com), quat[i].copy())
    return frames


def build_table(layout: Layout, multibody) -> ConstraintTable | None:
    """The ConstraintTable of a Layout's joints' and tendons' ranges and frictionloss and its active equalities
    (None when it has none), for the tree compiled in `multibody` (rbody.Multibody of the same layout, with its
    tendons). Raises ValueError naming the equality for one whose bodies, joints or tendons are not in the
    layout."""
    arrays = multibody.arrays
    body_index = {name: i for i, name in enumerate(multibody.body_names)}
    body_index[WORLD] = -1
    joint_index = {name: j for j, name in enumerate(multibody.joint_names)}
    joints = {joint.name: joint for joint in layout.joints}
    records: list[np.ndarray] = []
    units: list[Unit] = []
    rows = 0
    hull_of: list[tuple[int, int, tuple]] = []  # (record, field, (shape name, packed hull)) of mesh geoms

    blank = np.zeros(UNIT_SIZE)  # every record starts as a copy of it: no body, second dof, tendon or hull
    blank[[U_BODY1, U_BODY2, U_DOF2, U_QADR2, U_TENDON, U_TENDON2, U_HULL_A, U_HULL_B]] = -1

    def add(code: int, name: str, count: int | None = None, **fields) -> None:
        nonlocal rows
        count = KIND_ROWS[code] if count is None else count  # a contact's rows: its condim
        record = blank.copy()
        record[U_KIND], record[U_ROWS], record[U_ROW0] = code, count, rows
        for key, value in fields.items():
            if key in ("HULL_A", "HULL_B"):  # a mesh's hull (rbody.engine.contacts.convex.pack_hull) or a height
                # field's record (rbody.engine.contacts.terrain.pack_field): placed below
                hull_of.append((len(records), globals()["U_" + key], value))
                continue
            start = globals()[key]
            if isinstance(value, (int, float)):  # (most fields: one number, set without an array's round trip)
                record[start] = value
                continue
            values = np.asarray(value, dtype=float).reshape(-1)
            record[start:start + values.size] = values
        records.append(record)
        units.append(Unit(code, KIND_NAMES[code], name, count, rows))
        rows += count

    for name, kind, qa, da in zip(multibody.joint_names, arrays.joint_kinds, arrays.qposadr, arrays.dofadr):
        joint = joints[name]
        if joint.range is not None:
            low, high = joint.range
            if kind == "ball":
                add(CONE, name, U_DOF=da, U_QADR=qa, U_BOUND=high, U_RESTITUTION=joint.restitution)
            else:
                add(LOWER, f"{name}.lower", U_DOF=da, U_QADR=qa, U_BOUND=low, U_RESTITUTION=joint.restitution)
                add(UPPER, f"{name}.upper", U_DOF=da, U_QADR=qa, U_BOUND=high, U_RESTITUTION=joint.restitution)
    for name, kind, qa, da in zip(multibody.joint_names, arrays.joint_kinds, arrays.qposadr, arrays.dofadr):
        joint = joints[name]
        if joint.frictionloss > 0:
            count = JOINTS[kind].nv
            for k in range(count):
                add(FRICTION, name if count == 1 else f"{name}[{k}]", U_DOF=da + k, U_BOUND=joint.frictionloss)

    tendon_index = {tendon.name: t for t, tendon in enumerate(layout.tendons)}
    for t, tendon in enumerate(layout.tendons):
        if tendon.range is not None:
            low, high = tendon.range
            add(TENDON_LOWER, f"{tendon.name}.lower", U_TENDON=t, U_BOUND=low, U_RESTITUTION=tendon.restitution)
            add(TENDON_UPPER, f"{tendon.name}.upper", U_TENDON=t, U_BOUND=high, U_RESTITUTION=tendon.restitution)
    for t, tendon in enumerate(layout.tendons):
        if tendon.frictionloss > 0:
            add(TENDON_FRICTION, tendon.name, U_TENDON=t, U_BOUND=tendon.frictionloss)
    lengths0 = None

    names = [e.name for e in layout.equalities]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"two equalities are called {repeated[0]!r}: equality names must be unique")
    frames = None
    resolved = []
    for equality in layout.equalities:  # inactive ones are checked and made explicit too (exported as declared)
        what = f"equality {equality.name!r}"
        if equality.kind == "tendon":
            indices = []
            for field_name in ("tendon1", "tendon2"):
                tendon_name = getattr(equality, field_name)
                if tendon_name is not None and tendon_name not in tendon_index:
                    raise ValueError(f"{what}: {field_name}={tendon_name!r} is not a tendon of the layout (tendons: "
                                     f"{sorted(tendon_index)})")
                indices.append(-1 if tendon_name is None else tendon_index[tendon_name])
            if lengths0 is None:  # MuJoCo's tendon_length0: the lengths at qpos0
                q0 = reference_qpos(layout, multibody)
                lengths0 = multibody.tendons(q0, np.zeros(multibody.nv))["length"]
            t1, t2 = indices
            fields = dict(U_TENDON=t1, U_REF1=lengths0[t1], U_POLY=equality.polycoef)
            if t2 >= 0:
                fields.update(U_TENDON2=t2, U_REF2=lengths0[t2])
            if equality.active:
                add(TENDON_EQUALITY, equality.name, **fields)
            resolved.append(equality)
            continue
        if equality.kind == "joint":
            indices = []
            for field_name in ("joint1", "joint2"):
                joint_name = getattr(equality, field_name)
                if joint_name is None:
                    indices.append(-1)
                    continue
                if joint_name not in joint_index:
                    raise ValueError(f"{what}: {field_name}={joint_name!r} is not a joint of the layout")
                if not JOINTS[joints[joint_name].kind].scalar:
                    raise ValueError(f"{what}: {field_name}={joint_name!r} is a {joints[joint_name].kind} joint: a "
                                     "joint equality couples hinge, slide and roll joints")
                indices.append(joint_index[joint_name])
            j1, j2 = indices
            fields = dict(U_DOF=arrays.dofadr[j1], U_QADR=arrays.qposadr[j1], U_REF1=joints[equality.joint1].ref,
                          U_POLY=equality.polycoef)
            if j2 >= 0:
                fields.update(U_DOF2=arrays.dofadr[j2], U_QADR2=arrays.qposadr[j2], U_REF2=joints[equality.joint2].ref)
            if equality.active:
                add(COUPLING, equality.name, **fields)
            resolved.append(equality)
            continue
        for field_name in ("body1", "body2"):
            body = getattr(equality, field_name)
            if body not in body_index:
                raise ValueError(f"{what}: {field_name}={body!r} is not a body of the layout (nor {WORLD!r})")
        if frames is None:
            frames = _frames_at(layout, multibody, reference_qpos(layout, multibody))
        (x1, q1), (x2, q2) = frames[equality.body1], frames[equality.body2]
        from rbody.motion import quat_to_matrix

        R1, R2 = quat_to_matrix(q1), quat_to_matrix(q2)
        b1, b2 = body_index[equality.body1], body_index[equality.body2]
        if equality.kind == "connect":
            anchor2 = (np.asarray(equality.anchor2) if equality.anchor2 is not None
                       else R2.T @ (x1 + R1 @ np.asarray(equality.anchor) - x2))
            if equality.active:
                add(CONNECT, equality.name, U_BODY1=b1, U_BODY2=b2, U_A1=equality.anchor, U_A2=anchor2)
            resolved.append(dataclasses.replace(equality, anchor2=tuple(np.asarray(anchor2, dtype=float).tolist())))
        else:  # weld: body1's point relpos on body2's anchor, q1 relquat = q2
            anchor = np.asarray(equality.anchor)
            if equality.relpose is not None:
                relpos, relquat = np.asarray(equality.relpose[:3]), np.asarray(equality.relpose[3:])
            else:
                relpos = R1.T @ (x2 + R2 @ anchor - x1)
                relquat = _quat_product(_quat_conjugate(q1), q2)
            relquat = relquat / np.linalg.norm(relquat)
            if equality.active:
                add(WELD, equality.name, U_BODY1=b1, U_BODY2=b2, U_A1=relpos, U_A2=anchor, U_QUAT=relquat)
            resolved.append(dataclasses.replace(equality, relpose=tuple(np.concatenate([relpos, relquat]).tolist())))
    from rbody.engine.contacts.geometry import TIME_STEPPED
    from rbody.engine.contacts.terrain import HFIELD

    time_stepped = []  # contacts the event-driven scheme does not run (geometry.TIME_STEPPED)
    spinning = []  # and those with torsional or rolling friction (condim 4, 6)
    contact0 = len(units)
    pairs: list[tuple[int, int, int, int, str, str, float]] = []  # (unit, slots, row, width, shape a, shape b, margin)
    shapes = _ContactShapes(layout)
    for contact in layout.contacts:
        with_friction = contact.condim > 1 and contact.friction + contact.torsion + contact.rolling > 0
        candidates, (name_a, name_b) = _contact_units(contact, body_index, shapes)
        pairs.append((len(units), len(candidates), rows, contact.condim if with_friction else 1, name_a, name_b,
                      contact.margin))
        for record_fields, name in candidates:
            if with_friction:
                add(CONTACT, name, count=contact.condim, **record_fields)
            else:
                add(CONTACT1, name, **record_fields)
        if (record_fields["U_GTYPE_A"], record_fields["U_GTYPE_B"]) in TIME_STEPPED or record_fields["U_GTYPE_A"] == HFIELD:
            time_stepped.append(f"{contact.shape_a!r}/{contact.shape_b!r}")
        if with_friction and contact.condim > 3:
            spinning.append(f"{contact.shape_a!r}/{contact.shape_b!r}")
    if not units:
        return None
    from rbody.engine.elements import build_elements

    tree_size = int(multibody.arrays.row.size)
    params = np.asarray(multibody.params, dtype=np.float64)
    section = (params[tree_size:].copy() if params.size > tree_size
               else build_elements(layout, multibody.arrays, tree_size).row)
    section.setflags(write=False)
    offset = tree_size + int(section.size)
    count = len(units)
    # the convex hulls of mesh geoms after the modes, one record per shape, each unit pointing at its geoms'
    hulls, placed, end = [], {}, C_HEADER + UNIT_SIZE * count + count
    for index, field_at, (shape_name, packed) in hull_of:
        if shape_name not in placed:
            placed[shape_name] = end
            hulls.append(packed)
            end += packed.size
        records[index][field_at] = offset + placed[shape_name]
    pair_records, geom_records = _broad_phase_records(pairs, records, offset)
    geom_count = geom_records.size // GEOM_SIZE
    block = np.zeros(end + pair_records.size + geom_records.size)
    block[[C_UNITS, C_ROWS, C_UNIT, C_MODE]] = count, rows, offset + C_HEADER, offset + C_HEADER + UNIT_SIZE * count
    block[[C_CONTACT0, C_PAIRS, C_PAIR, C_GEOMS, C_GEOM]] = (contact0, len(pairs), offset + end, geom_count,
                                                             offset + end + pair_records.size)
    block[C_HEADER:C_HEADER + UNIT_SIZE * count] = np.concatenate(records)
    if hulls:
        block[C_HEADER + UNIT_SIZE * count + count:end] = np.concatenate(hulls)
    block[end:end + pair_records.size] = pair_records
    block[end + pair_records.size:] = geom_records
    mode0 = np.array([1.0 if unit.code in EQUALITY_KINDS else 0.0 for unit in units])
    block[C_HEADER + UNIT_SIZE * count:C_HEADER + UNIT_SIZE * count + count] = mode0
    CONSTRAINT_HEADER.check(block, 0, 1)
    UNIT.check(block, C_HEADER, count)
    PAIR.check(block, end, len(pairs))
    GEOM.check(block, end + pair_records.size, geom_count)
    block.setflags(write=False)
    mode0.setflags(write=False)
    # contacts: time-stepping by default (persistent contacts: stacks, feet, grasps), event-driven on request;
    # MuJoCo's integrators as the time-stepping's free motion (a file's own scheme, at its own step)
    methods = ("moreau", "rk4") if any(unit.code in CONTACT_KINDS for unit in units) else ("rk4", "moreau")
    events_refused = ""
    if time_stepped:
        more = f" (and {len(time_stepped) - 1} more)" if len(time_stepped) > 1 else ""
        methods = tuple(name for name in methods if name != "rk4")
        events_refused = (f"the event-driven scheme (rk4) holds a contact's candidate from event to event with "
                          f"closed-form curvature terms, which the contact {time_stepped[0]}{more} does not have (a "
                          "capsule against a box, a cylinder, an ellipsoid, a mesh or a height field: "
                          "rbody.engine.contacts.geometry.TIME_STEPPED): the "
                          "time-stepping runs it")
    elif spinning:
        more = f" (and {len(spinning) - 1} more)" if len(spinning) > 1 else ""
        methods = tuple(name for name in methods if name != "rk4")
        events_refused = (f"the event-driven scheme (rk4) models sliding friction only; the contact {spinning[0]}"
                          f"{more} has torsional or rolling friction (condim 4 or 6): the time-stepping runs it")
    methods += MUJOCO_METHODS
    return ConstraintTable(units=tuple(units), block=block, offset=offset, mode0=mode0, equalities=tuple(resolved),
                           methods=methods, tree_size=tree_size, section=section, events_refused=events_refused)


_HULLS: dict = {}  # Shape.vertices -> its packed hull (a model's meshes are packed once per process)


def _packed_hull(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre (3,), half (3,), hull): a mesh shape's vertices' bounding box (centre and half sizes in the shape's
    frame [m]) and the packed convex hull of the vertices about that centre (rbody.engine.contacts.convex.pack_hull:
    the broad phase's sphere and box about the geom's origin are then tight), cached. Raises ValueError naming the
    shape for vertices with no volume."""
    from rbody.engine.contacts.convex import pack_hull

    key = shape.vertices
    if key not in _HULLS:
        points = np.asarray(key, dtype=np.float64)
        low, high = points.min(axis=0), points.max(axis=0)
        centre = 0.5 * (low + high)
        try:
            _HULLS[key] = (centre, 0.5 * (high - low), pack_hull(points - centre))
        except ValueError as error:
            raise ValueError(f"mesh shape {shape.name!r}: {error}") from None
        if len(_HULLS) > 256:  # a bound on what a long session keeps
            _HULLS.pop(next(iter(_HULLS)))
    return _HULLS[key]


def _broad_phase_records(pairs: list, records: list[np.ndarray], offset: int) -> tuple[np.ndarray, np.ndarray]:
    """(pair records (PAIR_SIZE each), geom records (GEOM_SIZE each)) of build_table's contact pairs (first unit,
    slots, first row, rows per candidate, shape a, shape b, margin): each geom once, found in the first pair that
    names it (its pose read from that pair's first unit record, placed at offset + C_HEADER + UNIT_SIZE unit)."""
    geom_index: dict[str, int] = {}
    geoms, out = [], []
    for unit, slots, row, width, name_a, name_b, margin in pairs:
        record = records[unit]
        for name, body_at, type_at, pos_at in ((name_a, U_BODY1, U_GTYPE_A, U_GPOS_A),
                                              (name_b, U_BODY2, U_GTYPE_B, U_GPOS_B)):
            if name not in geom_index:
                geom_index[name] = len(geoms)
                geoms.append((record[body_at], record[type_at], offset + C_HEADER + UNIT_SIZE * unit + pos_at))
        out.append((unit, slots, row, width, geom_index[name_a], geom_index[name_b], margin))
    pair_records = np.array(out, dtype=np.float64).reshape(-1)
    geom_records = np.array(geoms, dtype=np.float64).reshape(-1)
    return pair_records, geom_records


class _ContactShapes:
    """The layout's shapes by name, each with its body, and each shape's record fields (type code, pose, size,
    packed hull or field) formed once: a model of many bodies names every shape in a pair with each other one."""

    def __init__(self, layout: Layout):
        self.where = {shape.name: (WORLD, shape) for shape in layout.fixed}
        for body in layout.bodies:
            for shape in body.shapes:
                self.where[shape.name] = (body.name, shape)
        self._fields: dict[str, dict] = {}

    def fields(self, shape, suffix: str) -> dict:
        """The unit record's fields of `shape` as geom `suffix` ("A" or "B") of a pair."""
        if shape.name not in self._fields:
            self._fields[shape.name] = _shape_fields(shape)
        return {f"{key}_{suffix}": value for key, value in self._fields[shape.name].items()}


def _shape_fields(shape) -> dict:
    """A contact shape's record fields (without the geom's suffix): U_GTYPE, U_GPOS, U_GMAT, U_GSIZE, and HULL for a
    mesh's packed hull or a height field's record."""
    from rbody.engine.contacts.geometry import TYPE_CODES
    from rbody.engine.contacts.terrain import HFIELD, pack_field
    from rbody.motion import quat_to_matrix

    size = np.zeros(3)
    size[:len(shape.size)] = shape.size[:3]
    axes = quat_to_matrix(np.asarray(shape.quat))
    pos = np.asarray(shape.pos, dtype=float)
    fields = {}
    if shape.kind == "mesh":  # its frame moved to the centre of its bounding box, its size that box's half sizes
        centre, half, packed = _packed_hull(shape)
        pos = pos + axes @ centre
        size[:] = half
        fields["HULL"] = (shape.name, packed)
    if shape.kind == "hfield":  # its record (elevations and sizes) placed once, like a mesh's hull
        fields["HULL"] = (shape.name, pack_field(np.asarray(shape.heights), shape.size))
    fields.update(U_GTYPE=HFIELD if shape.kind == "hfield" else TYPE_CODES[shape.kind], U_GPOS=pos,
                  U_GMAT=axes.reshape(-1), U_GSIZE=size)
    return fields


def _contact_units(contact, body_index: dict[str, int],
                   shapes: _ContactShapes) -> tuple[list[tuple[dict, str]], tuple[str, str]]:
    """(the unit records (fields for build_table's add) and names of a Contact's candidates, (geom a's shape name,
    geom b's)): one unit per slot of its pair of geoms (rbody.engine.contacts.geometry.SLOTS), the geoms in MuJoCo's
    order (type codes ascending).
    Raises ValueError naming the contact for a shape that is not in the layout, two shapes of one body, or a pair
    of kinds rbody does not compute."""
    from rbody.engine.contacts.geometry import MAX_SLOTS, SLOTS, TYPE_CODES, pairs_text
    from rbody.engine.contacts.terrain import FIELD_KINDS, HFIELD, bounding_radius_of, field_slots

    where = shapes.where
    what = f"contact {contact.shape_a!r}/{contact.shape_b!r}"
    geoms = []
    for field_name in ("shape_a", "shape_b"):
        name = getattr(contact, field_name)
        if name not in where:
            raise ValueError(f"{what}: {field_name}={name!r} is not a shape of the layout (a body's or a fixed one)")
        body, shape = where[name]
        if shape.kind not in TYPE_CODES and shape.kind != "hfield":
            raise ValueError(f"{what}: shape {name!r} is a {shape.kind}: rbody computes contacts of "
                             f"{tuple(TYPE_CODES) + ('hfield',)} shapes")
        if shape.kind == "mesh" and not shape.vertices:
            raise ValueError(f"{what}: mesh shape {name!r} has no vertices: a mesh collides by the convex hull of "
                             "Shape.vertices (from_mjcf gives them)")
        geoms.append((HFIELD if shape.kind == "hfield" else TYPE_CODES[shape.kind], body, shape))
    if geoms[0][1] == geoms[1][1]:
        raise ValueError(f"{what}: both shapes are on {geoms[0][1]!r}: a contact needs two bodies (or a body and "
                         "the world)")
    geoms.sort(key=lambda geom: geom[0])
    (ta, body_a, shape_a), (tb, body_b, shape_b) = geoms
    if ta == HFIELD:
        if tb not in FIELD_KINDS:
            raise ValueError(f"{what}: a height field collides with spheres, capsules, ellipsoids, cylinders, boxes "
                             f"and meshes, not a {shape_b.kind}")
    elif (ta, tb) not in SLOTS:
        raise ValueError(f"{what}: rbody computes contacts of {pairs_text()}, not {shape_a.kind}-{shape_b.kind}")
    fields = dict(U_BOUND=contact.friction, U_RESTITUTION=contact.restitution, U_BODY1=body_index[body_a],
                  U_BODY2=body_index[body_b], U_SPIN=contact.torsion, U_ROLL=contact.rolling, U_MARGIN=contact.margin)
    fields.update(shapes.fields(shape_a, "A"))
    fields.update(shapes.fields(shape_b, "B"))
    if ta == HFIELD:  # the window of cells under geom b (rbody.engine.contacts.terrain)
        if body_a != WORLD:
            raise ValueError(f"{what}: height field {shape_a.name!r} is on {body_a!r}: a height field is world-fixed "
                             "terrain (Layout.fixed)")
        radius = bounding_radius_of(tb, fields["U_GSIZE_B"])
        heights = np.asarray(shape_a.heights)
        dx = 2.0 * shape_a.size[0] / (heights.shape[1] - 1)
        dy = 2.0 * shape_a.size[1] / (heights.shape[0] - 1)
        mx, my, count = field_slots(tb, radius, dx, dy)
        if count > MAX_SLOTS:
            raise ValueError(f"{what}: geom {shape_b.name!r} (bounding radius {radius:.4g} m) spans up to {mx} x {my} "
                             f"cells of height field {shape_a.name!r} (cells {dx:.4g} x {dy:.4g} m): {count} "
                             f"candidates, more than rbody's {MAX_SLOTS} for one pair; a coarser field, or smaller "
                             "geoms against it, are computed")
        fields["U_WINDOW"] = (mx, my, radius)
    else:
        count = SLOTS[(ta, tb)]
    name = f"{shape_a.name}/{shape_b.name}"
    return ([(dict(fields, U_DOF=slot), name if count == 1 else f"{name}[{slot}]") for slot in range(count)],
            (shape_a.name, shape_b.name))
