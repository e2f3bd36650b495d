"""Variable mass (the chapter's section 5.3): the rocket, and the avalanche that gathers snow.

Rocket. A rocket of mass m(t) moves along a straight line (world x) with velocity v; it ejects fuel
at the rate alpha = -m' > 0 with speed u relative to itself. The momentum of rocket plus ejected fuel
gives the chapter's Tsiolkovsky equation (5.10) with the chapter's linear drag F = -beta v (5.11):

    m v' + u m' = -beta v,    m = m0 - alpha t,    so    m v' = alpha u - beta v.

In v as a function of m (the chapter's method), with w = alpha u - beta v: dw/dm = beta w / (alpha m),
so w = w0 (m/m0)^(beta/alpha) and

    v(m) = v0 (m/m0)^k + (alpha u / beta) (1 - (m/m0)^k),    k = beta / alpha,

which from rest is the chapter's v = (alpha u/beta)(1 - (m/m0)^(beta/alpha)), tending to the limiting
speed alpha u / beta (the chapter's half-mass question: m = m0/2). Without drag it is the free rocket
v = v0 + u log(m0/m). With L = log(m0/m) and z = -k L, both are one formula that has no cancellation
as beta -> 0: v = v0 e^z + u L phi1(z), phi1(z) = (e^z - 1)/z. Integrating v dt = -v dm / alpha,

    x = v0 m0 (1 - (m/m0)^(k+1)) / (alpha + beta) + u (m0/alpha) [(1 - m/m0) - (m/m0) L phi1(z)] / (k + 1),

which without drag is the chapter's x = v0 t + u [t - (m/alpha) log(m0/m)].

Burn-out. The chapter's rocket is all fuel and disappears at t = m0/alpha. rbody's rocket keeps a dry
mass 0 < dry_mass < m0: the engine stops at t_b = (m0 - dry_mass)/alpha and the rocket coasts,
dry_mass v' = -beta v: v = v_b exp(-beta (t - t_b)/dry_mass) (constant without drag) and
x = x_b + v_b (t - t_b) phi1(-beta (t - t_b)/dry_mass).

Gravity plays no role in the chapter's examples (a free rocket in space; sticky alien syrup): the
rocket moves along world x, perpendicular to gravity, which does no work on it (in other simulators
the slide joint along x holds it up).

Avalanche. A slab of snow slides down a frictionless slope of angle theta and picks up the snow
lying at rest in its path (density rho, height h, width w): m = rho h w x after a distance x. The
picked-up snow had no momentum, so (the chapter, with u = v in (5.10))

    d(m v)/dt = m g sin(theta),    i.e.    v' = g sin(theta) - v^2 / x    (m' = rho h w v).

The chapter's solution from x = 0 at rest is x = g sin(theta) t^2 / 6, v = sqrt(2/3 x g sin(theta)):
the acceleration is g sin(theta)/3, one third of a free slide. The start x = 0 is singular (m = 0,
v^2/x undefined), so the scene starts ON that parabola at a small distance x0 > 0: at t0 =
sqrt(6 x0 / (g sin(theta))) with v0 = sqrt(2/3 x0 g sin(theta)) = g sin(theta) t0 / 3. The parabola
is an exact solution of the ODE from any of its points (v' = g s/3 and v^2/x = 2 g s/3 with
s = sin(theta)), so from x0 the exact motion is x(t) = g sin(theta) (t + t0)^2 / 6.

Native models. Rocket: y = (x, v, s) with s = m0 - alpha t the burn clock (s' = -alpha, integrated
exactly by every method); the mass is max(s, dry_mass) and the thrust alpha u acts while s > dry_mass.
The right-hand side jumps at burn-out (the thrust alpha u / dry_mass switches off), and a fixed-step
method straddles that instant unless t_b falls on its grid: the step that contains it integrates the
jump with the method's stage weights instead of exactly, an error in v of at most
alpha u / dry_mass * dt (first order in dt) that the coast then carries along. Before burn-out and
after it the method keeps its order. Avalanche: y = (x, v), v' = g sin(theta) - v^2/x.

Other simulators change the body's mass every step: `body_mass(t, distance)` gives it and
`slide_force(t, distance, speed)` the force along the slide besides gravity (thrust minus drag for
the rocket; -m' v = -rho h w v^2 for the avalanche, the momentum given to the snow picked up).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import njit

from rbody.checks import describe_values, finite_array, nonnegative, positive, representable, scene_arguments
from rbody.inertia import Inertia
from rbody.layout import Body, Joint, Layout, Shape
from rbody.engine.native import NativeModel
from rbody.poses import observed
from rbody.scene import Scene

VARIABLE_MASS_METHODS = ("rk4", "euler", "gauss6", "reference")  # rk4 first: simulate's default


def _phi1(z: np.ndarray) -> np.ndarray:
    """(e^z - 1)/z, 1 at z = 0, accurate for small |z| (expm1)."""
    z = np.asarray(z, dtype=np.float64)
    zero = z == 0
    return np.where(zero, 1.0, np.expm1(z) / np.where(zero, 1.0, z))


# ----- rocket ----------------------------------------------------------------------------------------

# y = (x, v, s); params = (alpha [kg/s], u [m/s], beta [kg/s], dry mass [kg], phase): phase 1 burning,
# 0 coasting, -1 decided by the burn clock s (simulate sets 1 or 0 on each side of a shared burn-out).


@njit(cache=True)
def rocket_rhs(y, p, out):
    out[0] = y[1]
    burning = p[4] > 0.5 if p[4] >= 0.0 else y[2] > p[3]
    if burning:  # m v' = alpha u - beta v, m = s
        out[1] = (p[0] * p[1] - p[2] * y[1]) / y[2]
    else:            # coasting: dry_mass v' = -beta v
        out[1] = -p[2] * y[1] / p[3]
    out[2] = -p[0]


@dataclass(frozen=True, kw_only=True)
class Rocket(Scene):
    """The chapter's rocket along world x with linear drag, burning down to a dry mass.

    m0 [kg], burn_rate alpha [kg/s], exhaust_speed u [m/s], dry_mass [kg], drag beta [kg/s] and
    v0 [m/s] may be arrays (a batch). Observables: distance x [m], speed v [m/s] (velocity along x),
    mass [kg].
    """

    m0: Any
    burn_rate: Any
    exhaust_speed: Any
    dry_mass: Any
    drag: Any = 0.0
    v0: Any = 0.0

    observables: ClassVar[tuple[str, ...]] = ("distance", "speed", "mass")
    main_observable: ClassVar[str] = "distance"
    preferred_methods: ClassVar[tuple[str, ...]] = VARIABLE_MASS_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("m0", "burn_rate", "exhaust_speed", "dry_mass", "drag", "v0")

    def __post_init__(self) -> None:
        super().__post_init__()
        positive(self.m0, "m0")
        positive(self.burn_rate, "burn_rate")
        positive(self.exhaust_speed, "exhaust_speed")
        nonnegative(self.drag, "drag")
        finite_array(self.v0, "v0")
        finite_array(self.dry_mass, "dry_mass")
        self.batch_shape  # noqa: B018 - checks that the parameters broadcast
        m0, alpha, dry = self.batched("m0"), self.batched("burn_rate"), self.batched("dry_mass")
        if np.any(dry <= 0):
            b = int(np.argmax(dry <= 0))
            vanish = m0[b] / alpha[b]
            when = "before" if vanish < self.t_end else "after"
            raise ValueError(
                f"dry_mass={self.dry_mass!r}: must be > 0 [kg]. With no dry mass the chapter's rocket is all "
                f"fuel and burns itself away entirely at t = m0/burn_rate = {vanish:.6g} s ({when} "
                f"t_end = {self.t_end:.6g} s), where m v' = alpha u - beta v has m = 0; rbody's rocket keeps "
                "the mass that remains when the fuel is gone and coasts from there")
        if np.any(dry >= m0):
            raise ValueError(f"dry_mass={self.dry_mass!r}: must be < m0={self.m0!r} [kg] (the dry mass is what "
                             "is left of m0 when the fuel is burnt)")

    # --- the physics, as flat (B,) arrays ---------------------------------------------------------

    def _flat(self) -> tuple[np.ndarray, ...]:
        """m0, alpha, u, beta, dry mass, v0 (B,)."""
        return tuple(self.batched(name) for name in ("m0", "burn_rate", "exhaust_speed", "drag", "dry_mass", "v0"))

    @property
    def burnout_time(self) -> np.ndarray | float:
        """t_b = (m0 - dry_mass) / alpha [s]: the engine stops."""
        m0, alpha, _u, _beta, dry, _v0 = self._flat()
        return self.unflatten((m0 - dry) / alpha)

    @property
    def limiting_speed(self) -> np.ndarray | float:
        """alpha u / beta [m/s], the speed the burning rocket tends to (inf without drag)."""
        _m0, alpha, u, beta, _dry, _v0 = self._flat()
        with np.errstate(divide="ignore"):
            return self.unflatten(np.where(beta > 0, alpha * u / np.where(beta > 0, beta, 1.0), np.inf))

    def speed_at_mass(self, mass) -> np.ndarray:
        """The chapter's v(m) while burning: v0 (m/m0)^k + (alpha u/beta)(1 - (m/m0)^k), k = beta/alpha
        (v0 + u log(m0/m) without drag). mass (T,) in [dry_mass, m0] [kg]; returns (T, *batch) [m/s]."""
        mass = finite_array(mass, "mass").reshape(-1)[:, None]
        m0, alpha, u, beta, dry, v0 = self._flat()
        if np.any(mass < dry) or np.any(mass > m0):
            raise ValueError(f"mass={describe_values(mass)}: the rocket burns from m0={self.m0!r} down to "
                             f"dry_mass={self.dry_mass!r} [kg]; v(m) is defined between them")
        log_ratio = np.log(m0 / mass)
        z = -beta / alpha * log_ratio
        return (v0 * np.exp(z) + u * log_ratio * _phi1(z)).reshape((mass.shape[0],) + self.batch_shape)

    def _mass(self, t: np.ndarray) -> np.ndarray:
        """Mass (T, B) at times t (T, 1) [kg]: m0 - alpha t down to the dry mass."""
        m0, alpha, _u, _beta, dry, _v0 = self._flat()
        return np.maximum(m0 - alpha * t, dry)

    # --- closed form ---------------------------------------------------------------------------

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)[:, None]  # (T, 1) against (B,)
        m0, alpha, u, beta, dry, v0 = self._flat()
        k = beta / alpha
        t_b = (m0 - dry) / alpha
        # burning, at tau = min(t, t_b): m = m0 - alpha tau, L = log(m0/m), z = -k L
        tau = np.minimum(t, t_b)
        mass = m0 - alpha * tau
        ratio = mass / m0
        log_ratio = -np.log1p(-alpha * tau / m0)
        z = -k * log_ratio
        v_burn = v0 * np.exp(z) + u * log_ratio * _phi1(z)
        x_burn = (v0 * m0 * -np.expm1(-(k + 1) * log_ratio) / (alpha + beta)
                  + u * (m0 / alpha) * ((1 - ratio) - ratio * log_ratio * _phi1(z)) / (k + 1))
        # coasting after t_b: dry v' = -beta v
        coast = np.maximum(t - t_b, 0.0)
        decay = -beta / dry * coast
        speed = v_burn * np.exp(decay)
        distance = x_burn + v_burn * coast * _phi1(decay)
        shape = (t.shape[0],) + self.batch_shape
        return {"distance": distance.reshape(shape), "speed": speed.reshape(shape),
                "mass": mass.reshape(shape)}

    # --- native model ----------------------------------------------------------------------------

    def native(self) -> NativeModel:
        m0, alpha, u, beta, dry, v0 = self._flat()

        def observe(t, y):
            return {"distance": y[..., 0], "speed": y[..., 1], "mass": np.maximum(y[..., 2], dry)}

        burnout = (m0 - dry) / alpha
        shared = burnout.size > 0 and np.all(burnout == burnout[0])
        return NativeModel(y0=np.stack([np.zeros_like(m0), v0, m0], axis=1),
                           params=np.stack([alpha, u, beta, dry, np.full_like(m0, -1.0)], axis=1),
                           rhs=rocket_rhs, observe=observe,
                           break_time=float(burnout[0]) if shared else None, break_column=4)

    def why_not(self, method: str) -> str:
        if method in ("symplectic_euler", "verlet", "yoshida6"):
            return ("the rocket's acceleration (alpha u - beta v)/m depends on its velocity (drag) and on the "
                    "burning mass, not on position alone, so there is no separable Hamiltonian to split")
        return f"{method!r} is not a rocket method"

    # --- what other simulators build -------------------------------------------------------------

    def body_mass(self, t, distance=None) -> np.ndarray:
        """Mass of the rocket (T,) at times t (T,) [s] (unbatched scene) [kg]; distance is not needed."""
        self.require_single("body_mass")
        t = finite_array(t, "t").reshape(-1)
        return np.maximum(float(self.m0) - float(self.burn_rate) * t, float(self.dry_mass))

    def slide_force(self, t, distance, speed) -> np.ndarray:
        """Force along the slide (T,) besides gravity [N]: thrust alpha u while burning (t < t_b), minus
        drag beta v, so that m(t) v' = slide_force (the rocket equation with -u m' moved to the right)."""
        self.require_single("slide_force")
        t = finite_array(t, "t").reshape(-1)
        speed = finite_array(speed, "speed").reshape(-1)
        thrust = np.where(t < float(self.burnout_time), float(self.burn_rate) * float(self.exhaust_speed), 0.0)
        return thrust - float(self.drag) * speed

    def _layout(self) -> Layout:
        m0 = float(self.m0)
        length, radius = 1.0, 0.1
        inertia = Inertia.solid_cylinder(m0, radius, length, axis="x")
        along_x = (np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0)  # the capsule's local z turned onto world x
        shape = Shape("hull", "capsule", (radius, length / 2 - radius), quat=along_x)
        body = Body("rocket", inertia, shapes=(shape,))
        slide = Joint("slide", "slide", "rocket", axis=(1.0, 0.0, 0.0), qpos0=0.0, qvel0=float(self.v0))
        return Layout(bodies=(body,), joints=(slide,))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        x, v = (np.asarray(value, dtype=float) for value in joints["slide"])
        return {"distance": x, "speed": v, "mass": self.body_mass(t)}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """The slide's coordinate is the distance."""
        return {"slide": observed(self, trajectory, "distance")}

    def describe(self) -> str:
        return (f"{self.name}(m0={self.m0!r} kg, burn_rate={self.burn_rate!r} kg/s, exhaust_speed="
                f"{self.exhaust_speed!r} m/s, dry_mass={self.dry_mass!r} kg, drag={self.drag!r} kg/s, "
                f"v0={self.v0!r} m/s)")


def rocket(m0, *, burn_rate, exhaust_speed, dry_mass, drag=0.0, v0=0.0, t_end: float,
           gravity: float = 9.81) -> Rocket:
    """The chapter's rocket (5.10)-(5.11) along world x: m v' + u m' = -beta v, m' = -burn_rate until
    the mass is down to dry_mass (0 < dry_mass < m0), then it coasts.

    m0 [kg], burn_rate [kg/s], exhaust_speed [m/s], dry_mass [kg], drag beta [kg/s] (linear drag
    F = -beta v), v0 [m/s] may be arrays that broadcast to a batch. gravity is perpendicular to the
    motion and does no work (the chapter's examples have none). Observables distance, speed, mass.
    """
    scene_arguments(gravity, t_end)
    return representable(Rocket(name="rocket", t_end=t_end, gravity=gravity, m0=m0, burn_rate=burn_rate,
                  exhaust_speed=exhaust_speed, dry_mass=dry_mass, drag=drag, v0=v0))


# ----- avalanche ----------------------------------------------------------------------------------

# y = (x, v); params = (g sin(theta),)


@njit(cache=True)
def avalanche_rhs(y, p, out):
    out[0] = y[1]
    out[1] = p[0] - y[1] * y[1] / y[0]  # d(m v)/dt = m g sin(theta), m' = rho h w v


@dataclass(frozen=True, kw_only=True)
class Avalanche(Scene):
    """The chapter's avalanche: a slab gathering snow on a frictionless slope, started on the exact
    parabola at distance x0.

    slope theta [rad] in (0, pi/2], snow_density rho [kg/m^3], snow_height h [m], width w [m] and
    x0 [m] may be arrays (a batch). Observables: distance down the slope [m], speed [m/s], mass [kg].
    """

    slope: Any
    snow_density: Any = 300.0
    snow_height: Any = 0.5
    width: Any = 1.0
    x0: Any = 1e-3

    observables: ClassVar[tuple[str, ...]] = ("distance", "speed", "mass")
    main_observable: ClassVar[str] = "distance"
    preferred_methods: ClassVar[tuple[str, ...]] = VARIABLE_MASS_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("slope", "snow_density", "snow_height", "width", "x0")

    def __post_init__(self) -> None:
        super().__post_init__()
        slope = finite_array(self.slope, "slope")
        if np.any(slope <= 0) or np.any(slope > np.pi / 2):
            raise ValueError(f"slope={self.slope!r}: must lie in (0, pi/2] [rad]; on level ground the snow "
                             "never starts to move")
        positive(self.snow_density, "snow_density")
        positive(self.snow_height, "snow_height")
        positive(self.width, "width")
        positive(self.x0, "x0")
        if self.gravity <= 0:
            raise ValueError(f"gravity={self.gravity!r}: must be > 0 [m/s^2]; gravity is what drives the "
                             "avalanche")
        self.batch_shape  # noqa: B018 - checks that the parameters broadcast

    def _flat(self) -> tuple[np.ndarray, ...]:
        """g sin(theta) [m/s^2], rho h w [kg/m], x0 [m] (B,)."""
        drive = self.gravity * np.sin(self.batched("slope"))
        line_density = self.batched("snow_density") * self.batched("snow_height") * self.batched("width")
        return drive, line_density, self.batched("x0")

    @property
    def acceleration(self) -> np.ndarray | float:
        """g sin(theta) / 3 [m/s^2]: one third of a free slide."""
        return self.unflatten(self._flat()[0] / 3)

    @property
    def start_time(self) -> np.ndarray | float:
        """t0 = sqrt(6 x0 / (g sin(theta))) [s]: when the exact avalanche from rest at x = 0 passes x0."""
        drive, _rho, x0 = self._flat()
        return self.unflatten(np.sqrt(6 * x0 / drive))

    @property
    def start_speed(self) -> np.ndarray | float:
        """v0 = sqrt(2/3 x0 g sin(theta)) [m/s], the exact speed at x0."""
        drive, _rho, x0 = self._flat()
        return self.unflatten(np.sqrt(2.0 / 3.0 * x0 * drive))

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)[:, None]
        drive, line_density, x0 = self._flat()
        since_rest = t + np.sqrt(6 * x0 / drive)
        distance = drive * since_rest**2 / 6
        shape = (t.shape[0],) + self.batch_shape
        return {"distance": distance.reshape(shape), "speed": (drive * since_rest / 3).reshape(shape),
                "mass": (line_density * distance).reshape(shape)}

    def native(self) -> NativeModel:
        drive, line_density, x0 = self._flat()

        def observe(t, y):
            return {"distance": y[..., 0], "speed": y[..., 1], "mass": line_density * y[..., 0]}

        return NativeModel(y0=np.stack([x0, np.sqrt(2.0 / 3.0 * x0 * drive)], axis=1), params=drive[:, None],
                           rhs=avalanche_rhs, observe=observe)

    def why_not(self, method: str) -> str:
        if method in ("symplectic_euler", "verlet", "yoshida6"):
            return ("v' = g sin(theta) - v^2/x depends on the velocity (the snow picked up takes momentum), "
                    "so there is no separable Hamiltonian to split")
        return f"{method!r} is not an avalanche method"

    # --- what other simulators build -------------------------------------------------------------

    def body_mass(self, t, distance) -> np.ndarray:
        """Mass of the slab (T,) at slide coordinates distance (T,) [m]: rho h w x [kg] (unbatched)."""
        self.require_single("body_mass")
        return self._flat()[1][0] * finite_array(distance, "distance").reshape(-1)

    def slide_force(self, t, distance, speed) -> np.ndarray:
        """Force along the slide (T,) besides gravity [N]: -m' v = -rho h w v^2, the momentum given to the
        snow picked up, so that m v' = m g sin(theta) - rho h w v^2."""
        self.require_single("slide_force")
        speed = finite_array(speed, "speed").reshape(-1)
        return -self._flat()[1][0] * speed**2

    def _layout(self) -> Layout:
        slope, height, width, x0 = (float(self.slope), float(self.snow_height), float(self.width),
                                    float(self.x0))
        mass0 = float(self._flat()[1][0]) * x0
        # Body x along the slope, down-hill: a turn by +theta about world y takes x to (cos, 0, -sin).
        quat = (np.cos(slope / 2), 0.0, np.sin(slope / 2), 0.0)
        slab = Shape("slab", "box", (x0 / 2, width / 2, height / 2))
        body = Body("slab", Inertia.box(mass0, (x0, width, height)), shapes=(slab,), quat=quat)
        # No contact: the frictionless slide joint holds the slab on the slope, as in the chapter.
        slide = Joint("slide", "slide", "slab", axis=(1.0, 0.0, 0.0), qpos0=x0, qvel0=float(self.start_speed))
        return Layout(bodies=(body,), joints=(slide,))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        x, v = (np.asarray(value, dtype=float) for value in joints["slide"])
        return {"distance": x, "speed": v, "mass": self.body_mass(t, x)}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """The slide's coordinate is the distance down the slope (the slab drawn at its starting size)."""
        return {"slide": observed(self, trajectory, "distance")}

    def describe(self) -> str:
        return (f"{self.name}(slope={self.slope!r} rad, snow_density={self.snow_density!r} kg/m^3, "
                f"snow_height={self.snow_height!r} m, width={self.width!r} m, x0={self.x0!r} m)")


def avalanche(slope, *, snow_density=300.0, snow_height=0.5, width=1.0, x0=1e-3, t_end: float,
              gravity: float = 9.81) -> Avalanche:
    """The chapter's avalanche: d(m v)/dt = m g sin(slope) with m = snow_density snow_height width x,
    started on the exact solution x = g sin(slope) t^2/6 at distance x0 > 0 (x = 0 is singular: m = 0).

    slope [rad], snow_density [kg/m^3], snow_height [m], width [m], x0 [m] may be arrays (a batch).
    Observables distance, speed, mass; time 0 is when the slab passes x0.
    """
    scene_arguments(gravity, t_end)
    return representable(Avalanche(name="avalanche", t_end=t_end, gravity=gravity, slope=slope, snow_density=snow_density,
                     snow_height=snow_height, width=width, x0=x0))
