"""The event-driven run of a constrained tree: smooth steps in a mode, events located exactly, impacts and mode
changes solved as complementarity problems (the scheme: rbody.engine.constraints).

Between events the state moves by classical Runge-Kutta steps (dynamics.rk4_step) of the mode's dynamics, each
followed by the projection onto the held rows' manifold (dynamics.project), on the sampling grid t = k dt. After a
step, every unit's guard (dynamics.guards) is checked; where one has turned negative, its root in the step is found
by Brent's method on the step length h* in (0, h] of the same map from the step's start (so the event time is that
of the discrete flow, to a few ulp of t), the earliest root wins, and at the state there:

1. touching limits (distance <= TOUCH_TOLERANCE) are projected onto their stops; where one approaches (J v < 0) the
   impact is solved: impulses P >= 0 on the touching limits with J v+ + e J v- >= 0, P (J v+ + e J v-) = 0 (Newton's
   law, e the joint's restitution), the equalities' J v+ = 0, dry friction giving no impulse (a bounded force);
2. the new mode is the solution of the complementarity problem at the acceleration level over the touching limits
   at rest (unilateral), the dofs at rest with dry friction (box, |lambda| <= frictionloss) and the equalities
   (rbody.engine.constraints.solver.mlcp_exact): a limit holds where its force is needed, a dof sticks where
   frictionloss suffices, else it slides with the acceleration's sign;
3. the velocities are projected onto the held rows and the guards checked again (all >= 0 to round-off).

Where step 2's problem has no consistent force because contacts slide (Painleve: friction against the slip can make
a contact's normal acceleration fall as its normal force grows), the contacts at rest take a tangential impact
(EventRun.tangential_impact: the impact law at zero normal velocity, which stops them) and the mode is chosen again.

Zeno: a limit hit again and again with restitution under a steady load (a ball bouncing to rest) would need
infinitely many impacts in a finite time; an impact whose approach speed is below ZENO_RATIO of the largest this
unit met is taken as plastic (e = 0), and the joint stays at its stop. More than MAX_EVENTS_PER_STEP events in one
step of dt is a cluster this scheme does not resolve: SimulationError (method="moreau" time-steps through them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from rbody.errors import SimulationError
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.cone import NORMAL, ROW, TANGENT, TANGENT2, cone_pgs, cone_polish, stick_polish
from rbody.engine.constraints.contact_events import (closing_time, contact_guards, event_problem, slip_velocities,
                                                     tangent_frames)
from rbody.engine.constraints.sliding import SLIDING, SLIDING_HELD
from rbody.engine.constraints.solver import mlcp_exact, natural_residual, UNBOUNDED
from rbody.engine.constraints.table import (C_HEADER, CONTACT, CONTACT_KINDS, EQUALITY_KINDS, FRICTION_KINDS,
                                            LOWER_KINDS, STOP_KINDS, TENDON_KINDS, U_BODY1, U_BODY2, U_BOUND, U_DOF,
                                            U_RESTITUTION, U_SLIP, U_TENDON, UNILATERAL, UNIT_SIZE, ConstraintTable)

TOUCH_TOLERANCE = 1e-10   # [m or rad] a limit this close to its stop at an event touches it (projected onto it)
REST_SPEED = 1e-9         # [m/s or rad/s] a dof with friction this slow at an event is at rest (it may stick)
ZENO_RATIO = 1e-6         # an impact slower than this fraction of the fastest on its unit is plastic
MAX_EVENTS_PER_STEP = 200
PROJECTION_ROUNDS = 6     # projections at an event, each with the stops the last one pushed past
FORCE_RTOL = 1e-9         # held rows' forces: |W lambda - r| above this fraction of |r| (and ABS) is inconsistent
FORCE_ATOL = 1e-9
MLCP_RTOL = 1e-10         # an event's complementarity problem solved to this fraction of its scale
GUARD_RTOL = 1e-9         # after an event every guard is >= -this (relative to the largest): else no consistent mode
GUARD_DISTANCE = 1e-14    # [m or rad] a free stop passed by more than this is an event (the root is then located)
GUARD_SPEED = 1e-13       # [m/s or rad/s] a sliding dof's velocity past 0 by more than this is an event
GUARD_FORCE_RTOL = 1e-10  # a held force past its bound by more than this fraction of the forces in play is an event
CLOSING_MARGIN = 1e-3     # a step with open contacts ends this fraction past the earliest closing at present rates
FACE_ALIGNED = 1e-12       # slip directions of a face's contacts within 1 - cos of this are one direction (~1.4e-6 rad)
JAM_NUDGE = 1e-6          # a tangential impact solved at an approach of this fraction of its velocities, then finished
CONE_ROUND = 50           # an event's problem with contacts' cones: Gauss-Seidel sweeps between exact finishes,
CONE_SWEEPS = 2000        # and at most this many sweeps


@dataclass
class Event:
    """One event of a run: time t [s], what happened ("start", "impact", "tangential impact", "limit", "release",
    "stick", "slip"), the units it concerns (names), and for impacts the impulses [N s or N m s] and the kinetic
    energy lost [J]."""

    t: float
    what: str
    units: tuple[str, ...]
    impulse: tuple[float, ...] = ()
    energy_lost: float = 0.0


class Jammed(Exception):
    """select_mode's problem has no consistent force while the contacts `units` slide (Painleve: with friction
    against the slip in the force columns, W = J M^-1 F^T can lose its positive diagonal, and the normal force that
    the sliding would need pulls); residual: the unmet complementarity [N or m/s^2]."""

    def __init__(self, units: tuple, residual: float) -> None:
        super().__init__(units, residual)
        self.units, self.residual = units, residual


@dataclass
class EventLog:
    events: list = field(default_factory=list)
    impacts: int = 0
    mode_changes: int = 0


class EventRun:
    """The event-driven run of one batch element (module docstring).

    table: the ConstraintTable; params: (p,) the tree's row with the table's block (written: its mode changes);
    description: the scene's, for messages. run(y0, dt, nsteps, save_every) -> (samples (S, n), modes (S, units))."""

    def __init__(self, table: ConstraintTable, params: np.ndarray, description: str) -> None:
        self.table = table
        self.p = np.array(params, dtype=np.float64)
        self.modes = table.mode_slice()
        self.description = description
        self.nq, self.nv, self.n = (int(x) for x in dyn.sizes(self.p))
        self.rows = table.rows
        self.units = table.units
        self.codes = table.codes
        self.row_unit = np.concatenate([[k] * u.rows for k, u in enumerate(table.units)]).astype(int)
        self.restitution = np.array([self.p[self._record(k) + U_RESTITUTION] for k in range(len(self.units))])
        self.fastest = np.zeros(len(self.units))
        self.is_limit = table.of_kinds(UNILATERAL)
        self.is_friction = table.of_kinds(FRICTION_KINDS)
        self.largest_bound = max([0.0] + [float(self.p[self._record(k) + U_BOUND])
                                          for k in np.flatnonzero(self.is_friction)])
        self.is_contact = table.of_kinds(CONTACT_KINDS)
        self.contact_units = np.flatnonzero(self.is_contact)
        # guards: one per unit, then a contact's A and B (rbody.engine.constraints.contact_events)
        self.guard_unit = np.concatenate([np.arange(len(self.units)), self.contact_units,
                                          self.contact_units]).astype(int)
        tangent_row = np.zeros(self.rows, dtype=bool)
        for k in self.contact_units:
            tangent_row[self.units[k].row0 + 1:self.units[k].row0 + self.units[k].rows] = True
        self.has_position = (~self.is_friction[self.row_unit] & ~tangent_row).astype(float)
        self.pair = {int(k): (int(self.p[self._record(k) + U_BODY1]), int(self.p[self._record(k) + U_BODY2]))
                     for k in self.contact_units}
        self.mu = np.array([self.p[self._record(k) + U_BOUND] if self.codes[k] == CONTACT else 0.0
                            for k in range(len(self.units))])
        self.log = EventLog()

    # ----- small helpers ------------------------------------------------------------------------------

    def _record(self, k: int) -> int:
        return self.table.offset + C_HEADER + UNIT_SIZE * k

    def _along(self, k: int) -> tuple[str, int]:
        """What unit k's stop or dry friction acts along: ("dof", its dof) or ("tendon", its tendon)."""
        if self.codes[k] in TENDON_KINDS:
            return "tendon", int(self.p[self._record(k) + U_TENDON])
        return "dof", int(self.p[self._record(k) + U_DOF])

    @property
    def mode(self) -> np.ndarray:
        return self.p[self.modes]  # a view: the mode written in the params row

    def set_mode(self, mode: np.ndarray) -> None:
        self.p[self.modes] = mode

    def names(self, units) -> tuple[str, ...]:
        return tuple(self.units[k].name for k in units)

    def fail(self, t: float, what: str, units=(), residual: float | None = None) -> SimulationError:
        named = f" constraints {', '.join(repr(n) for n in self.names(units))};" if len(units) else ""
        tail = f" residual {residual:.3g}" if residual is not None else ""
        return SimulationError(f"scene {self.description}: at t={t:.9g} s{named} {what}{tail}")

    def state_rows(self, y: np.ndarray):
        M = np.empty((self.nv, self.nv))
        f = np.empty(self.nv)
        J = np.empty((self.rows, self.nv))
        jdot, g = np.empty(self.rows), np.empty(self.rows)
        dyn.state_rows(self.p, y, M, f, J, jdot, g)
        return M, f, J, jdot, g

    def held(self) -> np.ndarray:
        rows = np.empty(self.rows)
        dyn.held_rows(self.p, rows)
        return rows

    def step(self, y: np.ndarray, h: float) -> np.ndarray:
        out = np.empty_like(y)
        dyn.rk4_step(y, self.p, h, out)
        held = self.held()
        dyn.project(self.p, out, held * self.has_position, held)
        return out

    def guards(self, y: np.ndarray, t: float) -> np.ndarray:
        """Every guard at state y: one per unit (dynamics.guards; +inf for contacts), then each contact's A and B
        (contact_events.contact_guards)."""
        out = np.empty(len(self.units))
        residual, scale = dyn.guards(self.p, y, out)
        if self.contact_units.size:
            a, b = np.empty(self.contact_units.size), np.empty(self.contact_units.size)
            contact_guards(self.p, y, a, b)
            out = np.concatenate([out, a, b])
        if residual > FORCE_RTOL * scale + FORCE_ATOL:
            held = [k for k in range(len(self.units)) if self.held()[self.units[k].row0]]
            raise self.fail(t, "the held constraints admit no consistent force (they contradict each other):",
                            held, residual)
        return out

    # ----- the run ------------------------------------------------------------------------------------

    def run(self, y0: np.ndarray, dt: float, nsteps: int, save_every: int,
            before_step=None) -> tuple[np.ndarray, np.ndarray]:
        """before_step(k, t, y, p): called before step k (0-based) from time t and state y, to write the step's
        controls into the params row p (held through the step and its events), or None."""
        count = nsteps // save_every + 1
        samples = np.empty((count, self.n))
        modes = np.empty((count, len(self.units)))
        slips = [(k, slice(self._record(k) + U_SLIP, self._record(k) + U_SLIP + 3)) for k in self.contact_units]
        self.slips = np.zeros((count, len(self.units), 3))  # each sliding contact's direction at each sample
        y = np.array(y0, dtype=np.float64)
        samples[0] = y
        y = self.settle(y, 0.0, start=True)
        modes[0] = self.mode
        for k, span in slips:
            self.slips[0, k] = self.p[span]
        g0 = self.guards(y, 0.0)
        t = 0.0
        for k in range(1, nsteps + 1):
            target = k * dt
            if before_step is not None:  # a new control: where it breaks the mode (a held stop pulled, a sticking
                before_step(k - 1, t, y, self.p)  # dof pushed past its friction), an event at this instant
                g0 = self.guards(y, t)
                broken = np.flatnonzero(g0 < -self.guard_tolerance(g0, g0))
                if broken.size:
                    y = self.settle(y, t, triggered=list(broken))
                    g0 = self.guards(y, t)
            events = 0
            while True:
                h = target - t
                whole = True
                if self.contact_units.size:  # no further than just past the earliest closing of an open contact
                    closing = closing_time(self.p, y)
                    limit = closing * (1 + CLOSING_MARGIN) + CLOSING_MARGIN * 1e-3 * dt
                    if limit < h:
                        h, whole = limit, False
                y1 = self.step(y, h)
                if not np.all(np.isfinite(y1)):
                    raise self.fail(t, f"a step of {h:.3g} s gave a non-finite state; try a smaller dt")
                g1 = self.guards(y1, target)
                crossing = np.flatnonzero(g1 < -self.guard_tolerance(g0, g1))
                if crossing.size == 0:
                    y, g0 = y1, g1
                    if not whole:
                        t = t + h
                        continue
                    t = target
                    break
                events += 1
                if events > MAX_EVENTS_PER_STEP:
                    raise self.fail(t, f"more than {MAX_EVENTS_PER_STEP} events within one step of dt={dt:g} s (a "
                                       "cluster of impacts or stick-slip transitions this event-driven scheme does "
                                       "not resolve): use method='moreau', which time-steps through them;",
                                    sorted(set(self.guard_unit[crossing])))
                h_event, first = self.locate(y, h, crossing, g0)
                y = self.step(y, h_event) if h_event > 0 else y
                t = t + h_event
                y = self.settle(y, t, triggered=first)
                g0 = self.guards(y, t)
            if k % save_every == 0:
                samples[k // save_every] = y
                modes[k // save_every] = self.mode
                for unit, span in slips:
                    self.slips[k // save_every, unit] = self.p[span]
        return samples, modes

    def guard_tolerance(self, g0: np.ndarray, g1: np.ndarray) -> np.ndarray:
        """(units,) how far below 0 a guard must fall before it is an event: round-off of its kind (a distance
        GUARD_DISTANCE, a speed GUARD_SPEED, a force GUARD_FORCE_RTOL of the largest force or frictionloss in play),
        so that a guard that sits at 0 (a stop left with no force, a dof at rest on the verge of slipping) does not
        fire again and again at one instant."""
        mode = self.mode
        held_stop = self.is_limit & (mode == 1.0)
        sticking = self.is_friction & (mode == 0.0)
        force = np.concatenate([held_stop | sticking, self.is_contact[self.contact_units]
                                & (mode[self.contact_units] != 0.0), np.zeros(self.contact_units.size, bool)])
        scale = max(1.0, self.largest_bound, float(np.abs(g0[force]).max(initial=0.0)),
                    float(np.abs(g1[force]).max(initial=0.0)))
        out = np.where(force, GUARD_FORCE_RTOL * scale, GUARD_DISTANCE)
        out[:len(self.units)][self.is_friction & (mode != 0.0)] = GUARD_SPEED
        out[len(self.units) + self.contact_units.size:] = GUARD_SPEED
        return out

    def locate(self, y: np.ndarray, h: float, crossing: np.ndarray, g0: np.ndarray) -> tuple[float, list[int]]:
        """The earliest root h* in [0, h] of the guards that turned negative over the step from y, and the units
        whose guards cross there (to round-off of t)."""
        roots = {}
        for k in crossing:
            def guard(s, k=k):
                return self.guards(self.step(y, s), math.nan)[k] if s > 0 else g0[k]
            start = 0.0
            if g0[k] <= 0.0:  # at 0 after the last event (a stop just left): is it positive just after?
                start = next((s for s in h * 0.5 ** np.arange(1, 40) if guard(s) > 0.0), None)
                if start is None:
                    roots[int(k)] = 0.0
                    continue
            roots[int(k)] = brentq(guard, start, h, xtol=4 * np.finfo(float).eps * h, rtol=4 * np.finfo(float).eps,
                                   maxiter=200)
        earliest = min(roots.values())
        # Brent returns a point within xtol of the root; take the side where the guard has crossed
        first = [k for k, r in roots.items() if r <= earliest + 8 * np.finfo(float).eps * max(h, 1.0)]
        s = min(h, earliest + 4 * np.finfo(float).eps * h)
        return s, first

    # ----- at an event: impacts, then the new mode --------------------------------------------------------

    def settle(self, y: np.ndarray, t: float, start: bool = False, triggered=()) -> np.ndarray:
        """The consistent state and mode at an event at time t (module docstring, steps 1-3); start: the initial
        state, which may lie outside its ranges or off its equalities (it is projected onto them: the run's first
        event)."""
        y = y.copy()
        mode = self.mode.copy()
        before = self.mode.copy()
        nq, nv = self.nq, self.nv
        M, f, J, jdot, g = self.state_rows(y)
        unit_g = np.array([g[u.row0] for u in self.units])
        touching = [k for k in range(len(self.units)) if (self.codes[k] in UNILATERAL or self.is_contact[k])
                    and (unit_g[k] <= TOUCH_TOLERANCE or mode[k] != 0.0)]
        # 1. positions onto the equalities and the touching stops and contacts (a contact's normal row)
        position_rows = np.zeros(self.rows)
        for k, unit in enumerate(self.units):
            if self.codes[k] in EQUALITY_KINDS or k in touching:
                position_rows[unit.row0:unit.row0 + unit.rows] = 1.0
        position_rows *= self.has_position
        moved = y[:nq].copy()
        worst = 0.0
        for _round in range(PROJECTION_ROUNDS):  # a stop that the projection pushes past joins the set
            worst, _ = dyn.project(self.p, y, position_rows, np.zeros(self.rows))
            _M, _f, _J, _jdot, g = self.state_rows(y)
            grown = False
            for k, unit in enumerate(self.units):
                if (self.codes[k] in UNILATERAL or self.is_contact[k]) and g[unit.row0] < -TOUCH_TOLERANCE \
                        and not position_rows[unit.row0]:
                    position_rows[unit.row0] = 1.0
                    touching.append(k)
                    grown = True
            if not grown:
                break
        if worst > max(1e3 * dyn.PROJECTION_TOLERANCE, 1e-9):
            bad = [k for k in range(len(self.units)) if position_rows[self.units[k].row0]]
            raise self.fail(t, "no configuration satisfies these constraints together (projection stalled):",
                            bad, worst)
        if start and np.max(np.abs(y[:nq] - moved), initial=0.0) > 0:
            self.log.events.append(Event(t, "start", self.names(touching), (), 0.0))
        # 2. the impact
        M, f, J, jdot, g = self.state_rows(y)
        v = y[nq:nq + nv]
        jv = J @ v
        approaching = [k for k in touching if jv[self.units[k].row0] < -REST_SPEED]
        if approaching or start:
            y, lost, impulses = self.impact(y, M, J, touching, jv, start, t)
            if approaching:
                self.log.impacts += 1
                self.log.events.append(Event(t, "impact", self.names(approaching), impulses, lost))
            y[-1] += lost
            v = y[nq:nq + nv]
            jv = J @ v
        # 3. the mode: complementarity at the acceleration level
        resting = self.come_to_rest(y, touching)
        breaking = [k for k in triggered if k < len(self.units) and self.is_friction[k] and before[k] == 0.0]
        releasing = [k for k in triggered if k < len(self.units) and self.codes[k] in UNILATERAL
                     and before[k] == 1.0]
        first_b = len(self.units) + self.contact_units.size  # a contact's guard A: its force reached a bound
        breaking += [int(self.guard_unit[i]) for i in triggered if len(self.units) <= i < first_b
                     and before[self.guard_unit[i]] == 1.0]
        releasing += [int(self.guard_unit[i]) for i in triggered if len(self.units) <= i < first_b
                      and before[self.guard_unit[i]] != 0.0]
        try:
            mode = self.select_mode(y, t, resting, breaking, releasing)
        except Jammed as jam:  # Painleve: no force is consistent while they slide; an impulse stops them
            y = self.tangential_impact(y, t, touching, jam)
            resting = self.come_to_rest(y, touching)
            try:
                mode = self.select_mode(y, t, resting, breaking, releasing)
            except Jammed as again:
                raise self.fail(t, "Painleve configuration: no consistent force while these contacts slide, and "
                                   "none after the tangential impact that stops them:", again.units,
                                again.residual) from None
        self.set_mode(mode)
        held = self.held()
        dyn.project(self.p, y, np.zeros(self.rows), held)
        changed = np.flatnonzero(mode != before)
        if changed.size and not start:
            self.log.mode_changes += 1
            kinds = {("limit", 1.0): "limit", ("limit", 0.0): "release", ("friction", 0.0): "stick",
                     ("tendon limit", 1.0): "limit", ("tendon limit", 0.0): "release",
                     ("tendon friction", 0.0): "stick",
                     ("contact", 0.0): "release", ("contact", 1.0): "stick", ("contact", SLIDING): "slip",
                     ("contact", SLIDING_HELD): "slip"}
            for k in changed:
                what = kinds.get((self.units[k].kind, float(mode[k])), "slip")
                self.log.events.append(Event(t, what, (self.units[k].name,)))
        g_after = self.guards(y, t)
        finite = g_after[np.isfinite(g_after)]
        floor = -GUARD_RTOL * (1.0 + np.abs(finite).max(initial=0.0))
        if np.any(g_after < floor):
            bad = sorted({int(self.guard_unit[i]) for i in np.flatnonzero(g_after < floor)})
            raise self.fail(t, "no consistent mode: after the event these constraints still violate their "
                               "conditions (a force beyond its bound, or a limit pulled):", bad,
                            float(-g_after.min()))
        return y

    def come_to_rest(self, y: np.ndarray, touching) -> list:
        """Step 3's start (settle): the touching units at rest (a contact's normal velocity within REST_SPEED of 0;
        a contact made to approach by a sequential impact is not at rest: it is the next impact), every stop and
        contact free and each dry-friction dof sliding with its velocity's sign (select_mode decides), and the
        velocities of the resting rows made exactly 0 (y, in place: changes below REST_SPEED), so that a dof that
        starts to slide or a stop that is left moves away from rest in the direction its acceleration says.
        Returns the resting units."""
        nq, nv = self.nq, self.nv
        _M, _f, J, _jdot, _g = self.state_rows(y)
        jv = J @ y[nq:nq + nv]
        resting = [k for k in touching if jv[self.units[k].row0] <= REST_SPEED
                   and (jv[self.units[k].row0] >= -REST_SPEED or not self.is_contact[k])]
        slips = np.zeros((len(self.units), 3))
        if self.contact_units.size:
            slip_velocities(self.p, y, slips)
        slip_speed = np.linalg.norm(slips, axis=1)
        mode = self.mode.copy()
        for k in range(len(self.units)):
            if self.codes[k] in UNILATERAL or self.is_contact[k]:
                mode[k] = 0.0
            elif self.is_friction[k]:  # the velocity along its row: a dof's, or a tendon's L'
                speed = jv[self.units[k].row0]
                mode[k] = 0.0 if abs(speed) <= REST_SPEED else math.copysign(1.0, speed)
        self.set_mode(mode)
        at_rest = np.zeros(self.rows)
        for k, unit in enumerate(self.units):
            if self.is_contact[k]:
                if k in resting:  # its normal, and its tangents where it does not slip
                    at_rest[unit.row0:unit.row0 + (unit.rows if slip_speed[k] <= REST_SPEED else 1)] = 1.0
            elif self.codes[k] in EQUALITY_KINDS or k in resting or (self.is_friction[k] and mode[k] == 0.0):
                at_rest[unit.row0:unit.row0 + unit.rows] = 1.0
        dyn.project(self.p, y, np.zeros(self.rows), at_rest)
        return resting

    def tangential_impact(self, y: np.ndarray, t: float, touching, jam: "Jammed") -> np.ndarray:
        """The impulse that resolves a Painleve configuration (select_mode found no consistent force while the
        contacts jam.units slide): Darboux-Keller's impact at zero normal velocity, as the time-stepping scheme
        gives it in the limit dt -> 0. Every touching contact at rest takes part, plastic (e = 0), its friction
        impulse in its Coulomb cone; the rod of Painleve's example stops sliding at once (its stick impulse lies in
        the cone exactly where the sliding problem has no solution). Logged as the event "tangential impact";
        returns y with v+. A SimulationError where the impulse leaves the contacts sliding as before."""
        nq, nv = self.nq, self.nv
        M, _f, J, _jdot, _g = self.state_rows(y)
        jv = J @ y[nq:nq + nv]
        at_rest = [k for k in touching if self.is_contact[k] and abs(jv[self.units[k].row0]) <= REST_SPEED]
        slips = np.zeros((len(self.units), 3))
        slip_velocities(self.p, y, slips)
        before = np.linalg.norm(slips[list(jam.units)], axis=1)
        after, lost, impulses = self.impact(y, M, J, touching, jv, False, t, jammed=at_rest)
        slip_velocities(self.p, after, slips)
        if not np.all(np.linalg.norm(slips[list(jam.units)], axis=1) < before):
            raise self.fail(t, "Painleve configuration: no consistent force while these contacts slide, and the "
                               "tangential impact does not stop them:", jam.units, jam.residual)
        self.log.impacts += 1
        self.log.events.append(Event(t, "tangential impact", self.names(jam.units), impulses, lost))
        after[-1] += lost
        return after

    def impact(self, y, M, J, touching, jv, start: bool, t: float, jammed=()):
        """Impulses at an impact (Newton's law with each limit's and contact's restitution, equalities held, joint
        dry friction giving no impulse, a contact's friction impulse within its Coulomb cone: sticking, or sliding
        against the tangential velocity after the impact); returns (y with v+, kinetic energy lost [J], impulses on
        the approaching limits and contacts' normals). Touching limits all take part (simultaneous); contacts are
        sequential: only the approaching ones take part, and a touching contact that the impulse makes approach is
        the next event, at the same instant (the chapter's Newton's cradle and stacked balls: a simultaneous
        Newton law would share the momentum among the balls instead). jammed: contacts at rest that take part too,
        plastic (tangential_impact)."""
        nq, nv = self.nq, self.nv
        rows, lo, hi, b, role, mu = [], [], [], [], [], []
        impulses_of = []
        for k, unit in enumerate(self.units):
            if self.codes[k] in EQUALITY_KINDS:
                for a in range(unit.row0, unit.row0 + unit.rows):
                    rows.append(a), lo.append(-np.inf), hi.append(np.inf), b.append(jv[a]), role.append(ROW)
                    mu.append(0.0)
            elif k in touching and (not self.is_contact[k] or start or jv[unit.row0] < -REST_SPEED
                                    or k in jammed):
                # contacts: sequential impacts, the approaching ones only (a touching contact that the impulse
                # makes approach is the next impact, at the same instant: Newton's cradle, the stacked balls)
                a = unit.row0
                speed = -jv[a]
                e = 0.0 if start or k in jammed else self.restitution[k]
                if k in jammed:
                    impulses_of.append(len(rows))
                elif speed > 0:
                    if speed < ZENO_RATIO * self.fastest[k]:
                        e = 0.0
                    self.fastest[k] = max(self.fastest[k], speed)
                    impulses_of.append(len(rows))
                rows.append(a), lo.append(0.0), hi.append(np.inf), b.append(jv[a] + e * min(jv[a], 0.0))
                role.append(NORMAL if self.is_contact[k] else ROW), mu.append(0.0)
                if self.codes[k] == CONTACT:
                    for c, r in ((a + 1, TANGENT), (a + 2, TANGENT2)):
                        rows.append(c), lo.append(-np.inf), hi.append(np.inf), b.append(jv[c]), role.append(r)
                        mu.append(self.mu[k] if r == TANGENT else 0.0)
        v = y[nq:nq + nv].copy()
        if not rows:
            return y, 0.0, ()
        rows = np.array(rows)
        L = np.linalg.cholesky(M)
        A = np.linalg.solve(L, J[rows].T)
        W = A.T @ A
        lo, hi, b = np.array(lo), np.array(hi), np.array(b)
        role = np.array(role)
        mu = np.array(mu)
        if len(jammed):  # at zero normal velocity P = 0 solves too: the impulse is the limit of an approach
            # -delta as delta -> 0 (the time-stepping's, with -g dt), solved near it and finished exactly at delta = 0
            nudge = np.zeros(len(b))
            nudge[[i for i, a in enumerate(rows) if role[i] == NORMAL and self.row_unit[a] in jammed]] = \
                JAM_NUDGE * max(float(np.abs(b).max()), 1e-300)
            lam, status, residual = self.solve(W, b - nudge, lo, hi, role, mu)
            tolerance = MLCP_RTOL * max(1.0, float(np.abs(b).max()))  # solve's own, for the true b
            roles = role.astype(np.int64)
            residual = stick_polish(W, b, lo, hi, roles, mu, lam, 8)
            if residual > 1e-3 * tolerance:
                residual = cone_polish(W, b, lo, hi, roles, mu, lam, 4)
            status = 0 if residual <= tolerance else 1
        else:
            lam, status, residual = self.solve(W, b, lo, hi, role, mu)
        cones = bool(np.any(role != ROW))  # cones: solve's own tolerance, MLCP_RTOL of max(|b|, 1)
        if status != 0 or (not cones and residual > MLCP_RTOL * (np.abs(b).max() + 1e-300) + 1e-14):
            units = sorted({int(self.row_unit[a]) for a in rows})
            raise self.fail(t, "the impact has no consistent impulse "
                            f"(complementarity status {status}):", units, residual)
        kinetic = 0.5 * v @ M @ v
        v = v + np.linalg.solve(L.T, A @ lam)
        y = y.copy()
        y[nq:nq + nv] = v
        lost = kinetic - 0.5 * v @ M @ v
        return y, float(lost), tuple(float(lam[i]) for i in impulses_of)

    @staticmethod
    def solve(W, b, lo, hi, role, mu):
        """The complementarity problem of an event (solver.py; with contacts' cones, cone.py): (lam, status,
        residual). Without cones: the exact active-set method. With cones: Gauss-Seidel by blocks, each round
        finished exactly (the solution where every pushing contact sticks, else each contact's state read from
        Gauss-Seidel's answer), as the time-stepping scheme solves its steps."""
        lam = np.empty(len(b))
        if not np.any(role != ROW):
            status, _steps = mlcp_exact(W, b, lo, hi, lam)
            return lam, status, natural_residual(W, b, lo, hi, lam)
        lam[:] = np.clip(0.0, lo, hi)
        role = role.astype(np.int64)
        scale = max(1.0, float(np.abs(b).max(initial=0.0)))
        tolerance = 1e-3 * MLCP_RTOL * scale
        done, residual = 0, np.inf
        while done < CONE_SWEEPS:
            spent, residual = cone_pgs(W, b, lo, hi, role, mu, lam, tolerance, CONE_ROUND)
            done += max(spent, 1)
            residual = min(stick_polish(W, b, lo, hi, role, mu, lam, 8), residual)
            if residual > tolerance:
                residual = cone_polish(W, b, lo, hi, role, mu, lam, 4)
            if residual <= tolerance:
                break
        return lam, 0 if residual <= MLCP_RTOL * scale else 1, residual

    def select_mode(self, y: np.ndarray, t: float, resting, breaking=(), releasing=()) -> np.ndarray:
        """The mode at state y (module docstring, step 2): the complementarity problem at the acceleration level.

        A stop at rest on a dof with dry friction is one row with the force on the dof from both: the stop pushes
        any amount, friction pulls up to frictionloss F (bounds [-F, inf) on the stop's row, which holds the dof
        inside them and lets it slide away from the stop at -F). breaking: sticking dofs and contacts whose friction
        force has just grown to its bound (the event that located them); releasing: held stops and contacts whose
        force has just fallen to its bound. At the boundary itself the problem is degenerate (the force exactly at
        its bound, the acceleration 0), and the event's direction decides: they slide, or leave the stop.

        A resting contact (its normal velocity 0) enters with its normal row (lambda_n >= 0, complementary to its
        normal acceleration); if it does not slip, with its tangents in its Coulomb cone (it sticks inside the
        cone, and on its edge starts to slide along its tangential acceleration); if it slips, its friction is
        -mu lambda_n along the slip (its force column, rbody.engine.constraints.sliding)."""
        mode = self.mode.copy()
        friction_of = {self._along(k): k for k in range(len(self.units)) if self.is_friction[k]}
        slips = np.zeros((len(self.units), 3))
        if self.contact_units.size:
            slip_velocities(self.p, y, slips)
        slip_speed = np.linalg.norm(slips, axis=1)
        slipping = {k for k in resting if self.codes[k] == CONTACT and slip_speed[k] > REST_SPEED}
        for k in slipping:  # their friction along the slip, in the problem's force columns
            mode[k] = SLIDING
            self.p[self._record(k) + U_SLIP:self._record(k) + U_SLIP + 3] = slips[k] / slip_speed[k]
        self.hold_faces(mode)
        self.set_mode(mode)
        merged = {}  # stop unit -> the friction unit of its dof, both at rest
        rows, lo, hi, units, role, mu = [], [], [], [], [], []
        for k in resting:
            if self.codes[k] in STOP_KINDS:
                j = friction_of.get(self._along(k))
                if j is not None and mode[j] == 0.0:
                    merged[k] = j
        for k, unit in enumerate(self.units):
            if self.codes[k] in EQUALITY_KINDS:
                for a in range(unit.row0, unit.row0 + unit.rows):
                    rows.append(a), lo.append(-np.inf), hi.append(np.inf), units.append(k), role.append(ROW)
                    mu.append(0.0)
            elif k in resting and self.is_contact[k]:
                rows.append(unit.row0), lo.append(0.0), hi.append(np.inf), units.append(k), role.append(NORMAL)
                mu.append(0.0)
                if self.codes[k] == CONTACT and k not in slipping:
                    for a, r in ((unit.row0 + 1, TANGENT), (unit.row0 + 2, TANGENT2)):
                        rows.append(a), lo.append(-np.inf), hi.append(np.inf), units.append(k), role.append(r)
                        mu.append(self.mu[k] if r == TANGENT else 0.0)
            elif k in resting:
                bound = self.p[self._record(merged[k]) + U_BOUND] if k in merged else 0.0
                rows.append(unit.row0), lo.append(-bound), hi.append(np.inf), units.append(k), role.append(ROW)
                mu.append(0.0)
            elif self.is_friction[k] and mode[k] == 0.0 and k not in merged.values():
                bound = self.p[self._record(k) + U_BOUND]
                rows.append(unit.row0), lo.append(-bound), hi.append(bound), units.append(k), role.append(ROW)
                mu.append(0.0)
        if not rows:
            return mode
        rows = np.array(rows)
        m = len(rows)
        W, b = np.empty((m, m)), np.empty(m)
        event_problem(self.p, y, rows.astype(np.int64), W, b)
        lo, hi = np.array(lo), np.array(hi)
        role, mu = np.array(role), np.array(mu)
        lam, status, residual = self.solve(W, b, lo, hi, role, mu)
        scale = np.abs(b).max() + np.abs(W).max() * np.abs(lam).max(initial=0.0)
        if slipping:  # W is not symmetric: the solvers' residuals assume a positive diagonal; complementarity read
            # directly on the normal rows (lambda_n >= 0, w_n >= 0, one of them 0)
            normal = role == NORMAL
            w = W @ lam + b
            unmet = np.abs(np.minimum(lam[normal], w[normal])).max(initial=0.0)
            if status != 0 or max(residual, unmet) > MLCP_RTOL * scale + 1e-14:
                raise Jammed(tuple(sorted(k for k in set(units) if k in slipping)), max(residual, unmet))
        if status != 0 or residual > MLCP_RTOL * scale + 1e-14:
            bad = sorted(set(units))
            what = ("no consistent force exists (the held rows' accelerations contradict each other):"
                    if status == UNBOUNDED else "no consistent force exists (complementarity problem unsolved):")
            raise self.fail(t, what, bad, residual)
        w = W @ lam + b
        tolerance = 1e-12 * scale + 1e-14
        frames = None
        for i, k in enumerate(units):
            code = self.codes[k]
            if self.is_contact[k]:
                if role[i] != NORMAL:
                    continue
                at_bound = lam[i] <= tolerance
                if w[i] > tolerance or (at_bound and k in releasing):
                    mode[k] = 0.0
                elif k in slipping or code != CONTACT:
                    mode[k] = SLIDING if k in slipping else 1.0
                else:
                    ft = lam[i + 1:i + 3]
                    wt = w[i + 1:i + 3]
                    edge = np.hypot(*ft) >= (1 - 1e-9) * self.mu[k] * lam[i]
                    moving = np.hypot(*wt) > tolerance
                    if moving or edge:  # on its cone's edge it starts to slide: along its acceleration (or against
                        # its force where the acceleration is still 0: the direction of the event that brought it)
                        if frames is None:
                            frames = np.zeros((len(self.units), 3, 3))
                            tangent_frames(self.p, y, frames)
                        along = wt if moving else -ft
                        direction = along[0] * frames[k, 1] + along[1] * frames[k, 2]
                        self.p[self._record(k) + U_SLIP:self._record(k) + U_SLIP + 3] = \
                            direction / np.linalg.norm(direction)
                        mode[k] = SLIDING
                    else:
                        mode[k] = 1.0
            elif code in UNILATERAL:
                at_bound = lam[i] <= lo[i] + tolerance + 1e-9 * abs(lo[i])
                leaves = w[i] > tolerance or (at_bound and k in releasing)
                mode[k] = 0.0 if leaves else 1.0
                if k in merged:  # the dof sticks at the stop, or slides away from it
                    mode[merged[k]] = (1.0 if code in LOWER_KINDS else -1.0) if leaves and lo[i] < 0.0 else 0.0
            elif code in FRICTION_KINDS:
                mode[k] = 0.0 if abs(w[i]) <= tolerance else math.copysign(1.0, w[i])
                if k in breaking and abs(lam[i]) >= (1 - 1e-9) * hi[i]:
                    mode[k] = -math.copysign(1.0, lam[i])
        self.hold_faces(mode)
        return self.drop_redundant_stops(mode, W, lam, lo, units, merged, tolerance)

    def drop_redundant_stops(self, mode, W, lam, lo, units, merged, tolerance) -> np.ndarray:
        """A stop at rest with no force (lambda at its bound 0) whose row is a combination of the other held rows
        (in the metric of W: its Schur complement against them vanishes) is not held: the others keep it at its
        stop, and holding it too would leave its share of the force undetermined (the minimum-norm split of a
        redundant set can pull on a stop: two coupled fingers on their stops, a mimic with a limit on each joint).
        Its distance stays a guard, as for any stop that is not held."""
        for i, k in enumerate(units):
            if (self.codes[k] not in UNILATERAL or mode[k] != 1.0 or k in merged
                    or lam[i] > lo[i] + tolerance + 1e-9 * abs(lo[i])):
                continue
            others = [j for j, u in enumerate(units) if j != i and (self.codes[u] in EQUALITY_KINDS or
                      (self.codes[u] in UNILATERAL and mode[u] == 1.0)
                      or (self.is_friction[u] and mode[u] == 0.0))]
            if not others:
                continue
            block = W[np.ix_(others, others)]
            coupling = W[others, i]
            solution = np.linalg.lstsq(block, coupling, rcond=1e-12)[0]
            if W[i, i] - coupling @ solution <= 1e-9 * W[i, i]:
                mode[k] = 0.0
        return mode

    def hold_faces(self, mode: np.ndarray) -> None:
        """Several contacts of one pair of bodies sliding at once in one direction (a face that translates, their
        directions within FACE_ALIGNED): one direction for all of them, the mean of their slips' directions now,
        held until the next event (rbody.engine.constraints.sliding). A face that turns as it slides keeps each
        contact's own s/|s|."""
        faces = {}
        for k in self.contact_units:
            if mode[k] >= SLIDING:
                faces.setdefault(self.pair[k], []).append(k)
        for members in faces.values():
            if len(members) < 2:
                continue
            spans = [slice(self._record(k) + U_SLIP, self._record(k) + U_SLIP + 3) for k in members]
            mean = np.sum([self.p[span] for span in spans], axis=0)
            mean /= np.linalg.norm(mean)
            if min(float(self.p[span] @ mean) for span in spans) < 1 - FACE_ALIGNED:
                continue  # a face that turns as it slides: each contact along its own slip
            for k, span in zip(members, spans):
                self.p[span] = mean
                mode[k] = SLIDING_HELD


__all__ = ["EventRun", "Event", "EventLog", "TOUCH_TOLERANCE", "REST_SPEED", "ZENO_RATIO", "MAX_EVENTS_PER_STEP"]
