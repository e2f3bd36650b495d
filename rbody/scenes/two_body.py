"""The two-body problem (the chapter's section 5.1.5): really a one-body problem.

Two bodies of masses m1, m2 attract each other by gravity, F12 = -G m1 m2 r / |r|^3 with the
separation r = x1 - x2, and no external force acts. The centre of mass R = (m1 x1 + m2 x2)/M,
M = m1 + m2, then moves uniformly, and the separation obeys mu r'' = F12 with the reduced mass
mu = m1 m2 / M, i.e.

    r'' = -K r / |r|^3,    K = G (m1 + m2),

a Kepler orbit, with x1 = R + (m2/M) r and x2 = R - (m1/M) r. Uniform gravity is accepted for the
common signature and NOT applied: the chapter's two-body problem has no external force (a uniform
field would only accelerate R). The bodies move in the x-z plane; the centre of mass starts at the
origin with velocity com_velocity (at rest by default).

Exact orbit. From r0, v0: the angular momentum per unit reduced mass h = r0 x v0, the eccentricity
vector e = v0 x h / K - r0/|r0|, and 1/a = 2/|r0| - |v0|^2/K. In the orbit's plane, with P along the
pericentre and Q = h/|h| x P,
- ellipse (e < 1): r = a (cos E - e) P + b sin E Q, b = |h| sqrt(a/K), where Kepler's equation
  E - e sin E = M0 + n t, n = sqrt(K/a^3), is solved by Newton's method to round-off; period
  2 pi sqrt(a^3/K);
- hyperbola (e > 1, a < 0, A = -a): r = A (e - cosh H) P + b sinh H Q, b = |h| sqrt(A/K), with
  e sinh H - H = M0 + n t, n = sqrt(K/A^3).
Near e = 1 both forms lose accuracy as 1/|1 - e| (a and b grow without bound); parabolic orbits
(|1 - e| < 1e-6) and radial ones (h = 0: the bodies fall straight into each other) are refused.

Observables: r1, r2 (T, 3) positions [m]; separation |x1 - x2| (T,) [m]; energy (T,) [J] (kinetic
energy of both bodies plus -G m1 m2 / |r|); angular_momentum (T, 3) about the centre of mass
[kg m^2/s], which equals mu r x r'.

Native model: y = (x1, x2, v1, v2) (12 numbers; the y components stay exactly 0), q'' = a(q) with the
pair force computed once and applied with both signs, so total momentum is conserved to round-off
and the symplectic methods apply.

The general engine is not used here, by decision: it simulates a tree of bodies and joints under uniform
gravity, joint springs and damping (rbody.Multibody), and the attraction between two bodies is a pair force,
which no joint of a tree holds; the engine takes no applied or pair forces. Given this scene's Layout (each
body on an x and a z slide, what MuJoCo and pymunk are given, with the pair force applied by their wrappers
through pair_force) it would move the two bodies uniformly, with no attraction at all. So the hand-written
kernel above stays the scene's only native model (ENGINE_PATH below), not a fast path beside the engine;
adding force elements to the engine is the change that would let it run on the engine.

Other simulators: each body slides on two joints, along world x and world z (planar, no rotation),
with uniform gravity switched off and the pair force `pair_force(x1, x2)` applied each step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import njit

from rbody.checks import describe_values, finite_array, positive, representable, scene_arguments
from rbody.inertia import Inertia
from rbody.poses import observed
from rbody.particles import reduced_mass
from rbody.layout import Body, Joint, Layout, Shape
from rbody.engine.native import NativeModel
from rbody.scene import Scene

# False: native() always runs the hand kernel two_body_rhs / two_body_accel: the general engine holds no pair
# force (module docstring). There is no engine path to measure (benchmarks/fast_paths.py times the kernel alone).
ENGINE_PATH = False

TWO_BODY_METHODS = ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6", "reference")
PARABOLIC_BAND = 1e-6     # |1 - e| below this: refused (Kepler's equation in E or H loses 1/|1 - e|)
KEPLER_ITERATIONS = 100

# q = (x1 (3), x2 (3)); y = (q, v1 (3), v2 (3)); params = (G, m1, m2)


@njit(cache=True)
def two_body_accel(q, p, out):
    dx, dy, dz = q[0] - q[3], q[1] - q[4], q[2] - q[5]
    r2 = dx * dx + dy * dy + dz * dz
    scale = p[0] / (r2 * np.sqrt(r2))  # G / |r|^3
    # F12 = -G m1 m2 r/|r|^3 on body 1, -F12 on body 2
    out[0], out[1], out[2] = -scale * p[2] * dx, -scale * p[2] * dy, -scale * p[2] * dz
    out[3], out[4], out[5] = scale * p[1] * dx, scale * p[1] * dy, scale * p[1] * dz


@njit(cache=True)
def two_body_rhs(y, p, out):
    for j in range(6):
        out[j] = y[6 + j]
    two_body_accel(y[:6], p, out[6:])


def _in_plane(value: Any, name: str, scalar_axis: int) -> tuple[float, float, float]:
    """A scalar along world axis `scalar_axis`, or a (3,) vector with no y component."""
    array = finite_array(value, name)
    if array.ndim == 0:
        vector = np.zeros(3)
        vector[scalar_axis] = float(array)
    elif array.shape == (3,):
        vector = array
    else:
        raise ValueError(f"{name} has shape {array.shape}: expected a number or a (3,) vector")
    if vector[1] != 0:
        raise ValueError(f"{name}={vector.tolist()}: the two-body scene is planar in the x-z plane; the y "
                         "component must be 0")
    return tuple(float(c) for c in vector)


@dataclass(frozen=True, kw_only=True)
class TwoBody(Scene):
    """Two bodies under mutual gravity, no external force, in the x-z plane.

    m1, m2 [kg] and G [m^3/(kg s^2)] may be arrays (a batch); separation r0 = x1 - x2 [m],
    relative_velocity r0' [m/s] and com_velocity [m/s] are (3,) vectors in the x-z plane, the same for
    the whole batch. The centre of mass starts at the origin.
    """

    m1: Any
    m2: Any
    separation: Any
    relative_velocity: Any
    G: Any = 1.0
    com_velocity: Any = (0.0, 0.0, 0.0)

    observables: ClassVar[tuple[str, ...]] = ("r1", "r2", "separation", "energy", "angular_momentum")
    main_observable: ClassVar[str] = "r1"
    preferred_methods: ClassVar[tuple[str, ...]] = TWO_BODY_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("m1", "m2", "G")
    applies_gravity: ClassVar[bool] = False  # no external force: other simulators switch gravity off

    def __post_init__(self) -> None:
        super().__post_init__()
        positive(self.m1, "m1")
        positive(self.m2, "m2")
        positive(self.G, "G")
        separation = _in_plane(self.separation, "separation", 0)
        if not np.any(np.array(separation) != 0):
            raise ValueError(f"separation={self.separation!r}: must be non-zero; bodies at the same point "
                             "have an infinite mutual force")
        object.__setattr__(self, "separation", separation)
        object.__setattr__(self, "relative_velocity", _in_plane(self.relative_velocity, "relative_velocity", 2))
        object.__setattr__(self, "com_velocity", _in_plane(self.com_velocity, "com_velocity", 0))
        self.batch_shape  # noqa: B018 - checks that the parameters broadcast
        r0, v0 = np.array(self.separation), np.array(self.relative_velocity)
        h = np.cross(r0, v0)
        if not np.linalg.norm(h) > 1e-12 * np.linalg.norm(r0) * np.linalg.norm(v0):
            raise ValueError(
                f"relative_velocity={list(self.relative_velocity)} is zero or along separation="
                f"{list(self.separation)}: the motion is radial (no angular momentum) and the bodies fall "
                "straight into each other or fly apart on a line; give the relative velocity a component "
                "across the separation")
        eccentricity = self._elements()["e"]
        if np.any(np.abs(eccentricity - 1) < PARABOLIC_BAND):
            raise ValueError(
                f"eccentricity {describe_values(eccentricity)}: the orbit is parabolic to within {PARABOLIC_BAND:g} "
                "(|v0|^2 = 2 G (m1 + m2)/|r0|, escape speed); Kepler's equation in E or H loses accuracy "
                "as 1/|1 - e| there and parabolic orbits are not provided: change the relative speed")

    # --- the physics, as flat (B,) arrays ---------------------------------------------------------

    def _flat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """m1, m2, G (B,)."""
        return self.batched("m1"), self.batched("m2"), self.batched("G")

    def _elements(self) -> dict[str, np.ndarray]:
        """Orbit elements of the relative motion, each (B,) or (B, 3)."""
        m1, m2, G = self._flat()
        K = G * (m1 + m2)
        r0, v0 = np.array(self.separation), np.array(self.relative_velocity)
        r = np.linalg.norm(r0)
        h = np.cross(r0, v0)
        e_vec = np.cross(v0, h)[None, :] / K[:, None] - r0 / r   # (B, 3)
        e = np.linalg.norm(e_vec, axis=1)
        inverse_a = 2 / r - (v0 @ v0) / K
        h_hat = h / np.linalg.norm(h)
        P = np.where(e[:, None] > 0, e_vec / np.where(e > 0, e, 1.0)[:, None], r0 / r)
        Q = np.cross(h_hat, P)
        return {"K": K, "e": e, "inverse_a": inverse_a, "h": np.full_like(K, np.linalg.norm(h)), "P": P, "Q": Q}

    @property
    def total_mass(self) -> np.ndarray | float:
        """M = m1 + m2 [kg]."""
        m1, m2, _G = self._flat()
        return self.unflatten(m1 + m2)

    @property
    def reduced_mass(self) -> np.ndarray | float:
        """mu = m1 m2 / (m1 + m2) [kg] (rbody.particles.reduced_mass)."""
        m1, m2, _G = self._flat()
        return self.unflatten(np.array([reduced_mass(a, b) for a, b in zip(m1, m2)]))

    @property
    def eccentricity(self) -> np.ndarray | float:
        """e [-] of the relative orbit: < 1 bound (ellipse), > 1 unbound (hyperbola)."""
        return self.unflatten(self._elements()["e"])

    @property
    def semi_major_axis(self) -> np.ndarray | float:
        """a = 1/(2/|r0| - |v0|^2/K) [m]: > 0 for an ellipse, < 0 for a hyperbola."""
        return self.unflatten(1 / self._elements()["inverse_a"])

    @property
    def period(self) -> np.ndarray | float:
        """2 pi sqrt(a^3 / (G M)) [s] for a bound orbit; inf for an unbound one."""
        elements = self._elements()
        inverse_a, K = elements["inverse_a"], elements["K"]
        bound = elements["e"] < 1
        safe = np.where(bound, inverse_a, 1.0)
        return self.unflatten(np.where(bound, 2 * np.pi / np.sqrt(K * safe**3), np.inf))

    def energy_constant(self) -> np.ndarray:
        """E = 1/2 M |V|^2 + 1/2 mu |r0'|^2 - G m1 m2 / |r0| [J], (B,)."""
        m1, m2, G = self._flat()
        r0, v0, V = (np.array(value) for value in (self.separation, self.relative_velocity, self.com_velocity))
        mu = m1 * m2 / (m1 + m2)
        return 0.5 * (m1 + m2) * (V @ V) + 0.5 * mu * (v0 @ v0) - G * m1 * m2 / np.linalg.norm(r0)

    def angular_momentum_constant(self) -> np.ndarray:
        """L = mu r0 x r0' about the centre of mass [kg m^2/s], (B, 3)."""
        m1, m2, _G = self._flat()
        mu = m1 * m2 / (m1 + m2)
        return mu[:, None] * np.cross(np.array(self.separation), np.array(self.relative_velocity))

    # --- closed form ---------------------------------------------------------------------------

    def relative_orbit(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Exact separation r = x1 - x2 and its rate r' at times t (T,): each (T, B, 3) [m, m/s]."""
        t = finite_array(t, "t").reshape(-1)[:, None]       # (T, 1) against (B,)
        el = self._elements()
        K, e, inverse_a, h, P, Q = el["K"], el["e"], el["inverse_a"], el["h"], el["P"], el["Q"]
        r0 = np.array(self.separation)
        x0, y0 = P @ r0, Q @ r0                             # (B,) in the orbit's plane
        xp = np.empty((t.shape[0], K.size))
        yp, vx, vy = np.empty_like(xp), np.empty_like(xp), np.empty_like(xp)
        elliptic = e < 1
        if np.any(elliptic):
            i = elliptic
            a = 1 / inverse_a[i]
            b = h[i] * np.sqrt(a / K[i])
            n = np.sqrt(K[i] / a**3)
            E0 = np.arctan2(y0[i] / b, x0[i] / a + e[i])
            E = solve_kepler_elliptic(E0 - e[i] * np.sin(E0) + n * t, e[i])
            rate = n / (1 - e[i] * np.cos(E))               # E'
            xp[:, i], yp[:, i] = a * (np.cos(E) - e[i]), b * np.sin(E)
            vx[:, i], vy[:, i] = -a * np.sin(E) * rate, b * np.cos(E) * rate
        if np.any(~elliptic):
            i = ~elliptic
            A = -1 / inverse_a[i]
            b = h[i] * np.sqrt(A / K[i])
            n = np.sqrt(K[i] / A**3)
            H0 = np.arcsinh(y0[i] / b)
            H = solve_kepler_hyperbolic(e[i] * np.sinh(H0) - H0 + n * t, e[i])
            rate = n / (e[i] * np.cosh(H) - 1)              # H'
            xp[:, i], yp[:, i] = A * (e[i] - np.cosh(H)), b * np.sinh(H)
            vx[:, i], vy[:, i] = -A * np.sinh(H) * rate, b * np.cosh(H) * rate
        r = xp[..., None] * P + yp[..., None] * Q
        v = vx[..., None] * P + vy[..., None] * Q
        return r, v

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)
        m1, m2, _G = self._flat()
        r, _v = self.relative_orbit(t)
        R = t[:, None, None] * np.array(self.com_velocity)  # uniform motion of the centre of mass
        total = (m1 + m2)[:, None]
        values = {
            "r1": R + (m2[:, None] / total) * r,
            "r2": R - (m1[:, None] / total) * r,
            "separation": np.linalg.norm(r, axis=-1),
            "energy": np.broadcast_to(self.energy_constant(), (t.size, m1.size)),
            "angular_momentum": np.broadcast_to(self.angular_momentum_constant(), (t.size, m1.size, 3)),
        }
        return {name: np.array(value).reshape((t.size,) + self.batch_shape + value.shape[2:])
                for name, value in values.items()}

    # --- native model ----------------------------------------------------------------------------

    def initial_state(self) -> np.ndarray:
        """(B, 12): x1, x2, v1, v2 with the centre of mass at the origin moving with com_velocity."""
        m1, m2, _G = self._flat()
        total = (m1 + m2)[:, None]
        r0, v0, V = (np.array(value) for value in (self.separation, self.relative_velocity, self.com_velocity))
        w1, w2 = m2[:, None] / total, m1[:, None] / total
        return np.concatenate([w1 * r0, -w2 * r0, V + w1 * v0, V - w2 * v0], axis=1)

    def observe_states(self, x1: np.ndarray, x2: np.ndarray, v1: np.ndarray, v2: np.ndarray) -> dict[str, np.ndarray]:
        """Observables from positions and velocities (..., B, 3) of both bodies."""
        m1, m2, G = self._flat()
        a, b = m1[:, None], m2[:, None]
        R, V = (a * x1 + b * x2) / (a + b), (a * v1 + b * v2) / (a + b)
        r = np.linalg.norm(x1 - x2, axis=-1)
        kinetic = 0.5 * m1 * np.sum(v1**2, axis=-1) + 0.5 * m2 * np.sum(v2**2, axis=-1)
        L = a * np.cross(x1 - R, v1 - V) + b * np.cross(x2 - R, v2 - V)
        return {"r1": x1, "r2": x2, "separation": r, "energy": kinetic - G * m1 * m2 / r,
                "angular_momentum": L}

    def native(self) -> NativeModel:
        m1, m2, G = self._flat()

        def observe(t, y):
            return self.observe_states(y[..., 0:3], y[..., 3:6], y[..., 6:9], y[..., 9:12])

        return NativeModel(y0=self.initial_state(), params=np.stack([G, m1, m2], axis=1), rhs=two_body_rhs,
                           accel=two_body_accel, observe=observe)

    def why_not(self, method: str) -> str:
        return f"{method!r} is not a two-body method (no exact splitting of the Kepler flow is provided)"

    # --- what other simulators build -------------------------------------------------------------

    def pair_force(self, x1, x2) -> np.ndarray:
        """Force on body 1 (T, 3) [N] from positions (T, 3) [m]: -G m1 m2 r/|r|^3, r = x1 - x2 (unbatched);
        body 2 feels its opposite."""
        self.require_single("pair_force")
        r = finite_array(x1, "x1").reshape(-1, 3) - finite_array(x2, "x2").reshape(-1, 3)
        distance = np.linalg.norm(r, axis=1, keepdims=True)
        return -float(self.G) * float(self.m1) * float(self.m2) * r / distance**3

    def _layout(self) -> Layout:
        x1, x2, v1, v2 = self.initial_state()[0].reshape(4, 3)
        radius = 0.05 * float(np.linalg.norm(self.separation))
        bodies, joints = [], []
        for name, mass, x, v in (("body1", float(self.m1), x1, v1), ("body2", float(self.m2), x2, v2)):
            # Reference pose at the origin, so the slide coordinates are the world x and z of the body.
            bodies.append(Body(name, Inertia.solid_sphere(mass, radius), shapes=(Shape(f"{name}_ball", "sphere",
                                                                                        (radius,)),)))
            joints.append(Joint(f"{name}_x", "slide", name, axis=(1.0, 0.0, 0.0), qpos0=float(x[0]),
                                qvel0=float(v[0])))
            joints.append(Joint(f"{name}_z", "slide", name, axis=(0.0, 0.0, 1.0), qpos0=float(x[2]),
                                qvel0=float(v[2])))
        return Layout(bodies=tuple(bodies), joints=tuple(joints))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        def planar(name):
            (x, vx), (z, vz) = joints[f"{name}_x"], joints[f"{name}_z"]
            zero = np.zeros_like(np.asarray(x, dtype=float))
            return (np.stack([x, zero, z], axis=-1)[:, None, :], np.stack([vx, zero, vz], axis=-1)[:, None, :])

        (x1, v1), (x2, v2) = planar("body1"), planar("body2")
        return {name: value[:, 0] for name, value in self.observe_states(x1, x2, v1, v2).items()}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Slides "body<i>_x", "body<i>_z": the world x and z of r<i> (T, 3) (reference pose at the origin)."""
        out = {}
        for i in (1, 2):
            r = observed(self, trajectory, f"r{i}", (3,))
            out[f"body{i}_x"], out[f"body{i}_z"] = r[:, 0], r[:, 2]
        return out

    def describe(self) -> str:
        return (f"{self.name}(m1={self.m1!r} kg, m2={self.m2!r} kg, G={self.G!r}, separation="
                f"{list(self.separation)} m, relative_velocity={list(self.relative_velocity)} m/s)")


def solve_kepler_elliptic(M: np.ndarray, e: np.ndarray) -> np.ndarray:
    """E with E - e sin E = M, by Newton's method to round-off. M (..., B) [rad], e (B,) in [0, 1).

    M is reduced to [-pi, pi) first (E - M is 2 pi periodic) and Danby's start E = M + 0.85 e sign(M)
    makes Newton converge for every e < 1."""
    M = np.asarray(M, dtype=np.float64)
    turns = np.round(M / (2 * np.pi))
    reduced = M - 2 * np.pi * turns
    M, e = np.broadcast_arrays(M, np.asarray(e, dtype=np.float64))
    turns, reduced = np.broadcast_to(turns, M.shape), np.broadcast_to(reduced, M.shape)
    E = reduced + 0.85 * e * np.sign(reduced)
    for _ in range(KEPLER_ITERATIONS):
        slope = 1 - e * np.cos(E)
        step = (E - e * np.sin(E) - reduced) / slope
        E = E - step
        # converged when the step is below the round-off of f = E - e sin E - M divided by f'
        if np.all(np.abs(step) <= 1e-15 * np.maximum(np.abs(E), (np.abs(E) + np.abs(reduced)) / slope)):
            break
    else:
        raise RuntimeError("Kepler's equation E - e sin E = M did not converge; report the orbit")
    return E + 2 * np.pi * turns


def solve_kepler_hyperbolic(M: np.ndarray, e: np.ndarray) -> np.ndarray:
    """H with e sinh H - H = M, by Newton's method to round-off. M (..., B), e (B,) > 1.

    f(H) = e sinh H - H - M is increasing and convex on the side of the root, so Newton's iterates from
    the start sign(M) log(2|M|/e + 1.8) pass the root at most once and then fall monotonically to it."""
    M, e = np.broadcast_arrays(np.asarray(M, dtype=np.float64), np.asarray(e, dtype=np.float64))
    H = np.sign(M) * np.log(2 * np.abs(M) / e + 1.8)
    for _ in range(KEPLER_ITERATIONS):
        slope = e * np.cosh(H) - 1
        step = (e * np.sinh(H) - H - M) / slope
        H = H - step
        # converged when the step is below the round-off of f = e sinh H - H - M divided by f'
        if np.all(np.abs(step) <= 1e-15 * np.maximum(np.abs(H), (e * np.abs(np.sinh(H)) + np.abs(M)) / slope)):
            break
    else:
        raise RuntimeError("Kepler's equation e sinh H - H = M did not converge; report the orbit")
    return H


def two_body(m1, m2, *, separation, relative_velocity, G=1.0, com_velocity=(0.0, 0.0, 0.0), t_end: float,
             gravity: float = 9.81) -> TwoBody:
    """Two bodies under mutual gravity (the chapter's two-body problem), in the x-z plane.

    m1, m2 [kg] and G may be arrays (a batch). separation r0 = x1 - x2 [m]: a distance along x or a
    (3,) vector with y = 0; relative_velocity r0' [m/s]: a speed along z or a (3,) vector with y = 0;
    com_velocity [m/s]: velocity of the centre of mass, which starts at the origin. gravity is accepted
    and not applied (no external force). Observables r1, r2, separation, energy, angular_momentum.
    """
    scene_arguments(gravity, t_end)
    return representable(TwoBody(name="two_body", t_end=t_end, gravity=gravity, m1=m1, m2=m2, separation=separation,
                   relative_velocity=relative_velocity, G=G, com_velocity=com_velocity))
