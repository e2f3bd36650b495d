"""The chapter's bouncing balls (section 5.2.1): a small ball dropped on top of a large one.

A small ball of mass m rests on (or a small gap above) a large ball of mass M; both are dropped
together from rest, the large ball's bottom at height h above a floor, and every impact is elastic.
The chapter's idealisation: the large ball meets the floor at speed u = sqrt(2 g h), bounces back up
at u, and at once meets the small ball still falling at u. With velocities measured upwards,
energy and momentum,

    m u^2 + M u^2 = m v^2 + M V^2,    M u - m u = m v + M V,

divided as M (V - u)(V + u) = m (u - v)(u + v) by M (u - V) = m (v + u), give V + u = v - u and

    v = (3M - m) / (M + m) u,    V = (M - 3m) / (M + m) u,

so the small ball rises (v/u)^2 times as high as it fell: almost 3 times as fast and 9 times as high
when M >> m. (M = 3m leaves the large ball at rest on the floor and the small ball rises 4 h.)

Exact motion, with a gap d >= 0 between the balls at the start (the chapter's "very slightly
separated"): both fall freely; the large ball meets the floor at t1 = sqrt(2 h / g) at speed u and
reverses; the closing speed of the balls is then 2u, constant (the same gravity acts on both), so
they meet at t2 = t1 + d / (2u), with velocities u - g tau and -u - g tau, tau = d / (2u): the
relative velocity 2u is reversed, and

    v = (3M - m)/(M + m) u - g tau,    V = (M - 3m)/(M + m) u - g tau.

(d = 0 is the chapter's sequence exactly: the floor impact and the ball-ball impact happen at the
same instant, in that order.) Afterwards the small ball flies freely, a parabola, and the large ball
bounces on the floor elastically, a periodic train of parabolas of speed U = sqrt(V^2 + 2 g z) at the
floor. Between the large ball's floor impacts the gap between the balls changes linearly (gravity
cancels), so the balls meet again in the first bounce at whose end the small ball would be at or
below the contact level: that second ball-ball impact, found in closed form, ends the exact solution
(`exact_until`). The default duration is the time at which the small ball reaches its top.

Heights are those of the ball bottoms above the floor (the large ball's starts at h; the small
ball's at h + 2R + d), velocities are along world +z (up). The energy is the kinetic energy plus
M g z + m g z of the centres.

Native: the balls lie on a vertical line (world z) with the floor as a wall at 0 and gravity along
the line, run event by event (rbody.engine.events.Line with acceleration -g): ball-ball times of
impact are linear, the floor's the root of a quadratic, every impact exact.

Other simulators: two spheres on vertical slide joints (world z) above a floor plane, elastic
frictionless contacts floor-large and large-small (the small ball cannot reach the floor on the line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from rbody.checks import finite_array, nonnegative, positive, single_number, representable, scene_arguments
from rbody.engine.events import DONE, TOO_MANY, Line, LineRun, sample_times
from rbody.errors import SimulationError
from rbody.inertia import Inertia
from rbody.layout import Body, Contact, Joint, Layout, Shape
from rbody.poses import observed
from rbody.scene import Scene
from rbody.trajectory import Trajectory

# Event kinds in Trajectory.events["kind"].
BALL_BALL, FLOOR = 0, 1
# Half size of the drawn floor, in radii of the large ball (the contact is with the infinite plane).
FLOOR_HALF_SIZE = 5.0


@dataclass(frozen=True, kw_only=True)
class StackedBalls(Scene):
    """A small ball m dropped with a large ball M beneath it onto a floor, impacts elastic.

    large_mass M, small_mass m [kg] > 0; drop_height h [m] > 0 of the large ball's bottom; radii [m]
    > 0; gap d [m] >= 0 between the balls at the start, d < 8 h (so that they meet while the large
    ball rises from its first bounce); max_events: a run stops with SimulationError beyond this many
    impacts (M close to but not exactly 3m leaves the large ball bouncing with a tiny amplitude,
    ever faster). t_end None: the time at which the small ball reaches its top (`top_time`), or, if the
    balls meet again before it (`exact_until`), halfway to that second ball-ball impact.
    """

    large_mass: float
    small_mass: float
    drop_height: float
    radius_large: float = 0.1
    radius_small: float = 0.02
    gap: float = 0.0
    max_events: int = 10**6
    t_end: Any = None

    observables: ClassVar[tuple[str, ...]] = ("small_velocity", "large_velocity", "small_height", "large_height",
                                              "energy")
    main_observable: ClassVar[str] = "small_height"
    event_driven: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("large_mass", "small_mass", "drop_height", "radius_large", "radius_small"):
            object.__setattr__(self, name, single_number(getattr(self, name), name, positive))
        gap = single_number(self.gap, "gap", nonnegative)
        if not gap < 8 * self.drop_height:
            raise ValueError(f"gap={gap!r}: must be < 8 drop_height = {8 * self.drop_height!r} m, so that the balls "
                             "meet while the large ball rises from its first bounce (the chapter's sequence)")
        object.__setattr__(self, "gap", float(gap))
        gravity = finite_array(self.gravity, "gravity")
        if gravity.ndim != 0 or not gravity > 0:
            raise ValueError(f"gravity={self.gravity!r}: must be > 0 [m/s^2]; the balls are dropped")
        if (not isinstance(self.max_events, (int, np.integer)) or isinstance(self.max_events, bool)
                or self.max_events < 1):
            raise ValueError(f"max_events={self.max_events!r}: expected a whole number >= 1")
        if self.t_end is None:
            object.__setattr__(self, "gravity", float(gravity))
            object.__setattr__(self, "t_end", self._default_t_end())
        super().__post_init__()

    # ----- the model -----------------------------------------------------------------------------

    @property
    def masses(self) -> np.ndarray:
        """(2,) [kg]: large, small (bottom to top on the line)."""
        return np.array([self.large_mass, self.small_mass])

    @property
    def radii(self) -> np.ndarray:
        """(2,) [m]: large, small."""
        return np.array([self.radius_large, self.radius_small])

    @property
    def start_heights(self) -> np.ndarray:
        """(2,) heights of the bottoms at t = 0 [m]: large h, small h + 2R + d."""
        h = self.drop_height
        return np.array([h, h + 2 * self.radius_large + self.gap])

    @property
    def line(self) -> Line:
        """The balls on the vertical line: the floor a wall at 0, acceleration -g along the line."""
        return Line(masses=self.masses, radii=self.radii, restitution=1.0, wall_lo=0.0, wall_hi=np.inf,
                    acceleration=-self.gravity)

    def energy_of(self, heights: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """Energy (...,) [J] of bottom heights and velocities (..., 2) (large, small):
        sum 1/2 m v^2 + m g (z + r), the centres' potential energy above the floor."""
        m, r = self.masses, self.radii
        return np.sum(0.5 * m * np.asarray(velocities) ** 2 + m * self.gravity * (np.asarray(heights) + r), axis=-1)

    @property
    def energy(self) -> float:
        """The conserved energy [J] (both at rest at t = 0)."""
        return float(self.energy_of(self.start_heights, np.zeros(2)))

    # ----- the chapter's numbers ---------------------------------------------------------------------

    @property
    def speed_ratio(self) -> float:
        """The chapter's v/u = (3M - m)/(M + m) [-]: the small ball's rebound speed over its impact speed."""
        M, m = self.large_mass, self.small_mass
        return (3 * M - m) / (M + m)

    @property
    def height_ratio(self) -> float:
        """(v/u)^2 [-]: how many times as high as it fell the small ball rises (nearly 9 for M >> m)."""
        return self.speed_ratio**2

    @property
    def impact_speed(self) -> float:
        """u = sqrt(2 g h) [m/s]: speed of the large ball at the floor."""
        return math.sqrt(2 * self.gravity * self.drop_height)

    @cached_property
    def _sequence(self) -> dict[str, float]:
        """The closed-form sequence: impact times, the state after the ball-ball impact, the large
        ball's bounces and the second ball-ball impact (see the module docstring)."""
        g, h, d = self.gravity, self.drop_height, self.gap
        M, m = self.large_mass, self.small_mass
        u = self.impact_speed
        t1 = math.sqrt(2 * h / g)
        tau = d / (2 * u)                          # closing speed 2u, no relative acceleration
        z_large = u * tau - 0.5 * g * tau * tau    # large ball's bottom at the ball-ball impact
        v_small = (3 * M - m) / (M + m) * u - g * tau
        v_large = (M - 3 * m) / (M + m) * u - g * tau
        # The large ball then bounces: speed U at the floor, first floor impact s1 after t2, period P.
        U = math.sqrt(v_large * v_large + 2 * g * z_large)
        if v_large >= 0:
            s1 = (v_large + U) / g
        else:
            s1 = 2 * z_large / (U - v_large)       # both terms > 0: no cancellation
        period = 2 * U / g
        # y(s) = small bottom - 2R, measured like the large ball's bottom: the balls touch when y = z.
        # It meets level 0 at s_land; the first floor impact of the large ball at or after it ends the
        # bounce in which the balls meet (the gap is linear in each bounce).
        root = math.sqrt(v_small * v_small + 2 * g * z_large)
        s_land = (v_small + root) / g if v_small >= 0 else 2 * z_large / (root - v_small)
        if period == 0.0:                          # the large ball lies at rest on the floor
            s_meet = s_land
        else:
            j = max(1, math.ceil((s_land - s1) / period))
            start = s1 + (j - 1) * period          # floor impact that begins the bounce
            y = z_large + v_small * start - 0.5 * g * start * start
            closing = U - (v_small - g * start)
            # closing <= 0: the balls touch and move together through the bounce (M = m) until the
            # large ball's next floor impact turns it into the small ball
            s_meet = start + max(y, 0.0) / closing if closing > 0 else start + period
        return {"u": u, "t1": t1, "t2": t1 + tau, "tau": tau, "z_large": z_large, "v_small": v_small,
                "v_large": v_large, "U": U, "s1": s1, "period": period, "s_meet": s_meet}

    @property
    def rebound_velocity(self) -> float:
        """Velocity of the small ball just after the ball-ball impact [m/s]: (3M - m)/(M + m) u - g d/(2u)."""
        return self._sequence["v_small"]

    @property
    def top_time(self) -> float:
        """Time [s] at which the small ball reaches its top (the ball-ball impact when it does not rise)."""
        seq = self._sequence
        return seq["t2"] + max(seq["v_small"], 0.0) / self.gravity

    @property
    def top_height(self) -> float:
        """Height of the small ball's bottom at its top [m]: 2R + z + v^2/(2g), z the large ball's bottom at
        the ball-ball impact (2R + (v/u)^2 h for d = 0)."""
        seq = self._sequence
        return 2 * self.radius_large + seq["z_large"] + max(seq["v_small"], 0.0) ** 2 / (2 * self.gravity)

    @property
    def exact_until(self) -> float:
        """Time of the second ball-ball impact [s]: the closed form holds up to it."""
        seq = self._sequence
        return seq["t2"] + seq["s_meet"]

    def _default_t_end(self) -> float:
        """The small ball's top; when the balls meet again before it, halfway from the first ball-ball
        impact to the second (a sample time k dt may pass t_end by round-off, and must not pass the
        second impact, after which the closed form does not hold)."""
        t2, until = self._sequence["t2"], self.exact_until
        if self.top_time < until:
            return self.top_time
        if until > t2:
            return t2 + 0.5 * (until - t2)
        raise ValueError(
            f"{self.describe()}: the balls meet again at the instant of their first impact (the large ball, "
            f"lighter than the small one, is sent back to the floor and bounces into it at t={t2!r} s), so the "
            "chapter's sequence and its closed form end there; give t_end")

    # ----- exact solution ------------------------------------------------------------------------------

    def exact(self, t: ArrayLike) -> dict[str, np.ndarray]:
        """Closed-form observables at times t (T,) [s], 0 <= t <= exact_until: heights (T,) of the bottoms
        [m], velocities (T,) upwards [m/s], energy (T,) [J]. A time equal to an impact time shows the
        motion just before it (as the event-driven run's samples)."""
        t = finite_array(t, "t").reshape(-1)
        if np.any(t < 0):
            raise ValueError(f"t={t[t < 0][:3].tolist()}: times must be >= 0 [s]")
        if np.any(t > self.exact_until):
            raise ValueError(f"t up to {float(t.max())!r} s: the closed form holds up to the second ball-ball impact "
                             f"at exact_until={self.exact_until!r} s")
        g, seq = self.gravity, self._sequence
        z0_large, z0_small = self.start_heights
        t1, t2 = seq["t1"], seq["t2"]
        # Both fall from rest until the large ball meets the floor at t1.
        z_large, v_large = z0_large - 0.5 * g * t * t, -g * t
        z_small, v_small = z0_small - 0.5 * g * t * t, -g * t
        # t1 < t <= t2: the large ball rises from the floor at u; the small ball still falls.
        s = t - t1
        rising = (t > t1) & (t <= t2)
        z_large = np.where(rising, seq["u"] * s - 0.5 * g * s * s, z_large)
        v_large = np.where(rising, seq["u"] - g * s, v_large)
        # t > t2: the small ball in free flight from the ball-ball impact; the large ball bounces.
        after = t > t2
        s = t - t2
        z_small = np.where(after, 2 * self.radius_large + seq["z_large"] + seq["v_small"] * s - 0.5 * g * s * s,
                           z_small)
        v_small = np.where(after, seq["v_small"] - g * s, v_small)
        first = after & (s <= seq["s1"])
        z_large = np.where(first, seq["z_large"] + seq["v_large"] * s - 0.5 * g * s * s, z_large)
        v_large = np.where(first, seq["v_large"] - g * s, v_large)
        bouncing = after & (s > seq["s1"])
        if np.any(bouncing):
            U, period = seq["U"], seq["period"]
            if period > 0:
                since = s - seq["s1"]
                # phi in (0, P]: a time at a floor impact shows the motion just before it
                k = np.maximum(np.ceil(since / period) - 1, 0)
                phi = since - k * period
            else:
                phi = np.zeros_like(s)
            z_large = np.where(bouncing, U * phi - 0.5 * g * phi * phi, z_large)
            v_large = np.where(bouncing, U - g * phi, v_large)
        heights = np.stack([np.maximum(z_large, 0.0), z_small], axis=-1)
        velocities = np.stack([v_large, v_small], axis=-1)
        return self._observed(heights, velocities)

    def _observed(self, heights: np.ndarray, velocities: np.ndarray) -> dict[str, np.ndarray]:
        """Observables from bottom heights and velocities (..., 2) (large, small)."""
        return {"small_velocity": velocities[..., 1], "large_velocity": velocities[..., 0],
                "small_height": heights[..., 1], "large_height": heights[..., 0],
                "energy": np.broadcast_to(self.energy_of(heights, velocities), heights.shape[:-1]).copy()}

    # ----- the run ---------------------------------------------------------------------------------

    def _run(self, **kwargs) -> LineRun:
        z = self.start_heights + self.radii                         # centres
        run = self.line.run(z, np.zeros(2), max_events=self.max_events, **kwargs)
        if run.status == TOO_MANY:
            raise SimulationError(
                f"scene {self.describe()}: more than max_events={self.max_events} impacts before "
                f"t={kwargs.get('t_stop')} s (last at t={run.t_last:.6g} s); a large ball left almost at rest on the "
                "floor (M close to 3m) bounces with a tiny amplitude ever faster — give a shorter t_end or a larger "
                "max_events")
        return run

    def run_events(self, t_end: float, sample_dt: float) -> Trajectory:
        """The exact event-by-event run, sampled every sample_dt [s] from 0 to the first k sample_dt >= t_end.

        Observables (T,) as exact(); events: time (E,) [s], kind (E,) (0 ball-ball, 1 floor),
        large_velocity, small_velocity (E,) just after each impact [m/s]."""
        t = sample_times(t_end, sample_dt)
        sample_dt = float(sample_dt)
        run = self._run(t_stop=t[-1], sample_t=t, record=True)
        centres = self.line.positions(run.samples["gaps"], run.samples["x0"])
        data = self._observed(centres - self.radii, run.samples["velocities"])
        ev = run.event_arrays
        events = {"time": ev["time"], "kind": np.where(ev["gap"] == 0, FLOOR, BALL_BALL).astype(np.int8),
                  "large_velocity": ev["velocities"][:, 0], "small_velocity": ev["velocities"][:, 1]}
        meta = {"scene": self.name, "backend": "rbody", "method": "events", "dt": sample_dt,
                "event_count": run.events, "ball_collisions": run.ball, "floor_collisions": run.wall,
                "t_last_event": run.t_last, "done": run.status == DONE}
        return Trajectory(t, data, events, meta)

    # ----- what other simulators build --------------------------------------------------------------

    def _layout(self) -> Layout:
        """Two spheres on slide joints "z_large", "z_small" along world z (reference pose at the start,
        qpos0 = 0, at rest), a floor plane at z = 0, elastic frictionless contacts floor-large and
        large-small."""
        bodies, joints = [], []
        for name, mass, radius, bottom in (("large", self.large_mass, self.radius_large, self.start_heights[0]),
                                           ("small", self.small_mass, self.radius_small, self.start_heights[1])):
            bodies.append(Body(name, Inertia.solid_sphere(mass, radius), shapes=(Shape(name, "sphere", (radius,)),),
                               pos=(0.0, 0.0, float(bottom + radius))))
            joints.append(Joint(f"z_{name}", "slide", name, axis=(0.0, 0.0, 1.0), qpos0=0.0, qvel0=0.0))
        half = FLOOR_HALF_SIZE * self.radius_large
        floor = Shape("floor", "plane", (half, half))
        contacts = (Contact("floor", "large", friction=0.0, restitution=1.0),
                    Contact("large", "small", friction=0.0, restitution=1.0))
        return Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=(floor,), contacts=contacts)

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        """Heights = start + qpos of "z_large", "z_small"; velocities their qvel."""
        q = np.stack([np.asarray(joints[f"z_{n}"][0], dtype=float) for n in ("large", "small")], axis=-1)
        qd = np.stack([np.asarray(joints[f"z_{n}"][1], dtype=float) for n in ("large", "small")], axis=-1)
        return self._observed(q + self.start_heights, qd)

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Slides "z_large", "z_small": each ball's height above its start."""
        return {f"z_{name}": observed(self, trajectory, f"{name}_height") - start
                for name, start in zip(("large", "small"), self.start_heights)}

    def describe(self) -> str:
        return (f"{self.name}(M={self.large_mass:g} kg, m={self.small_mass:g} kg, h={self.drop_height:g} m, "
                f"R={self.radius_large:g} m, r={self.radius_small:g} m, gap={self.gap:g} m)")


def stacked_balls(M: float, m: float, *, drop_height: float, radius_large: float = 0.1, radius_small: float = 0.02,
                  gap: float = 0.0, t_end: float | None = None, gravity: float = 9.81) -> StackedBalls:
    """The chapter's bouncing balls: a small ball m on a large ball M, dropped onto a floor, impacts elastic.

    M, m [kg] > 0; drop_height h [m] > 0 of the large ball's bottom above the floor; radius_large,
    radius_small [m] > 0; gap [m] >= 0 between the balls at the start (0: touching, the chapter's
    sequence exactly); t_end [s] or None: until the small ball reaches its top; gravity [m/s^2] > 0.
    Observables small_velocity, large_velocity (T,) upwards [m/s], small_height, large_height (T,) of
    the ball bottoms above the floor [m], energy (T,) [J]. scene.speed_ratio is the chapter's
    v/u = (3M - m)/(M + m), scene.height_ratio (v/u)^2.
    """
    scene_arguments(gravity, t_end)
    try:
        return representable(StackedBalls(name="stacked_balls", t_end=t_end, gravity=gravity, large_mass=M,
                                          small_mass=m, drop_height=drop_height, radius_large=radius_large,
                                          radius_small=radius_small, gap=gap))
    except (OverflowError, ZeroDivisionError) as error:  # the impact sequence left float64 (a mass ratio of 1e300)
        raise ValueError(f"stacked_balls(M={M!r}, m={m!r}, drop_height={drop_height!r}, gap={gap!r}): the sequence "
                         f"of impacts cannot be followed in float64 ({error}); give masses and heights nearer "
                         "each other's scale") from None
