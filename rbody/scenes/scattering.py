"""Right-angle scattering (the chapter, section 5.2): an elastic collision of equal masses, one at rest.

A disc of mass m moving at velocity v hits an equal disc at rest. Energy and momentum,

    1/2 m v^2 = 1/2 m v1^2 + 1/2 m v2^2,    m v = m v1 + m v2,

give, on squaring the second and comparing with the first, v1 . v2 = 0: either one of the discs
is at rest afterwards, or they leave at right angles. Conservation alone leaves the outcome open; the
geometry of the impact fixes it. With the projectile moving along +x at speed u on a line a distance
b (the impact parameter) from the target's centre, discs of radius r touch when their centres are
2r apart, on the line of centres n at the angle phi below the x axis, sin(phi) = b / (2r). Without
friction the impulse acts along n only (and the discs do not spin), so

    v2' = (v . n) n = u cos(phi) (cos(phi), -sin(phi)),
    v1' = v - (v . n) n = u sin(phi) (sin(phi), cos(phi)),

speeds u cos(phi) and u sin(phi), at right angles; head on (b = 0) the projectile stops and the
target takes its velocity. For b >= 2r the discs miss (at b = 2r they graze, with no impulse): both
move on straight lines and nothing happens.

Plane and gravity: the discs slide on a frictionless horizontal table. They move in rbody's plane
of planar scenes, world x-z, with no external force: gravity is balanced by the table's reaction
and does no work, so it is accepted for the common signature and not applied (`applies_gravity =
False`: other simulators switch it off). Positions and velocities are (x, z) components. The target
starts at rest at the origin, the projectile at (-distance, b) moving along +x.

Native: the discs are run event by event (rbody.engine.events.Discs): the time of impact solves
|x1 + v1 t - x2| = 2r in a form without cancellation, the impulse acts along the line of centres.

Other simulators: two spheres, each on slide joints along world x and world z (no rotation), one
elastic frictionless contact between them, gravity off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from rbody.checks import finite_array, nonnegative, positive, single_number, representable, scene_arguments
from rbody.engine.events import DONE, TOO_MANY, Discs, sample_times
from rbody.errors import SimulationError
from rbody.inertia import Inertia
from rbody.layout import Body, Contact, Joint, Layout, Shape
from rbody.poses import observed
from rbody.scene import Scene
from rbody.trajectory import Trajectory

# Default start: the projectile's centre this many radii behind the target's along x.
DEFAULT_DISTANCE_RADII = 5.0


@dataclass(frozen=True, kw_only=True)
class Scattering(Scene):
    """A disc hits an equal disc at rest off-centre, elastically, without friction, in the x-z plane.

    impact_parameter b [m] >= 0: distance of the projectile's line from the target's centre (b >= 2r:
    no collision); speed u [m/s] > 0 of the projectile along +x; mass m [kg] > 0 and radius r [m] > 0
    of each disc; distance [m] > 2r: the projectile's start behind the target along x (None: 5 r).
    t_end None: 2 distance / u (the projectile, unhit, would have passed the target by distance).
    """

    impact_parameter: float
    speed: float = 1.0
    mass: float = 1.0
    radius: float = 0.1
    distance: Any = None
    t_end: Any = None

    observables: ClassVar[tuple[str, ...]] = ("position_1", "position_2", "velocity_1", "velocity_2",
                                              "angle_between", "energy", "momentum")
    main_observable: ClassVar[str] = "position_1"
    event_driven: ClassVar[bool] = True
    applies_gravity: ClassVar[bool] = False  # a horizontal table carries the weight: other simulators switch gravity off

    def __post_init__(self) -> None:
        b = finite_array(self.impact_parameter, "impact_parameter")
        if b.ndim == 0 and b < 0:
            raise ValueError(f"impact_parameter={float(b)!r}: must be >= 0 [m] (the scene is symmetric: a negative b "
                             "is its mirror image)")
        object.__setattr__(self, "impact_parameter", single_number(b, "impact_parameter", nonnegative))
        for name in ("speed", "mass", "radius"):
            object.__setattr__(self, name, single_number(getattr(self, name), name, positive))
        distance = DEFAULT_DISTANCE_RADII * self.radius if self.distance is None else self.distance
        distance = single_number(distance, "distance", positive)
        if not distance > 2 * self.radius:
            raise ValueError(f"distance={distance!r}: must be > 2 radius = {2 * self.radius!r} m so that the discs do "
                             "not overlap at t = 0")
        object.__setattr__(self, "distance", distance)
        if self.t_end is None:
            object.__setattr__(self, "t_end", 2 * distance / self.speed)
        super().__post_init__()

    # ----- the impact geometry ------------------------------------------------------------------------

    @property
    def collides(self) -> bool:
        """True when b < 2r: the discs meet (at b = 2r they only graze)."""
        return self.impact_parameter < 2 * self.radius

    @property
    def contact_angle(self) -> float:
        """phi = arcsin(b / 2r) [rad]: the line of centres at contact, below the x axis; the target leaves at
        -phi, the projectile at pi/2 - phi. nan when the discs miss."""
        if not self.collides:
            return math.nan
        cos, sin = self._cos_sin()
        return math.atan2(sin, cos)     # asin(b / 2r), well conditioned up to the graze

    def _cos_sin(self) -> tuple[float, float]:
        """cos(phi), sin(phi), with cos = sqrt((2r - b)(2r + b)) / 2r free of cancellation near grazing."""
        D, b = 2 * self.radius, self.impact_parameter
        return math.sqrt((D - b) * (D + b)) / D, b / D

    @property
    def impact_time(self) -> float:
        """t_c = (distance - 2r cos(phi)) / u [s]; inf when the discs miss."""
        if not self.collides:
            return math.inf
        cos, _ = self._cos_sin()
        return (self.distance - 2 * self.radius * cos) / self.speed

    @property
    def speeds_after(self) -> tuple[float, float]:
        """(u sin(phi), u cos(phi)) [m/s]: the projectile's and the target's speed after the impact."""
        if not self.collides:
            return self.speed, 0.0
        cos, sin = self._cos_sin()
        return self.speed * sin, self.speed * cos

    def _initial(self) -> tuple[np.ndarray, np.ndarray]:
        """positions, velocities (2, 2) at t = 0: rows projectile, target; columns world x, z."""
        return (np.array([[-self.distance, self.impact_parameter], [0.0, 0.0]]),
                np.array([[self.speed, 0.0], [0.0, 0.0]]))

    # ----- exact solution -----------------------------------------------------------------------------

    def exact(self, t: ArrayLike) -> dict[str, np.ndarray]:
        """Closed-form observables at times t (T,) [s] (a time equal to the impact time shows the motion
        just before it): positions, velocities (T, 2) (x, z) [m, m/s], angle_between (T,) [rad],
        energy (T,) [J], momentum (T, 2) [kg m/s]."""
        t = finite_array(t, "t").reshape(-1)[:, None]
        x0, v0 = self._initial()
        x1, v1 = x0[0] + v0[0] * t, np.broadcast_to(v0[0], (t.shape[0], 2))
        x2, v2 = np.broadcast_to(x0[1], (t.shape[0], 2)), np.zeros((t.shape[0], 2))
        if self.collides:
            cos, sin = self._cos_sin()
            u, D, b = self.speed, 2 * self.radius, self.impact_parameter
            after = t > self.impact_time
            s = t - self.impact_time
            w1 = u * sin * np.array([sin, cos])          # v - (v.n) n
            w2 = u * cos * np.array([cos, -sin])         # (v.n) n
            x1 = np.where(after, np.array([-D * cos, b]) + w1 * s, x1)
            v1 = np.where(after, w1, v1)
            x2 = np.where(after, w2 * s, x2)
            v2 = np.where(after, w2, v2)
        return self._observed(np.asarray(x1, dtype=float), np.asarray(x2, dtype=float),
                              np.asarray(v1, dtype=float), np.asarray(v2, dtype=float))

    def _observed(self, x1: np.ndarray, x2: np.ndarray, v1: np.ndarray, v2: np.ndarray) -> dict[str, np.ndarray]:
        m = self.mass
        dot = np.sum(v1 * v2, axis=-1)
        cross = v1[..., 0] * v2[..., 1] - v1[..., 1] * v2[..., 0]
        return {"position_1": x1, "position_2": x2, "velocity_1": v1, "velocity_2": v2,
                # atan2(|v1 x v2|, v1.v2): pi/2 after an off-centre impact, 0 while a disc is at rest
                "angle_between": np.arctan2(np.abs(cross), dot),
                "energy": 0.5 * m * (np.sum(v1 * v1, axis=-1) + np.sum(v2 * v2, axis=-1)),
                "momentum": m * (v1 + v2)}

    # ----- the run -------------------------------------------------------------------------------------

    @property
    def discs(self) -> Discs:
        """The two discs as the event engine takes them."""
        return Discs(masses=np.full(2, self.mass), radii=np.full(2, self.radius), restitution=1.0)

    def run_events(self, t_end: float, sample_dt: float) -> Trajectory:
        """The exact event-by-event run, sampled every sample_dt [s] from 0 to the first k sample_dt >= t_end.

        Observables as exact(); events: time (E,) [s], velocity_1, velocity_2 (E, 2) just after each
        impact [m/s] (one impact when b < 2r, none otherwise)."""
        t = sample_times(t_end, sample_dt)
        sample_dt = float(sample_dt)
        x0, v0 = self._initial()
        run = self.discs.run(x0, v0, t_stop=t[-1], sample_t=t, record=True, max_events=16)
        if run.status == TOO_MANY:  # two discs without walls meet at most once
            raise SimulationError(f"scene {self.describe()}: more than one impact of two free discs")
        x, v = run.samples["positions"], run.samples["velocities"]
        data = self._observed(x[:, 0], x[:, 1], v[:, 0], v[:, 1])
        ev = run.event_arrays
        events = {"time": ev["time"], "velocity_1": ev["velocities"][:, 0], "velocity_2": ev["velocities"][:, 1]}
        meta = {"scene": self.name, "backend": "rbody", "method": "events", "dt": sample_dt,
                "event_count": run.events, "t_last_event": run.t_last, "done": run.status == DONE}
        return Trajectory(t, data, events, meta)

    # ----- what other simulators build ------------------------------------------------------------------

    def _layout(self) -> Layout:
        """Two spheres "disc_1" (projectile) and "disc_2" (target), each on slide joints "x_<i>", "z_<i>"
        along world x and z (reference pose at the start, qpos0 = 0), one elastic frictionless contact.
        Gravity is not applied (applies_gravity): the discs slide on a table."""
        x0, v0 = self._initial()
        bodies, joints = [], []
        for i in range(2):
            name = f"disc_{i + 1}"
            bodies.append(Body(name, Inertia.solid_sphere(self.mass, self.radius),
                               shapes=(Shape(name, "sphere", (self.radius,)),),
                               pos=(float(x0[i, 0]), 0.0, float(x0[i, 1]))))
            joints.append(Joint(f"x_{i + 1}", "slide", name, axis=(1.0, 0.0, 0.0), qpos0=0.0, qvel0=float(v0[i, 0])))
            joints.append(Joint(f"z_{i + 1}", "slide", name, axis=(0.0, 0.0, 1.0), qpos0=0.0, qvel0=float(v0[i, 1])))
        contact = Contact("disc_1", "disc_2", friction=0.0, restitution=1.0)
        return Layout(bodies=tuple(bodies), joints=tuple(joints), contacts=(contact,))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        """Positions = start + (qpos of "x_<i>", "z_<i>"), velocities their qvel."""
        x0, _ = self._initial()

        def disc(i):
            q = np.stack([np.asarray(joints[f"{a}_{i + 1}"][0], dtype=float) for a in "xz"], axis=-1)
            qd = np.stack([np.asarray(joints[f"{a}_{i + 1}"][1], dtype=float) for a in "xz"], axis=-1)
            return q + x0[i], qd

        (x1, v1), (x2, v2) = disc(0), disc(1)
        return self._observed(x1, x2, v1, v2)

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Slides "x_<i>", "z_<i>": disc i's position_<i> (T, 2) (world x, z) less its start."""
        x0, _ = self._initial()
        out = {}
        for i in range(2):
            moved = observed(self, trajectory, f"position_{i + 1}", (2,)) - x0[i]
            out[f"x_{i + 1}"], out[f"z_{i + 1}"] = moved[:, 0], moved[:, 1]
        return out

    def describe(self) -> str:
        return (f"{self.name}(b={self.impact_parameter:g} m, r={self.radius:g} m, u={self.speed:g} m/s, "
                f"m={self.mass:g} kg)")


def scattering(impact_parameter: float, *, speed: float = 1.0, mass: float = 1.0, radius: float = 0.1,
               distance: float | None = None, t_end: float | None = None, gravity: float = 9.81) -> Scattering:
    """The chapter's right-angle scattering: a disc hits an equal disc at rest, elastically, off-centre.

    impact_parameter b [m] >= 0 (b >= 2 radius: they miss); speed [m/s] of the projectile along +x;
    mass [kg] and radius [m] of each disc; distance [m] > 2 radius: the projectile's start behind the
    target along x (default 5 radius); t_end [s] or None: 2 distance / speed. The discs slide on a
    frictionless horizontal table, drawn in the x-z plane; gravity [m/s^2] does no work and is not
    applied. Observables position_1, position_2, velocity_1, velocity_2 (T, 2) (x, z), angle_between
    (T,) [rad] (pi/2 after an off-centre impact), energy (T,) [J], momentum (T, 2) [kg m/s].
    """
    scene_arguments(gravity, t_end)
    return representable(Scattering(name="scattering", t_end=t_end, gravity=gravity, impact_parameter=impact_parameter,
                      speed=speed, mass=mass, radius=radius, distance=distance))
