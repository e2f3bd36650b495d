"""Collisions on a line, and the chapter's bouncing balls that count the digits of pi.

Balls move on a frictionless horizontal line (the world x axis) between fixed walls. Between
impacts they move freely; each impact is found exactly, t = gap / closing speed, and resolved by the
chapter's one-dimensional collision with coefficient of restitution e (momentum conserved, relative
velocity reversed and scaled by e; a wall is a body of infinite mass). There is no time step: the
`dt` given to `simulate` only sets where the trajectory is sampled (rbody.engine.events).

The line is horizontal and every ball slides along x, so gravity (along -z) does no work and the
energy is the kinetic energy sum 1/2 m v^2.

The pi scene (the chapter, section 5.2.2, after Galperin's "Playing pool with pi"): a heavy ball M,
a light ball m, a wall. With x = m/M, a wall bounce and the next ball-ball impact map the
velocities linearly, (u_n+1, v_n+1) = A (u_n, v_n), so (u_n, v_n) = A^n (u_0, 0) with

    A = 1/(1+x) [[1-x, -2x], [2, 1-x]],   eigenvalues e^(+-i theta),  cos(theta) = (1-x)/(1+x),
    u_n = u_0 cos(n theta),   v_n = (u_0 / sqrt(x)) sin(n theta),

where u_n, v_n are the heavy and light velocities just after the n-th ball-ball impact (the light
ball then meets the wall and comes back with -v_n). theta = 2 arctan(sqrt(x)) is the same angle,
written without the cancellation of 1 - cos(theta) for small x. In the coordinates
(sqrt(M) X, sqrt(m) x) the motion is a billiard in a wedge of angle alpha = arctan(sqrt(x)); unfolded,
it is a straight line, which gives the exact state at any time and the exact counts:
#{k >= 1: k alpha < pi} impacts in all, and the heavy ball turns round at the first ball-ball
impact n with cos(n theta) < 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from rbody.checks import finite_array, in_interval, nonnegative, one_of, positive, representable, scene_arguments
from rbody.engine.events import DONE, TOO_MANY, Line, LineRun, exact_line, sample_times
from rbody.errors import SimulationError
from rbody.inertia import Inertia
from rbody.layout import Body, Contact, Joint, Layout, Shape
from rbody.optional import optional
from rbody.poses import observed
from rbody.scene import Scene
from rbody.trajectory import Trajectory

# Radius [m] given in the layout to a ball of radius 0 (MuJoCo and pymunk need a size); the layout
# shifts the balls so that every surface gap is that of the scene.
LAYOUT_RADIUS = 0.05
# Half sizes [m] of the thin box that stands for a wall; its face lies at the wall position.
WALL_HALF_SIZES = (0.05, 0.5, 0.5)
# Event arrays are kept when they take at most this many bytes (record_events=None).
MAX_EVENT_BYTES = 512 * 2**20
# Event kinds in Trajectory.events["kind"].
BALL_BALL, BALL_WALL = 0, 1


@dataclass(frozen=True, kw_only=True)
class LineCollisions(Scene):
    """Balls on the world x axis between walls, impacts found exactly.

    masses (n,) [kg] > 0; positions (n,) centres at t = 0, increasing [m]; velocities (n,) [m/s];
    radii (n,) [m] >= 0; walls: positions of fixed walls [m], each with every ball on one side of
    it (only the nearest wall on each side can be reached); restitution e in [0, 1];
    max_events: a run stops with SimulationError beyond this many impacts (inelastic collapse, e < 1:
    infinitely many impacts in a finite time; 10^8 impacts take a few seconds).
    t_end None: run until no further impact is possible; t_end is then 1.1 times the time of the
    last impact (1 s when there is none), so the samples show the final free motion.
    """

    masses: Any
    positions: Any
    velocities: Any
    radii: Any = 0.0
    walls: Any = (0.0,)
    restitution: float = 1.0
    max_events: int = 10**8
    t_end: Any = None

    observables: ClassVar[tuple[str, ...]] = ("positions", "velocities", "energy", "collisions")
    main_observable: ClassVar[str] = "positions"
    event_driven: ClassVar[bool] = True

    def __post_init__(self) -> None:
        masses = finite_array(self.masses, "masses", ndim=1)
        if masses.size == 0:
            raise ValueError("masses=[]: a line needs at least one ball")
        positive(masses, "masses")
        n = masses.size
        x = finite_array(self.positions, "positions", shape=(n,))
        v = finite_array(self.velocities, "velocities", shape=(n,))
        radii = finite_array(self.radii, "radii")
        if radii.shape not in ((), (n,)):
            raise ValueError(f"radii has shape {radii.shape}: expected one radius or one per ball ({n},)")
        radii = np.broadcast_to(np.asarray(nonnegative(radii, "radii"), dtype=np.float64), (n,)).copy()
        walls = finite_array(self.walls, "walls").reshape(-1)
        restitution = in_interval(self.restitution, "restitution", 0.0, 1.0, closed=True)
        if (not isinstance(self.max_events, (int, np.integer)) or isinstance(self.max_events, bool)
                or self.max_events < 1):
            raise ValueError(f"max_events={self.max_events!r}: expected a whole number >= 1")
        for k in range(1, n):
            if x[k] < x[k - 1]:
                raise ValueError(f"positions: balls {k - 1} and {k} are not in order (x={float(x[k - 1])!r} then "
                                 f"x={float(x[k])!r}); give the balls from left to right")
            gap = x[k] - x[k - 1] - (radii[k - 1] + radii[k])
            # Touching balls (gap 0) are allowed; a gap of -1 ulp is how touching rounds.
            if gap < -4 * np.finfo(float).eps * max(abs(x[k]), abs(x[k - 1]), radii[k - 1] + radii[k]):
                raise ValueError(f"positions: balls {k - 1} and {k} overlap at t = 0 (centres {float(x[k - 1])!r} and "
                                 f"{float(x[k])!r} m, radii {float(radii[k - 1])!r} and {float(radii[k])!r} m, gap {gap:.6g} m)")
        lo, hi = -np.inf, np.inf
        for w in walls:
            if np.all(x - radii > w):
                lo = max(lo, w)
            elif np.all(x + radii < w):
                hi = min(hi, w)
            else:
                touching = (x - radii <= w) & (x + radii >= w)
                if np.any(touching):
                    i = int(np.argmax(touching))
                    raise ValueError(f"walls: ball {i} (centre {float(x[i])!r} m, radius {float(radii[i])!r} m) is on "
                                     f"or through the wall at {float(w)!r} m; every ball must start strictly on one "
                                     "side of every wall")
                i = int(np.argmax(x > w)) - 1
                raise ValueError(f"walls: the wall at {float(w)!r} m lies between balls {i} and {i + 1}; every ball must "
                                 "start on the same side of each wall")
        for name, value in (("masses", masses), ("positions", x), ("velocities", v), ("radii", radii),
                            ("walls", walls)):
            object.__setattr__(self, name, tuple(float(u) for u in value))
        object.__setattr__(self, "restitution", float(restitution))
        object.__setattr__(self, "_line", Line(masses=masses, radii=radii, restitution=float(restitution),
                                               wall_lo=float(lo), wall_hi=float(hi)))
        self._check_more()
        final = None
        if self.t_end is None:
            if np.isfinite(lo) and np.isfinite(hi) and np.any(v != 0):
                raise ValueError(f"t_end=None with walls on both sides ({float(lo)!r} and {float(hi)!r} m): the balls bounce "
                                 "between them for ever; give t_end")
            final = self._run(t_stop=np.inf)
            object.__setattr__(self, "t_end", 1.1 * final.t_last if final.t_last > 0 else 1.0)
        object.__setattr__(self, "_final", final)
        super().__post_init__()

    def _check_more(self) -> None:
        """Subclasses check their own parameters here, before any run."""

    # ----- the model ---------------------------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of balls."""
        return len(self.masses)

    @property
    def line(self) -> Line:
        """The balls, radii, restitution and the reachable walls, as the event engine takes them."""
        return self._line

    @property
    def watch(self) -> int:
        """Ball whose first reversal the runs report (-1: none)."""
        return -1

    def energy_of(self, velocities: np.ndarray) -> np.ndarray:
        """Kinetic energy sum 1/2 m v^2 (...,) [J] of velocities (..., n) [m/s] (gravity does no work)."""
        return 0.5 * np.sum(np.asarray(self.masses) * np.asarray(velocities) ** 2, axis=-1)

    def _run(self, **kwargs) -> LineRun:
        run = self.line.run(np.array(self.positions), np.array(self.velocities), watch=self.watch,
                            max_events=self.max_events, **kwargs)
        if run.status == TOO_MANY:
            raise SimulationError(
                f"scene {self.describe()}: more than max_events={self.max_events} impacts before "
                f"t={kwargs.get('t_stop')} s (last at t={run.t_last:.6g} s); the balls may be in inelastic collapse "
                "(infinitely many impacts in finite time, e < 1) — give a shorter t_end or a larger max_events")
        return run

    def counts(self, t_end: float | None = None) -> dict[str, float | int]:
        """Impact counts of the compiled run up to t_end [s] (default: the scene's t_end): total,
        ball (ball-ball), wall, turn (ball-ball impacts up to the first reversal of the watched ball,
        -1 if none), t_last (time of the last impact [s]), done (no further impact is possible)."""
        if t_end is None:
            if self._final is None:  # the run to the scene's t_end, made once (a pi scene's t_end is exact)
                object.__setattr__(self, "_final", self._run(t_stop=self.t_end))
            run = self._final
        else:
            run = self._run(t_stop=self.t_end if t_end is None else float(finite_array(t_end, "t_end")))
        return {"total": run.events, "ball": run.ball, "wall": run.wall, "turn": run.turn,
                "t_last": run.t_last, "done": run.status == DONE}

    # ----- the run -----------------------------------------------------------------------------

    def run_events(self, t_end: float, sample_dt: float, *, record_events: bool | None = None) -> Trajectory:
        """The exact event-by-event run, sampled every sample_dt [s] from 0 to >= t_end [s].

        Samples (T,) at t_k = k sample_dt up to the first t_k >= t_end (as the time-stepped runs);
        impacts up to the last sample time are applied. Observables: positions (T, n) [m],
        velocities (T, n) [m/s], energy (T,) [J], collisions (T,) impacts before each sample
        (a sample at an impact time shows the motion just before it). events: time (E,) [s],
        kind (E,) (0 ball-ball, 1 ball-wall), i (E,) the (left) ball, j (E,) the right ball or -1 for
        a wall, velocities (E, n) just after each impact [m/s].
        record_events: True keep every impact; False none; None keep them when the arrays take at
        most MAX_EVENT_BYTES (meta["events_recorded"] says which; meta["event_count"] is the count).
        """
        t = sample_times(t_end, sample_dt)
        sample_dt = float(sample_dt)
        final = self._final
        per_event = 8 + 4 + 8 * self.n
        estimate = self.expected_events(t[-1])
        if final is not None and final.status == DONE and t[-1] >= final.t_last:
            count = final.events
        elif record_events is False or (record_events is None and estimate * per_event > MAX_EVENT_BYTES):
            count = None  # not recorded: no counting run is needed
        else:
            count = self._run(t_stop=t[-1]).events
        record = bool(record_events) if record_events is not None else (
            count is not None and count * per_event <= MAX_EVENT_BYTES)
        run = self._run(t_stop=t[-1], sample_t=t, record=record, expected_events=count)
        samples = run.samples
        data = {"positions": self.line.positions(samples["gaps"], samples["x0"]),
                "velocities": samples["velocities"],
                "energy": self.energy_of(samples["velocities"]),
                "collisions": samples["collisions"],
                "ball_collisions": samples["ball_collisions"]}
        events = {}
        if record:
            gap = run.event_arrays["gap"]
            wall = (gap == 0) | (gap == self.n)
            events = {"time": run.event_arrays["time"],
                      "kind": np.where(wall, BALL_WALL, BALL_BALL).astype(np.int8),
                      "i": np.where(gap == 0, 0, gap - 1).astype(np.int32),
                      "j": np.where(wall, -1, gap).astype(np.int32),
                      "velocities": run.event_arrays["velocities"]}
        data, events = self._named(data, events)
        meta = {"scene": self.name, "backend": "rbody", "method": "events", "dt": sample_dt,
                "event_count": run.events, "ball_collisions": run.ball, "wall_collisions": run.wall,
                "turn": run.turn, "events_recorded": record, "t_last_event": run.t_last,
                "done": run.status == DONE}
        return Trajectory(t, data, events, meta)

    def expected_events(self, t_end: float) -> int:
        """Impacts up to t_end [s] known before any run, to size the work (0: not known; a line of balls
        in general has to be run to be counted, within max_events)."""
        return 0

    def _named(self, data: dict, events: dict) -> tuple[dict, dict]:
        """The scene's observables from the sampled run (subclasses add their own names)."""
        data = {name: data[name] for name in self.observables}
        return data, events

    # ----- exact solution ---------------------------------------------------------------------------

    def exact(self, t: ArrayLike, *, max_events: int = 10_000) -> dict[str, np.ndarray]:
        """The same observables at times t (T,) [s] from the run in exact rational arithmetic
        (rbody.engine.events.exact_line): no round-off but the final conversion to float.
        ValueError beyond max_events impacts (it is meant for small runs)."""
        t = finite_array(t, "t").reshape(-1)
        out = exact_line(self.line, np.array(self.positions), np.array(self.velocities), t, max_events=max_events)
        data, _ = self._named(out, {})
        return data

    # ----- what other simulators build ------------------------------------------------------------

    def _layout(self) -> Layout:
        """One sphere per ball on a slide joint "x_<i>" along world x (reference pose at the ball's
        start, qpos0 = 0, qvel0 its velocity), the reachable walls as thin fixed boxes whose face lies
        at the wall, frictionless contacts between neighbours and between each wall and the ball next
        to it, with the scene's restitution. Balls of radius 0 get LAYOUT_RADIUS, and the layout
        moves the balls (and a right wall) so that every surface gap is the scene's: a joint's qpos is
        still the displacement of its ball, so observe() is unchanged."""
        line, n = self.line, self.n
        radius = np.where(line.radii > 0, line.radii, LAYOUT_RADIUS)
        gaps = line.gaps(np.array(self.positions))
        # Anchored at the left wall if there is one (a right wall then moves by the added radii), else
        # at the right wall, else at ball 0.
        anchor_hi = np.inf if np.isfinite(line.wall_lo) else line.wall_hi
        layout_line = Line(masses=line.masses, radii=radius, restitution=line.restitution,
                           wall_lo=line.wall_lo, wall_hi=anchor_hi)
        x = layout_line.positions(gaps, np.array(self.positions[0]))
        wall_hi = x[-1] + radius[-1] + gaps[-1] if np.isfinite(line.wall_hi) else np.inf
        bodies, joints, contacts, fixed = [], [], [], []
        for i in range(n):
            name = f"ball_{i}"
            shape = Shape(name, "sphere", (float(radius[i]),))
            bodies.append(Body(name, Inertia.solid_sphere(float(line.masses[i]), float(radius[i])),
                               shapes=(shape,), pos=(float(x[i]), 0.0, 0.0)))
            joints.append(Joint(f"x_{i}", "slide", name, axis=(1.0, 0.0, 0.0), qpos0=0.0,
                                qvel0=float(self.velocities[i])))
            if i > 0:
                contacts.append(Contact(f"ball_{i - 1}", name, friction=0.0, restitution=self.restitution))
        half = WALL_HALF_SIZES[0]
        if np.isfinite(line.wall_lo):
            fixed.append(Shape("wall_lo", "box", WALL_HALF_SIZES, pos=(line.wall_lo - half, 0.0, 0.0)))
            contacts.append(Contact("wall_lo", "ball_0", friction=0.0, restitution=self.restitution))
        if np.isfinite(wall_hi):
            fixed.append(Shape("wall_hi", "box", WALL_HALF_SIZES, pos=(float(wall_hi) + half, 0.0, 0.0)))
            contacts.append(Contact(f"ball_{n - 1}", "wall_hi", friction=0.0, restitution=self.restitution))
        return Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=tuple(fixed), contacts=tuple(contacts))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        """positions (T, n) = start + qpos of "x_<i>", velocities (T, n) = its qvel, energy (T,).
        Impacts are not states: a backend counts them itself (contact onsets)."""
        q = np.stack([np.asarray(joints[f"x_{i}"][0], dtype=float) for i in range(self.n)], axis=-1)
        qd = np.stack([np.asarray(joints[f"x_{i}"][1], dtype=float) for i in range(self.n)], axis=-1)
        return self._observed(q + np.array(self.positions), qd)

    def _observed(self, positions: np.ndarray, velocities: np.ndarray) -> dict[str, np.ndarray]:
        return {"positions": positions, "velocities": velocities, "energy": self.energy_of(velocities)}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Slide "x_<i>" is ball i's displacement from its start: positions (T, n) - positions at t = 0."""
        moved = observed(self, trajectory, "positions", (self.n,)) - np.asarray(self.positions, dtype=np.float64)
        return {f"x_{i}": moved[:, i] for i in range(self.n)}

    def describe(self) -> str:
        return (f"{self.name}(n={self.n}, masses={list(self.masses)}, e={self.restitution:g}, "
                f"walls={list(self.walls)})")


def line_collisions(masses: ArrayLike, positions: ArrayLike, velocities: ArrayLike, *, radii: ArrayLike = 0.0,
                    walls: ArrayLike = (0.0,), restitution: float = 1.0,
                    t_end: float | None = None, gravity: float = 9.81, max_events: int = 10**8) -> LineCollisions:
    """Balls on a frictionless horizontal line (world x) with fixed walls, impacts found exactly.

    masses (n,) [kg]; positions (n,) centres at t = 0, left to right, not overlapping [m];
    velocities (n,) [m/s]; radii scalar or (n,) [m]; walls: wall positions [m], every ball strictly on
    one side of each; restitution e in [0, 1] (1 elastic); t_end [s] or None: until no further impact
    is possible (then t_end = 1.1 x the last impact time; ValueError with walls on both sides);
    gravity [m/s^2] does no work on the horizontal line. simulate(scene, dt=...) samples every dt.
    """
    scene_arguments(gravity, t_end)
    return representable(LineCollisions(name="line_collisions", t_end=t_end, gravity=gravity, masses=masses,
                          positions=positions, velocities=velocities, radii=radii, walls=walls,
                          restitution=restitution, max_events=max_events), exact=False)


# ----- the digits of pi ---------------------------------------------------------------------------

CONVENTIONS = ("galperin", "chapter")
MAX_DIGITS = 11  # 100**digits (and 16 x 100**digits) is a float exactly up to here


def _whole_number(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}={value!r}: expected a whole number (int)")
    return int(value)


@dataclass(frozen=True, kw_only=True)
class PiCollisions(LineCollisions):
    """The chapter's heavy and light balls and a wall (section 5.2.2), counting the digits of pi.

    digits N >= 0; light_mass m [kg]; speed [m/s] of the heavy ball at t = 0; radius [m] of both
    balls; spacing s [m]. convention "galperin": M = 100^N m, the wall at x = 0, the light ball at
    x = s at rest, the heavy ball at x = 2 s moving towards the wall; the count is every impact (ball-ball and
    wall), floor(pi 10^N). "chapter": M = 16 x 100^N m, the heavy ball at x = 0 kicked to the right,
    the light ball at x = s, the wall at x = 2 s; the count p(N) is the number of ball-ball impacts
    until the heavy ball turns round, p(N) - 1 = floor(pi 10^N). The masses, positions and
    velocities are derived here; t_end None (the factory's): the run goes on until no further impact
    is possible.
    """

    digits: int
    convention: str = "galperin"
    light_mass: float = 1.0
    speed: float = 1.0
    radius: float = 0.05
    spacing: float = 1.0
    masses: Any = ()
    positions: Any = ()
    velocities: Any = ()
    walls: Any = ()

    observables: ClassVar[tuple[str, ...]] = ("positions", "velocities", "energy", "collisions",
                                              "ball_collisions", "u", "v")
    main_observable: ClassVar[str] = "collisions"

    def __post_init__(self) -> None:
        digits = _whole_number(self.digits, "digits")
        if not 0 <= digits <= MAX_DIGITS:
            raise ValueError(f"digits={digits}: must lie in [0, {MAX_DIGITS}] (the mass ratio 100^digits must be "
                             "a float exactly; 10^digits x pi impacts take about 10^digits x 30 ns)")
        one_of(self.convention, "convention", CONVENTIONS)
        light = positive(self.light_mass, "light_mass")
        speed = positive(self.speed, "speed")
        radius = nonnegative(self.radius, "radius")
        spacing = positive(self.spacing, "spacing")
        if not radius < 0.45 * spacing:
            raise ValueError(f"radius={radius!r}: must be < 0.45 spacing = {0.45 * spacing!r} m so that the balls, "
                             f"{spacing!r} m apart, and the wall do not touch at t = 0")
        ratio = float(100**digits) * (16.0 if self.convention == "chapter" else 1.0)
        heavy = light * ratio
        if self.convention == "galperin":
            masses, x, v, walls = (light, heavy), (spacing, 2 * spacing), (0.0, -speed), (0.0,)
        else:
            masses, x, v, walls = (heavy, light), (0.0, spacing), (speed, 0.0), (2 * spacing,)
        for name, value in (("digits", digits), ("light_mass", light), ("speed", speed), ("radius", radius),
                            ("spacing", spacing),
                            ("masses", masses), ("positions", x), ("velocities", v), ("walls", walls),
                            ("radii", radius)):
            object.__setattr__(self, name, value)
        # Room for the exact count (about pi 10^N impacts), a guard, not a limit.
        object.__setattr__(self, "max_events", 2 * 4 * 10**digits * (4 if self.convention == "chapter" else 1) + 100)
        if self.t_end is None:  # 1.1 x the last impact, from the closed form: no run of pi 10^N impacts here
            object.__setattr__(self, "t_end", 1.1 * self.last_impact_time)
        super().__post_init__()

    def _check_more(self) -> None:
        if self.restitution != 1.0:
            raise ValueError(f"restitution={self.restitution!r}: the pi count needs elastic impacts (1.0)")

    # ----- which ball is which ----------------------------------------------------------------------

    @property
    def heavy(self) -> int:
        """Index of the heavy ball (1 galperin, 0 chapter); the light one is 1 - heavy."""
        return 1 if self.convention == "galperin" else 0

    @property
    def light(self) -> int:
        return 1 - self.heavy

    @property
    def watch(self) -> int:
        return self.heavy

    @property
    def mass_ratio(self) -> float:
        """x = m / M [-] of the simulated masses."""
        return self.masses[self.light] / self.masses[self.heavy]

    # ----- counts -------------------------------------------------------------------------------------

    def count(self) -> int:
        """The simulated count of the convention: every impact (galperin) or the ball-ball impacts until
        the heavy ball turns round (chapter), from the compiled run to the end."""
        counts = self.counts()
        return counts["total"] if self.convention == "galperin" else counts["turn"]

    @cached_property
    def expected_collisions(self) -> int:
        """The exact count of the convention: floor(pi 10^N) (galperin), or p(N), the smallest n with
        cos(n theta) < 0, theta = 2 arctan(sqrt(x)), x = 1/(16 100^N) (chapter) — in exact integer and
        high-precision arithmetic (mpmath), not with float pi."""
        mpmath = optional("mpmath", "exact", "the exact collision counts (high-precision arithmetic)")

        n = self.digits
        with mpmath.workdps(n + 40):
            if self.convention == "galperin":
                return _floor_exact(mpmath.pi * mpmath.mpf(10) ** n)
            alpha = mpmath.atan(1 / (4 * mpmath.mpf(10) ** n))  # theta/2 = arctan(sqrt(x))
            return _floor_exact(mpmath.pi / (4 * alpha)) + 1

    @cached_property
    def exact_counts(self) -> dict[str, int]:
        """Exact counts for the simulated masses, from the unfolded wedge of angle
        alpha = arctan(sqrt(m/M)): total #{k >= 1: k alpha < pi}, ball (odd k), wall (even k), and
        turn, the first ball-ball impact n with cos(2 n alpha) < 0 (the heavy ball turns round)."""
        mpmath = optional("mpmath", "exact", "the exact collision counts (high-precision arithmetic)")

        with mpmath.workdps(self.digits + 40):
            alpha = mpmath.atan(mpmath.sqrt(mpmath.mpf(self.masses[self.light]) / mpmath.mpf(self.masses[self.heavy])))
            ratio = mpmath.pi / alpha
            whole = _floor_exact(ratio)
            total = whole - 1 if _is_whole(ratio) else whole
            turn = _floor_exact(mpmath.pi / (4 * alpha)) + 1
        return {"total": total, "ball": (total + 1) // 2, "wall": total // 2, "turn": turn}

    def exact_velocities(self, n: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The chapter's closed form after n ball-ball impacts, n (K,) whole numbers >= 0:
        (u_n, v_n) = A^n (u_0, 0): u_n = u_0 cos(n theta), v_n = (u_0 / sqrt(x)) sin(n theta),
        theta = 2 arctan(sqrt(x)), x = m/M, u_0 the heavy ball's initial velocity (world x).
        u (K,) heavy, v (K,) light ball velocity along world x just after the n-th impact [m/s]
        (in the chapter's frame v_n is the light ball's speed towards the wall)."""
        n_arr = np.asarray(n)
        if n_arr.dtype.kind not in "iu" or np.any(n_arr < 0):
            raise ValueError(f"n={n!r}: expected whole numbers >= 0")
        limit = self.exact_counts["ball"]
        if np.any(n_arr > limit):
            raise ValueError(f"n={n!r}: only {limit} ball-ball impacts happen in this scene")
        x = self.mass_ratio
        theta = 2 * np.arctan(np.sqrt(x))
        u0 = self.velocities[self.heavy]
        return u0 * np.cos(n_arr * theta), u0 / np.sqrt(x) * np.sin(n_arr * theta)

    def expected_events(self, t_end: float) -> int:
        """The exact count of every impact (at most; fewer when t_end is before the last one)."""
        return self.exact_counts["total"]

    @cached_property
    def last_impact_time(self) -> float:
        """Time of the last impact [s], exact (mpmath), from the unfolded billiard (see exact()): the K-th
        impact, K = exact_counts["total"], is where the straight line P(t) = P0 + W t reaches the polar
        angle K alpha: (P0 + W t) x d = 0 with d = (cos K alpha, sin K alpha), t = (d x P0) / (W x d)."""
        mpmath = optional("mpmath", "exact", "the exact collision counts (high-precision arithmetic)")

        with mpmath.workdps(self.digits + 30):
            sm, sM, alpha, a0, b0, va0, ub0 = self._wedge()
            k = self.exact_counts["total"]
            d1, d2 = mpmath.cos(k * alpha), mpmath.sin(k * alpha)
            p1, p2 = sM * b0, sm * a0
            w1, w2 = sM * ub0, sm * va0
            return float((d1 * p2 - d2 * p1) / (w1 * d2 - w2 * d1))

    def _wedge(self):
        """sqrt(m), sqrt(M), alpha = atan(sqrt(m/M)), and the light (a) and heavy (b) balls' distances from first
        contact and velocities a0, b0, va0, ub0, in the frame with the wall on the left (mpmath)."""
        mpmath = optional("mpmath", "exact", "the exact collision counts (high-precision arithmetic)")

        sign = 1.0 if self.convention == "galperin" else -1.0   # mirror the chapter's frame
        w, r = self.walls[0], self.radius
        h, l = self.heavy, self.light
        mp = mpmath.mpf
        sm, sM = mpmath.sqrt(mp(self.masses[l])), mpmath.sqrt(mp(self.masses[h]))
        a0 = mp(sign * (self.positions[l] - w) - r)
        b0 = mp(sign * (self.positions[h] - w) - 3 * r)
        return sm, sM, mpmath.atan(sm / sM), a0, b0, mp(sign * self.velocities[l]), mp(sign * self.velocities[h])

    # ----- observables --------------------------------------------------------------------------------

    def _named(self, data: dict, events: dict) -> tuple[dict, dict]:
        velocities = data["velocities"]
        data = dict(data, u=velocities[..., self.heavy], v=velocities[..., self.light])
        if events:
            events = dict(events, u=events["velocities"][:, self.heavy], v=events["velocities"][:, self.light])
        return {name: data[name] for name in self.observables}, events

    def _observed(self, positions: np.ndarray, velocities: np.ndarray) -> dict[str, np.ndarray]:
        out = super()._observed(positions, velocities)
        out.update(u=velocities[..., self.heavy], v=velocities[..., self.light])
        return out

    def exact(self, t: ArrayLike, **_: Any) -> dict[str, np.ndarray]:
        """Observables at times t (T,) [s] from the unfolded billiard (mpmath, then rounded to float).

        In the frame where the wall is at the left (the chapter's is mirrored), with a the light
        ball's and b the heavy ball's distance from first contact (a = 0 at the wall, b = a at
        contact), the point P = (sqrt(M) b, sqrt(m) a) moves in the wedge 0 <= angle <= alpha,
        tan(alpha) = sqrt(m/M), reflected at its sides. Unfolded, P(t) = P(0) + W t is a straight line;
        its polar angle phi has crossed k = floor(phi/alpha) sides (impacts; odd k ball-ball, even
        wall), and folding back rotates by -k alpha (k even) or reflects onto (k+1) alpha - phi (k odd).
        collisions counts the impacts before t (a sample at an impact time shows the motion before it).
        """
        mpmath = optional("mpmath", "exact", "the exact collision counts (high-precision arithmetic)")

        t = finite_array(t, "t").reshape(-1)
        sign = 1.0 if self.convention == "galperin" else -1.0   # mirror the chapter's frame
        w = self.walls[0]
        r = self.radius
        h, l = self.heavy, self.light
        a0 = sign * (self.positions[l] - w) - r
        b0 = sign * (self.positions[h] - w) - 3 * r
        va0, ub0 = sign * self.velocities[l], sign * self.velocities[h]
        out = {name: np.empty(t.size) for name in ("a", "b", "va", "ub")}
        collisions = np.empty(t.size, dtype=np.int64)
        with mpmath.workdps(self.digits + 30):
            mp = mpmath.mpf
            sm, sM = mpmath.sqrt(mp(self.masses[l])), mpmath.sqrt(mp(self.masses[h]))
            alpha = mpmath.atan(sm / sM)
            w1, w2 = sM * mp(ub0), sm * mp(va0)
            speed, beta = mpmath.hypot(w1, w2), mpmath.atan2(w2, w1)
            for s, ts in enumerate(t):
                p1, p2 = sM * (mp(b0) + mp(ub0) * mp(ts)), sm * (mp(a0) + mp(va0) * mp(ts))
                rho, phi = mpmath.hypot(p1, p2), mpmath.atan2(p2, p1)
                k = int(mpmath.floor(phi / alpha))
                if k % 2 == 0:
                    psi, direction = phi - k * alpha, beta - k * alpha
                else:
                    psi, direction = (k + 1) * alpha - phi, (k + 1) * alpha - beta
                out["b"][s] = float(rho * mpmath.cos(psi) / sM)
                out["a"][s] = float(rho * mpmath.sin(psi) / sm)
                out["ub"][s] = float(speed * mpmath.cos(direction) / sM)
                out["va"][s] = float(speed * mpmath.sin(direction) / sm)
                collisions[s] = k
        positions, velocities = np.empty((t.size, 2)), np.empty((t.size, 2))
        positions[:, l] = w + sign * (out["a"] + r)
        positions[:, h] = w + sign * (out["b"] + 3 * r)
        velocities[:, l], velocities[:, h] = sign * out["va"], sign * out["ub"]
        data = {"positions": positions, "velocities": velocities, "energy": self.energy_of(velocities),
                "collisions": collisions, "ball_collisions": (collisions + 1) // 2,
                "u": velocities[:, h], "v": velocities[:, l]}
        return data

    def describe(self) -> str:
        return (f"{self.name}(digits={self.digits}, convention={self.convention!r}, "
                f"M/m={self.masses[self.heavy] / self.masses[self.light]:g}, speed={self.speed:g} m/s)")


def _is_whole(value) -> bool:
    """value (mpmath) equal to a whole number to within the working precision (exact cases like
    equal masses, alpha = pi/4)."""
    import mpmath

    return abs(value - mpmath.nint(value)) < mpmath.mpf(10) ** (-(mpmath.mp.dps // 2))


def _floor_exact(value) -> int:
    """floor of an mpmath value, with a whole number recognised as such."""
    import mpmath

    if _is_whole(value):
        return int(mpmath.nint(value))
    return int(mpmath.floor(value))


def pi_collisions(digits: int, *, light_mass: float = 1.0, speed: float = 1.0, convention: str = "galperin",
                  radius: float = 0.05, spacing: float = 1.0, gravity: float = 9.81) -> PiCollisions:
    """The chapter's heavy ball, light ball and wall, whose impacts count the digits of pi.

    digits N >= 0 (whole); light_mass [kg]; speed [m/s] of the heavy ball (10**-N keeps the light ball
    near 1 m/s); convention "galperin" (M = 100^N m, count every impact: floor(pi 10^N)) or "chapter"
    (M = 16 x 100^N m, count the ball-ball impacts until the heavy ball turns round: p(N) =
    floor(pi 10^N) + 1); radius [m] of both balls; spacing [m] between the centres of the wall, the
    light ball and the heavy ball at t = 0 (the run lasts about 3 spacing / speed; the count does not
    depend on it); gravity [m/s^2] does no work on the horizontal line.
    The run goes on until no further impact is possible: scene.count() is the simulated count,
    scene.expected_collisions the exact one, scene.exact_velocities(n) the chapter's closed form.
    """
    scene_arguments(gravity)
    return representable(PiCollisions(name="pi_collisions", t_end=None, gravity=gravity, digits=digits, convention=convention,
                        light_mass=light_mass, speed=speed, radius=radius, spacing=spacing))
