"""Exact impacts on a line: balls between walls, simulated event by event.

Between impacts every ball moves freely, x_i(t) = x_i + v_i t, so the surface gap between two
neighbours (or a ball and a wall) shrinks at the constant closing speed c = v_left - v_right and
the time of impact is found exactly,

    t = gap / c        (only for c > 0: a pair that does not approach never collides).

At an impact of the pair (a, b), a left of b, the chapter's one-dimensional collision with
momentum conserved and the relative velocity reversed and scaled by the coefficient of
restitution e, v_b' - v_a' = -e (v_b - v_a), gives the impulse J = (1 + e) mu (v_a - v_b),
mu = m_a m_b / (m_a + m_b):

    v_a' = v_a - (1 + e) m_b / (m_a + m_b) (v_a - v_b),
    v_b' = v_b + (1 + e) m_a / (m_a + m_b) (v_a - v_b).

A wall is a body of infinite mass at rest: the ball's velocity becomes -e v.

State. The engine integrates the n + 1 surface gaps (gap 0: left wall to ball 0, gap k: ball
k-1 to ball k, gap n: ball n-1 to right wall; inf where there is no wall) and the velocities, not
the positions: the gap that closes is set to exactly 0, every gap is clamped at 0 against
round-off, so no pair ever penetrates, and a small gap keeps its full relative precision however
far from the origin the balls are. After an impact the pair separates (e > 0) or moves together
(e = 0), so its closing speed is <= 0 and it cannot collide again at once: no Zeno loop. (With
e < 1 several balls can still meet infinitely often in a finite time, inelastic collapse; a run
stops after max_events impacts.)
Simultaneous impacts (Newton's cradle) are resolved one pair at a time, the lowest gap first, each
at time-of-impact 0 after the previous one.

The trajectory is sampled at given times; a sample at a time t shows the state of the free
motion before any impact at exactly t (the initial state at t = 0), and the collision counts of
impacts at times < t. The time step of the caller only chooses these sample times.

Gravity along the line (a vertical line: balls dropped onto a floor). Every ball has the same constant
acceleration a (-g on a line pointing up), the walls none. A gap between two balls then still closes
at a constant speed (the a t^2/2 of both cancel) and its time of impact stays gap / c; a gap between a
wall and a ball is a parabola,

    gap(tau) = gap - c tau + A tau^2 / 2,    A = a (wall below the ball), -a (wall above it),

whose first closing root (gap' <= 0 there) is tau = (c - sqrt(D)) / A, D = c^2 - 2 A gap, evaluated
without cancellation as tau = 2 gap / (c + sqrt(D)) when c >= 0; when c < 0 the ball is moving away
and comes back only if A < 0, at (c - sqrt(D)) / A (both terms of one sign). D < 0: never. Right after
a floor impact (gap 0, c = -v < 0) this is the time of flight 2 v / |a|, with no root at tau = 0.
A ball left exactly at rest on the floor (the large ball of the stacked balls when M = 3 m) would
meet it again at zero speed, at the same instant, for ever: balls at rest (velocity exactly 0) in a
touching column (gaps exactly 0) on the wall the acceleration presses them against are held by it,
its reaction balancing their weight, and do not accelerate until an impact moves them; the gap
above such a column then closes under the relative acceleration of the ball falling onto it.

`line_events` is the compiled loop (no Python per event). `exact_line` is its twin in rational
arithmetic (fractions.Fraction, exact for float inputs): the reference for small runs without
acceleration (with one the times of impact are square roots, not rational).

Discs in a plane (`disc_events`, `Discs`): n discs moving freely in a plane without external force,
impacts found exactly. With d = x_j - x_i, w = v_j - v_i and D = r_i + r_j, contact |d + w tau| = D
is the quadratic |w|^2 tau^2 + 2 (d.w) tau + (|d| - D)(|d| + D) = 0; the pair approaches when d.w < 0,
and its discriminant, by Lagrange's identity (d.w)^2 - |d|^2 |w|^2 = -(d x w)^2, is, with the
impact parameter p = |d x w_hat| (w_hat = w / |w|),

    (d.w)^2 - |w|^2 (|d|^2 - D^2) = |w|^2 (D - p)(D + p)     (no cancellation),

negative when the discs miss, zero when they graze (no impulse: no impact). The first root is taken
in the form tau = (|d| - D)(|d| + D) / (-(d.w) + sqrt(disc)), whose terms have one sign. The impulse
acts along the line of centres n = d_c / |d_c| at contact (no friction, so the discs do not spin),
formed from d_c . w = -sqrt(disc) and d_c x w = d x w rather than from the difference of two nearly
equal positions (which loses the small offset along w near a graze); with the closing speed
c = (v_i - v_j).n > 0,

    v_i' = v_i - (1 + e) m_j / (m_i + m_j) c n,    v_j' = v_j + (1 + e) m_i / (m_i + m_j) c n.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from rbody.checks import finite_array
from rbody.errors import SimulationError


def sample_times(t_end: float, sample_dt: float) -> np.ndarray:
    """(T,) sampling grid 0, dt, 2 dt, ... reaching t_end (rounded up to round-off) [s], both checked."""
    t_end = float(finite_array(t_end, "t_end"))
    sample_dt = float(finite_array(sample_dt, "sample_dt"))
    if not (t_end > 0 and 0 < sample_dt <= t_end):
        raise ValueError(f"t_end={t_end!r}, sample_dt={sample_dt!r}: need 0 < sample_dt <= t_end [s]")
    steps = max(1, math.ceil(t_end / sample_dt * (1 - 1e-12)))
    return np.arange(steps + 1) * sample_dt


# stats[STATUS] after a run
DONE, STOPPED, TOO_MANY = 0, 1, 2
EVENTS, BALL, WALL, TURN, STATUS = range(5)


@njit(cache=True)
def time_to_close(gap, c, accel):
    """First time tau >= 0 [s] at which gap(tau) = gap - c tau + accel tau^2 / 2 reaches 0 while closing
    (inf: never). gap >= 0 [m]; c closing speed [m/s]; accel [m/s^2] the relative acceleration of the
    gap (its second derivative). accel = 0: gap / c for c > 0, as free motion."""
    if accel == 0.0:
        return gap / c if c > 0.0 else np.inf
    if not gap < np.inf:
        return np.inf
    disc = c * c - 2.0 * accel * gap
    if disc < 0.0:
        return np.inf                  # turns round before it closes (accel > 0)
    root = np.sqrt(disc)
    if c >= 0.0:
        s = c + root                   # both terms >= 0: no cancellation
        if s > 0.0:
            return 2.0 * gap / s
        return 0.0 if accel < 0.0 else np.inf  # touching, at rest relative to each other
    if accel < 0.0:
        return (c - root) / accel      # moving apart now, pulled back: both terms < 0
    return np.inf


@njit(cache=True)
def support(gap, vel, accel, acc, gap_acc):
    """Accelerations of the balls (acc (n+2,), walls 0) and of the gaps (gap_acc (n+1,)) under a
    constant acceleration accel [m/s^2] along the line, in place: balls at rest in a touching column
    on the wall that accel presses them against (gaps exactly 0, velocities exactly 0) are held there
    by it and do not accelerate; every other ball has accel."""
    n = vel.shape[0] - 2
    acc[0] = 0.0
    acc[n + 1] = 0.0
    for i in range(1, n + 1):
        acc[i] = accel
    if accel < 0.0:                    # pressed onto the left wall (a floor)
        k = 0
        while k < n and gap[k] == 0.0 and vel[k + 1] == 0.0:
            acc[k + 1] = 0.0
            k += 1
    elif accel > 0.0:                  # pressed onto the right wall
        k = n
        while k > 0 and gap[k] == 0.0 and vel[k] == 0.0:
            acc[k] = 0.0
            k -= 1
    for k in range(n + 1):
        gap_acc[k] = acc[k + 1] - acc[k]


@njit(cache=True)
def line_events(gap, vel, k_left, k_right, accel, watch, t_stop, max_events,
                sample_t, sample_gap, sample_vel, sample_x0, sample_events, sample_ball,
                record, ev_time, ev_gap, ev_vel, stats):
    """Run the impacts of balls on a line up to time t_stop, in place.

    gap:      (n+1,) surface gaps [m] (gap 0 left wall-ball 0, gap k ball k-1-ball k, gap n ball
              n-1-right wall; inf: no wall); on return the gaps at the last event
    vel:      (n+2,) velocities [m/s]: vel[k+1] is ball k, vel[0] = vel[n+1] = 0 are the walls;
              on return the velocities after the last impact
    k_left, k_right: (n+1,) impulse factors of gap k: (1+e) m_right/(m_left+m_right) and
              (1+e) m_left/(m_left+m_right); a wall has factor 0 (infinite mass)
    accel:    constant acceleration of every ball along the line [m/s^2] (0: free motion); the
              walls are fixed, so gap 0 closes with relative acceleration accel, gap n with -accel;
              balls resting on the wall accel presses them against are held by it (`support`)
    watch:    ball whose first reversal of velocity is reported in stats[TURN] (-1: none)
    t_stop:   last time [s]: impacts at times <= t_stop are applied
    max_events: the run stops with status TOO_MANY after this many impacts
    sample_t: (K,) increasing sample times [s]; sample_gap (K, n+1), sample_vel (K, n),
              sample_x0 (K,) displacement of ball 0 since t = 0 [m], sample_events (K,) impacts
              before each sample, sample_ball (K,) ball-ball impacts before each sample
    record:   store every impact in ev_time (E,) [s], ev_gap (E,) gap index, ev_vel (E, n)
              velocities after it (E >= the number of impacts)
    stats:    (5,) int64 out: impacts, ball-ball impacts, wall impacts, ball-ball impacts up to and
              including the first reversal of `watch` (-1 if it never reverses), status
    Returns the time of the last impact [s] (0.0 when there is none).
    """
    n_gaps = gap.shape[0]
    n = n_gaps - 1
    n_samples = sample_t.shape[0]
    t = 0.0
    t_last = 0.0
    x0 = 0.0                       # displacement of ball 0 since t = 0
    events = 0
    ball = 0
    wall = 0
    turn = -1
    v_watch0 = vel[watch + 1] if watch >= 0 else 0.0
    # Acceleration of each ball (walls 0) and of each gap, right body's minus left body's: ball-ball
    # gaps 0 but next to a ball held at rest by a wall.
    acc = np.zeros(n + 2)
    gap_acc = np.zeros(n_gaps)
    if accel != 0.0:
        support(gap, vel, accel, acc, gap_acc)
    s = 0
    status = DONE
    while True:
        # Earliest time of impact over the approaching pairs (lowest gap on a tie).
        dt = np.inf
        hit = -1
        if accel == 0.0:
            for k in range(n_gaps):
                c = vel[k] - vel[k + 1]
                if c > 0.0:
                    tk = gap[k] / c
                    if tk < dt:
                        dt = tk
                        hit = k
        else:
            for k in range(n_gaps):
                tk = time_to_close(gap[k], vel[k] - vel[k + 1], gap_acc[k])
                if tk < dt:
                    dt = tk
                    hit = k
        t_hit = t + dt
        if hit < 0 or t_hit > t_stop:
            status = DONE if hit < 0 else STOPPED
            break
        if events >= max_events:
            status = TOO_MANY
            break
        # Samples up to and including t_hit see the free motion before the impact.
        while s < n_samples and sample_t[s] <= t_hit:
            tau = sample_t[s] - t
            for k in range(n_gaps):
                g = gap[k] - (vel[k] - vel[k + 1]) * tau
                if gap_acc[k] != 0.0:
                    g += 0.5 * gap_acc[k] * tau * tau
                sample_gap[s, k] = g if g > 0.0 else 0.0
            for i in range(n):
                sample_vel[s, i] = vel[i + 1] + acc[i + 1] * tau
            sample_x0[s] = x0 + vel[1] * tau + 0.5 * acc[1] * tau * tau
            sample_events[s] = events
            sample_ball[s] = ball
            s += 1
        # Free motion to the impact; the closing gap is exactly 0, none below 0.
        if accel == 0.0:
            for k in range(n_gaps):
                g = gap[k] - (vel[k] - vel[k + 1]) * dt
                gap[k] = g if g > 0.0 else 0.0
            x0 += vel[1] * dt
        else:
            for k in range(n_gaps):
                g = gap[k] - (vel[k] - vel[k + 1]) * dt + 0.5 * gap_acc[k] * dt * dt
                gap[k] = g if g > 0.0 else 0.0
            x0 += vel[1] * dt + 0.5 * acc[1] * dt * dt
            for i in range(1, n + 1):
                vel[i] += acc[i] * dt
        gap[hit] = 0.0
        t = t_hit
        t_last = t
        # Impulse: closing speed c reversed and scaled by e, momentum conserved.
        c = vel[hit] - vel[hit + 1]
        vel[hit] -= k_left[hit] * c
        vel[hit + 1] += k_right[hit] * c
        vel[0] = 0.0
        vel[n + 1] = 0.0
        if accel != 0.0:
            support(gap, vel, accel, acc, gap_acc)
        events += 1
        if hit == 0 or hit == n:
            wall += 1
        else:
            ball += 1
        if turn < 0 and watch >= 0 and vel[watch + 1] * v_watch0 < 0.0:
            turn = ball
        if record:
            e = events - 1
            ev_time[e] = t
            ev_gap[e] = hit
            for i in range(n):
                ev_vel[e, i] = vel[i + 1]
    # Samples after the last impact: free motion.
    while s < n_samples:
        tau = sample_t[s] - t
        for k in range(n_gaps):
            g = gap[k] - (vel[k] - vel[k + 1]) * tau
            if gap_acc[k] != 0.0:
                g += 0.5 * gap_acc[k] * tau * tau
            sample_gap[s, k] = g if g > 0.0 else 0.0
        for i in range(n):
            sample_vel[s, i] = vel[i + 1] + acc[i + 1] * tau
        sample_x0[s] = x0 + vel[1] * tau + 0.5 * acc[1] * tau * tau
        sample_events[s] = events
        sample_ball[s] = ball
        s += 1
    stats[EVENTS] = events
    stats[BALL] = ball
    stats[WALL] = wall
    stats[TURN] = turn
    stats[STATUS] = status
    return t_last


@dataclass(frozen=True)
class LineRun:
    """Result of one run of `Line.run`.

    t_last: time of the last impact [s] (0 if none); events, ball, wall: impact counts; turn:
    ball-ball impacts up to the first reversal of the watched ball (-1: none or no ball watched);
    status: DONE (no further impact possible), STOPPED (t_stop reached) or TOO_MANY.
    samples: name -> sampled arrays (empty when no sample times were given):
      gaps (K, n+1) [m], velocities (K, n) [m/s], x0 (K,) displacement of ball 0 [m],
      collisions (K,), ball_collisions (K,) impacts before each sample time.
    event_arrays: time (E,) [s], gap (E,) gap index, velocities (E, n) after each impact [m/s]
      (empty when not recorded).
    """

    t_last: float
    events: int
    ball: int
    wall: int
    turn: int
    status: int
    samples: dict = field(default_factory=dict)
    event_arrays: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Line:
    """Balls on a line between at most one wall on each side (the reachable ones).

    masses (n,) [kg], radii (n,) [m], restitution e in [0, 1]; wall_lo, wall_hi: positions of the
    wall faces left and right of the balls [m], -inf / +inf where there is none; acceleration:
    constant acceleration of every ball along the line [m/s^2] (-g on a vertical line pointing up,
    the left wall then a floor; 0 on a horizontal line).
    """

    masses: np.ndarray
    radii: np.ndarray
    restitution: float
    wall_lo: float = -np.inf
    wall_hi: float = np.inf
    acceleration: float = 0.0

    @property
    def n(self) -> int:
        return self.masses.size

    def impulse_factors(self) -> tuple[np.ndarray, np.ndarray]:
        """(n+1,) factors (1+e) m_b/(m_a+m_b) and (1+e) m_a/(m_a+m_b) of each gap; walls have 0
        for themselves and (1+e) for the ball."""
        e1 = 1.0 + self.restitution
        k_left, k_right = np.zeros(self.n + 1), np.zeros(self.n + 1)
        k_right[0] = e1             # left wall: the ball (right of it) gets (1+e)
        k_left[self.n] = e1         # right wall: the ball (left of it) gets (1+e)
        m_a, m_b = self.masses[:-1], self.masses[1:]
        k_left[1:-1] = e1 * m_b / (m_a + m_b)
        k_right[1:-1] = e1 * m_a / (m_a + m_b)
        return k_left, k_right

    def gaps(self, positions: np.ndarray) -> np.ndarray:
        """(n+1,) surface gaps of centre positions (n,) [m]: walls, then neighbours."""
        x, r = positions, self.radii
        out = np.empty(self.n + 1)
        out[0] = x[0] - r[0] - self.wall_lo
        out[1:-1] = x[1:] - x[:-1] - (r[:-1] + r[1:])
        out[-1] = self.wall_hi - x[-1] - r[-1]
        return out

    def positions(self, gaps: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Centre positions (..., n) [m] from gaps (..., n+1) [m] and the position of ball 0 (...,)
        when there is no wall to anchor them: anchored at the left wall if there is one (so no ball
        ever crosses it), else at the right wall, else at ball 0."""
        r = self.radii
        gaps = np.asarray(gaps)
        step = gaps[..., 1:-1] + (r[:-1] + r[1:])      # x_k - x_(k-1)
        if np.isfinite(self.wall_lo):
            first = np.asarray(self.wall_lo + gaps[..., 0] + r[0])
        elif np.isfinite(self.wall_hi):
            last = np.asarray(self.wall_hi - gaps[..., -1] - r[-1])
            back = np.cumsum(step[..., ::-1], axis=-1)[..., ::-1]
            return np.concatenate([last[..., None] - back, last[..., None]], axis=-1)
        else:
            first = np.asarray(x0)
        return np.concatenate([first[..., None], first[..., None] + np.cumsum(step, axis=-1)], axis=-1)

    def run(self, positions: np.ndarray, velocities: np.ndarray, *, t_stop: float,
            sample_t: np.ndarray | None = None, record: bool = False, watch: int = -1,
            max_events: int = 10**9, expected_events: int | None = None) -> LineRun:
        """Run the compiled event loop from positions (n,) [m] and velocities (n,) [m/s] at t = 0.

        sample_t (K,) [s]: sample times (none: count only); record: keep every impact (needs
        expected_events, the count of impacts up to t_stop, to size the arrays; found with a
        counting run when not given). Returns a LineRun; samples' x0 is the position of ball 0.
        """
        n = self.n
        k_left, k_right = self.impulse_factors()
        if record and expected_events is None:
            expected_events = self.run(positions, velocities, t_stop=t_stop, watch=watch,
                                       max_events=max_events).events
        size = int(expected_events) if record else 0
        sample_t = np.zeros(0) if sample_t is None else np.ascontiguousarray(sample_t, dtype=np.float64)
        k = sample_t.size
        gap = self.gaps(np.asarray(positions, dtype=np.float64))
        vel = np.zeros(n + 2)
        vel[1:-1] = velocities
        stats = np.zeros(5, dtype=np.int64)
        samples = {"gaps": np.empty((k, n + 1)), "velocities": np.empty((k, n)), "x0": np.empty(k),
                   "collisions": np.empty(k, dtype=np.int64), "ball_collisions": np.empty(k, dtype=np.int64)}
        ev = {"time": np.empty(size), "gap": np.empty(size, dtype=np.int32), "velocities": np.empty((size, n))}
        t_last = line_events(gap, vel, k_left, k_right, float(self.acceleration), int(watch), float(t_stop),
                             int(max_events),
                             sample_t, samples["gaps"], samples["velocities"], samples["x0"],
                             samples["collisions"], samples["ball_collisions"],
                             bool(record), ev["time"], ev["gap"], ev["velocities"], stats)
        if record and stats[EVENTS] != size:
            raise SimulationError(f"the recording run found {stats[EVENTS]} impacts, the counting run {size}")
        if k:
            samples["x0"] += positions[0]
        return LineRun(t_last=float(t_last), events=int(stats[EVENTS]), ball=int(stats[BALL]),
                       wall=int(stats[WALL]), turn=int(stats[TURN]), status=int(stats[STATUS]),
                       samples=samples if k else {}, event_arrays=ev if record else {})


def exact_line(line: Line, positions: ArrayLike, velocities: ArrayLike, sample_t: ArrayLike, *,
               max_events: int = 10_000) -> dict:
    """The same event-by-event motion in exact rational arithmetic (the twin of `line_events`).

    Every float input is an exact binary fraction, the times of impact gap / c and the impulses are
    rational, so the run has no round-off at all; only the final conversion to float rounds.
    positions, velocities (n,) at t = 0; sample_t (K,) [s]. Returns positions (K, n) [m],
    velocities (K, n) [m/s], energy (K,) [J], collisions (K,), ball_collisions (K,) (impacts at
    times < each sample, as the compiled loop), and events: time (E,) [s], gap (E,), velocities
    (E, n) for the impacts up to the last sample time. ValueError beyond max_events impacts, and for a
    line with acceleration (its times of impact are square roots, not rational numbers).
    """
    if line.acceleration != 0.0:
        raise ValueError(f"line.acceleration={line.acceleration!r}: the rational twin covers free motion only "
                         "(acceleration 0); with one the times of impact are irrational")
    n = line.n
    F = Fraction
    m = [F(float(v)) for v in line.masses]
    r = [F(float(v)) for v in line.radii]
    e = F(float(line.restitution))
    x = [F(float(v)) for v in positions]
    v = [F(float(u)) for u in velocities]
    lo = None if not np.isfinite(line.wall_lo) else F(float(line.wall_lo))
    hi = None if not np.isfinite(line.wall_hi) else F(float(line.wall_hi))
    sample_t = np.asarray(sample_t, dtype=np.float64).reshape(-1)
    order = np.argsort(sample_t, kind="stable")
    out_x, out_v = np.empty((sample_t.size, n)), np.empty((sample_t.size, n))
    out_energy = np.empty(sample_t.size)
    out_events = np.empty(sample_t.size, dtype=np.int64)
    out_ball = np.empty(sample_t.size, dtype=np.int64)
    ev_t, ev_g, ev_v = [], [], []
    t = F(0)
    events = ball = 0
    s = 0
    t_end = F(float(sample_t.max())) if sample_t.size else F(0)

    def record_samples(upto):
        nonlocal s
        while s < sample_t.size and (upto is None or F(float(sample_t[order[s]])) <= upto):
            tau = F(float(sample_t[order[s]])) - t
            row = order[s]
            out_x[row] = [float(x[i] + v[i] * tau) for i in range(n)]
            out_v[row] = [float(u) for u in v]
            out_energy[row] = float(sum(mi * ui * ui for mi, ui in zip(m, v)) / 2)
            out_events[row], out_ball[row] = events, ball
            s += 1

    while True:
        best, hit = None, -1
        for k in range(n + 1):
            if k == 0:
                if lo is None or v[0] >= 0:
                    continue
                gap, c = x[0] - r[0] - lo, -v[0]
            elif k == n:
                if hi is None or v[n - 1] <= 0:
                    continue
                gap, c = hi - x[n - 1] - r[n - 1], v[n - 1]
            else:
                c = v[k - 1] - v[k]
                if c <= 0:
                    continue
                gap = x[k] - x[k - 1] - r[k - 1] - r[k]
            tk = gap / c
            if best is None or tk < best:
                best, hit = tk, k
        if hit < 0 or t + best > t_end:
            break
        if events >= max_events:
            raise ValueError(f"max_events={max_events}: the exact (rational) run has more impacts before "
                             f"t={float(t_end)} s; it is meant for small runs")
        record_samples(t + best)
        x = [xi + vi * best for xi, vi in zip(x, v)]
        t += best
        if hit == 0:
            v[0] = -e * v[0]
        elif hit == n:
            v[n - 1] = -e * v[n - 1]
        else:
            a, b = hit - 1, hit
            c = v[a] - v[b]
            total = m[a] + m[b]
            v[a], v[b] = v[a] - (1 + e) * m[b] / total * c, v[b] + (1 + e) * m[a] / total * c
        events += 1
        ball += 0 < hit < n
        ev_t.append(float(t))
        ev_g.append(hit)
        ev_v.append([float(u) for u in v])
    record_samples(None)
    return {"positions": out_x, "velocities": out_v, "energy": out_energy, "collisions": out_events,
            "ball_collisions": out_ball,
            "events": {"time": np.array(ev_t, dtype=np.float64), "gap": np.array(ev_g, dtype=np.int32),
                       "velocities": np.array(ev_v, dtype=np.float64).reshape(-1, n)}}


# ----- discs in a plane ---------------------------------------------------------------------------


@njit(cache=True)
def disc_time_of_impact(dx, dy, wx, wy, distance):
    """First time tau >= 0 [s] at which two discs touch, |d + w tau| = distance (inf: they do not).

    d = (dx, dy) = x_j - x_i [m], w = (wx, wy) = v_j - v_i [m/s], distance D = r_i + r_j [m]. Only an
    approaching pair (d.w < 0) can collide; with w_hat = w / |w| and the offset p = |d x w_hat| of the
    line of relative motion (the impact parameter), disc = |w|^2 (D - p)(D + p): a miss (p > D) or a
    graze (p = D, zero normal speed) is no impact; a pair touching or overlapping by round-off while
    approaching collides at once (tau = 0).
    """
    if not dx * wx + dy * wy < 0.0:
        return np.inf
    speed = np.sqrt(wx * wx + wy * wy)
    ux, uy = wx / speed, wy / speed
    p = abs(ux * dy - uy * dx)
    h2 = (distance - p) * (distance + p)
    if not h2 > 0.0:
        return np.inf
    dist = np.hypot(dx, dy)
    c0 = (dist - distance) * (dist + distance)      # |d|^2 - D^2
    if c0 <= 0.0:
        return 0.0
    # c0 / (-(d.w) + sqrt(disc)), both terms of the sum > 0
    return c0 / (speed * (np.sqrt(h2) - (dx * ux + dy * uy)))


@njit(cache=True)
def disc_contact_normal(dx, dy, wx, wy, distance):
    """Unit line of centres (nx, ny), from disc i to disc j, at the contact that disc_time_of_impact
    finds from d = (dx, dy) = x_j - x_i [m], w = (wx, wy) = v_j - v_i [m/s], distance D [m].

    At the contact d_c = d + w tau: d_c . w_hat = -sqrt((D - p)(D + p)) (the first root) and
    d_c x w_hat = d x w_hat, so in the frame of w_hat and w_perp = (-w_hat_y, w_hat_x),
    d_c = -sqrt((D - p)(D + p)) w_hat + (w_hat x d) w_perp, free of the cancellation in d + w tau near
    a graze. A touching or overlapping pair (tau = 0): d / |d|.
    """
    dist = np.hypot(dx, dy)
    if (dist - distance) * (dist + distance) <= 0.0:
        return dx / dist, dy / dist
    speed = np.sqrt(wx * wx + wy * wy)
    ux, uy = wx / speed, wy / speed
    across = ux * dy - uy * dx                          # w_hat x d = d_c . w_perp
    p = abs(across)
    along = -np.sqrt((distance - p) * (distance + p))   # d_c . w_hat
    nx, ny = along * ux - across * uy, along * uy + across * ux
    norm = np.hypot(nx, ny)                             # = D, to round-off
    return nx / norm, ny / norm


@njit(cache=True)
def disc_events(pos, vel, masses, radii, restitution, t_stop, max_events,
                sample_t, sample_pos, sample_vel, sample_events,
                record, ev_time, ev_i, ev_j, ev_vel, stats):
    """Run the impacts of n discs moving freely in a plane up to time t_stop, in place.

    pos, vel: (n, 2) centres [m] and velocities [m/s] at t = 0; on return at the last impact
    masses (n,) [kg]; radii (n,) [m]; restitution e in [0, 1] of every pair
    t_stop:   last time [s]: impacts at times <= t_stop are applied
    max_events: the run stops with status TOO_MANY after this many impacts
    sample_t: (K,) increasing sample times [s]; sample_pos, sample_vel (K, n, 2); sample_events (K,)
              impacts before each sample (a sample at an impact time shows the motion before it)
    record:   store every impact in ev_time (E,) [s], ev_i, ev_j (E,) the pair (i < j), ev_vel
              (E, n, 2) velocities after it (E >= the number of impacts)
    stats:    (2,) int64 out: impacts, status (DONE, STOPPED, TOO_MANY)
    Returns the time of the last impact [s] (0.0 when there is none).
    """
    n = pos.shape[0]
    n_samples = sample_t.shape[0]
    e1 = 1.0 + restitution
    t = 0.0
    t_last = 0.0
    events = 0
    s = 0
    status = DONE
    while True:
        # Earliest time of impact over every pair (the first pair in order on a tie).
        dt = np.inf
        hit_i = -1
        hit_j = -1
        for i in range(n):
            for j in range(i + 1, n):
                tk = disc_time_of_impact(pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1],
                                         vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1], radii[i] + radii[j])
                if tk < dt:
                    dt = tk
                    hit_i = i
                    hit_j = j
        t_hit = t + dt
        if hit_i < 0 or t_hit > t_stop:
            status = DONE if hit_i < 0 else STOPPED
            break
        if events >= max_events:
            status = TOO_MANY
            break
        while s < n_samples and sample_t[s] <= t_hit:
            tau = sample_t[s] - t
            for i in range(n):
                for a in range(2):
                    sample_pos[s, i, a] = pos[i, a] + vel[i, a] * tau
                    sample_vel[s, i, a] = vel[i, a]
            sample_events[s] = events
            s += 1
        # Line of centres at the contact, from the state before the free motion to it.
        i, j = hit_i, hit_j
        nx, ny = disc_contact_normal(pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1],
                                     vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1], radii[i] + radii[j])
        for k in range(n):
            for a in range(2):
                pos[k, a] += vel[k, a] * dt
        t = t_hit
        t_last = t
        # Impulse along the line of centres n, closing speed c = (v_i - v_j).n reversed and scaled by e.
        c = (vel[i, 0] - vel[j, 0]) * nx + (vel[i, 1] - vel[j, 1]) * ny
        total = masses[i] + masses[j]
        ki, kj = e1 * masses[j] / total * c, e1 * masses[i] / total * c
        vel[i, 0] -= ki * nx
        vel[i, 1] -= ki * ny
        vel[j, 0] += kj * nx
        vel[j, 1] += kj * ny
        if record and events < ev_time.shape[0]:   # a short array is reported by the caller
            ev_time[events] = t
            ev_i[events] = i
            ev_j[events] = j
            for k in range(n):
                for a in range(2):
                    ev_vel[events, k, a] = vel[k, a]
        events += 1
    while s < n_samples:
        tau = sample_t[s] - t
        for i in range(n):
            for a in range(2):
                sample_pos[s, i, a] = pos[i, a] + vel[i, a] * tau
                sample_vel[s, i, a] = vel[i, a]
        sample_events[s] = events
        s += 1
    stats[0] = events
    stats[1] = status
    return t_last


@dataclass(frozen=True)
class DiscRun:
    """Result of one run of `Discs.run`.

    t_last: time of the last impact [s] (0 if none); events: impact count; status: DONE (no further
    impact possible), STOPPED (t_stop reached) or TOO_MANY.
    samples: positions (K, n, 2) [m], velocities (K, n, 2) [m/s], collisions (K,) impacts before each
      sample time (empty when no sample times were given).
    event_arrays: time (E,) [s], i, j (E,) the pair, velocities (E, n, 2) after each impact [m/s]
      (empty when not recorded).
    """

    t_last: float
    events: int
    status: int
    samples: dict = field(default_factory=dict)
    event_arrays: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Discs:
    """n discs moving freely in a plane (no external force, no friction), impacts found exactly.

    masses (n,) [kg], radii (n,) [m], restitution e in [0, 1] of every pair.
    """

    masses: np.ndarray
    radii: np.ndarray
    restitution: float

    @property
    def n(self) -> int:
        return self.masses.size

    def run(self, positions: np.ndarray, velocities: np.ndarray, *, t_stop: float,
            sample_t: np.ndarray | None = None, record: bool = False, max_events: int = 10**7,
            expected_events: int | None = None) -> DiscRun:
        """Run the compiled event loop from positions (n, 2) [m] and velocities (n, 2) [m/s] at t = 0.

        sample_t (K,) [s]: sample times (none: count only); record: keep every impact (the arrays are
        sized by expected_events, found with a counting run when not given)."""
        n = self.n
        if record and expected_events is None:
            expected_events = self.run(positions, velocities, t_stop=t_stop, max_events=max_events).events
        size = int(expected_events) if record else 0
        sample_t = np.zeros(0) if sample_t is None else np.ascontiguousarray(sample_t, dtype=np.float64)
        k = sample_t.size
        pos = np.array(positions, dtype=np.float64).reshape(n, 2)
        vel = np.array(velocities, dtype=np.float64).reshape(n, 2)
        stats = np.zeros(2, dtype=np.int64)
        samples = {"positions": np.empty((k, n, 2)), "velocities": np.empty((k, n, 2)),
                   "collisions": np.empty(k, dtype=np.int64)}
        ev = {"time": np.empty(size), "i": np.empty(size, dtype=np.int32), "j": np.empty(size, dtype=np.int32),
              "velocities": np.empty((size, n, 2))}
        t_last = disc_events(pos, vel, np.ascontiguousarray(self.masses, dtype=np.float64),
                             np.ascontiguousarray(self.radii, dtype=np.float64), float(self.restitution),
                             float(t_stop), int(max_events), sample_t, samples["positions"],
                             samples["velocities"], samples["collisions"], bool(record), ev["time"], ev["i"],
                             ev["j"], ev["velocities"], stats)
        if record and stats[0] != size:
            raise SimulationError(f"the recording run found {stats[0]} impacts, the counting run {size}")
        return DiscRun(t_last=float(t_last), events=int(stats[0]), status=int(stats[1]),
                       samples=samples if k else {}, event_arrays=ev if record else {})
