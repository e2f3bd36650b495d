"""The compound pendulum and the chapter's swinging rod.

A rigid body turns about a fixed horizontal axis through a pivot. With I the moment of inertia
about that axis and d the distance of the centre of mass from it, the chapter's energy
E = 1/2 I theta'^2 - M g d cos(theta) gives

    theta'' = -w0^2 sin(theta),    w0^2 = M g d / I,

the simple pendulum of length l = I / (M d) (for the rod about its end, I = M L^2/3: l = 2L/3).

Exact motion, with k^2 = sin^2(theta0/2) + omega0^2 / (4 w0^2) = (E + M g d) / (2 M g d):
- swinging (k < 1): sin(theta/2) = k sn(w0 t + u0 | k^2), cos(theta/2) = dn(...),
  theta' = 2 k w0 cn(w0 t + u0 | k^2), period 4 K(k^2) / w0;
- whirling (k > 1): theta/2 = am(k w0 t + u0 | 1/k^2), theta' = 2 k w0 dn(...), one turn every
  2 K(1/k^2) / (k w0);
- the separatrix (k = 1): theta/2 = gd(w0 t + u0) = atan(sinh(w0 t + u0)), theta' = 2 w0 sech(...).
Near the top (k -> 1) every elliptic function is evaluated from the complementary parameter
1 - k^2 = cos^2(theta0/2) - omega0^2/(4 w0^2), formed without cancellation: K(m) = ellipkm1(1 - m),
F(phi | m) = sin(phi) R_F(cos^2 phi, cos^2 phi + (1 - m) sin^2 phi, 1) (Carlson), and sn, cn, dn, am
by the arithmetic-geometric mean started from sqrt(1 - m) (scipy's ellipj loses all accuracy for
1 - m below about 1e-9).

Coordinates: world pivot at the origin, hinge axis along world y, theta = 0 with the centre of
mass straight below the pivot; positive theta turns the body about +y.

Native model: the scene's Layout (one body on one hinge, the model MuJoCo and pymunk read) runs on the
general engine (rbody.Scene.from_layout: theta is the hinge's qpos, omega its qvel), or on the hand-written
kernel pendulum_rhs / pendulum_accel (theta'' = -w0^2 sin theta), which is the engine's oracle in the tests
and stays the scene's fast path while FAST_PATH says it is more than 1.5x cheaper per step. Both paths offer
every method of PENDULUM_METHODS (one hinge: the engine's mass matrix is constant, so the symplectic methods
apply there too).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import carray, cfunc, njit
from scipy.special import ellipkm1, elliprf

from rbody.elliptic import jacobi
from rbody.checks import finite_array, positive, representable, scene_arguments
from rbody.inertia import Inertia, AxisLike, unit_axis
from rbody.motion import quat_from_matrix
from rbody.layout import Body, Joint, Layout, Shape
from rbody.engine import pointers
from rbody.engine.native import NativeModel
from rbody.poses import observed
from rbody.scene import Scene

# y = (theta, omega); params = (w0^2, I [kg m^2], M g d [N m])


@njit(cache=True)
def pendulum_rhs(y, p, out):
    out[0] = y[1]
    out[1] = -p[0] * np.sin(y[0])


@njit(cache=True)
def pendulum_accel(q, p, out):
    out[0] = -p[0] * np.sin(q[0])


# The two kernels as C function pointers kept in numba's disk cache (rbody.engine.pointers): a warm start compiles
# no wrapper.
def _rhs_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def pendulum_rhs_c(y, p, out, n, m):
        pendulum_rhs(carray(y, n), carray(p, m), carray(out, n))
    return pendulum_rhs_c


def _accel_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def pendulum_accel_c(q, p, out, n, m):
        pendulum_accel(carray(q, n), carray(p, m), carray(out, n))
    return pendulum_accel_c


pointers.register(pendulum_rhs, "rhs", _rhs_pointer)
pointers.register(pendulum_accel, "rhs", _accel_pointer)


# Which kernel native() runs: True, the hand-written pendulum_rhs / pendulum_accel; False, the general engine on
# the scene's Layout. ns per step, hand kernel / engine (its planar path): rk4 73 / 233 (3.2x cheaper) for the rod
# and for the disc, verlet 28 / 66 (2.3x) (one pendulum, dt = 1e-3; python benchmarks/fast_paths.py --repeats 5,
# 2026-11-23, commit a920624, AMD EPYC, 2 cores, idle). Before the planar path: 49x for rk4.
FAST_PATH = True

PENDULUM_METHODS = ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6", "reference")


@dataclass(frozen=True, kw_only=True)
class Pendulum(Scene):
    """A rigid body on a fixed horizontal hinge: the compound pendulum.

    theta0 [rad], omega0 [rad/s] may be arrays (a batch). Subclasses give the moment about the
    hinge `moment_pivot` [kg m^2], `mass` [kg] and `distance` d of the centre of mass [m].
    """

    theta0: Any
    omega0: Any = 0.0

    observables: ClassVar[tuple[str, ...]] = ("theta", "omega", "energy")
    main_observable: ClassVar[str] = "theta"
    preferred_methods: ClassVar[tuple[str, ...]] = PENDULUM_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("theta0", "omega0")

    def __post_init__(self) -> None:
        super().__post_init__()
        finite_array(self.theta0, "theta0")
        finite_array(self.omega0, "omega0")
        self.batch_shape  # noqa: B018 - checks that the parameters broadcast

    # --- the physics, as flat (B,) arrays -------------------------------------------------------

    def _mass(self) -> np.ndarray:
        raise NotImplementedError

    def _moment_pivot(self) -> np.ndarray:
        raise NotImplementedError

    def _distance(self) -> np.ndarray:
        raise NotImplementedError

    def _w0_squared(self) -> np.ndarray:
        """w0^2 = M g d / I [1/s^2], (B,)."""
        return self._mass() * self.gravity * self._distance() / self._moment_pivot()

    def _state0(self) -> tuple[np.ndarray, np.ndarray]:
        return self.batched("theta0"), self.batched("omega0")

    @property
    def equivalent_length(self) -> np.ndarray | float:
        """Length I / (M d) [m] of the simple pendulum with the same motion."""
        return self.unflatten(self._moment_pivot() / (self._mass() * self._distance()))

    @property
    def modulus(self) -> np.ndarray | float:
        """k^2 = sin^2(theta0/2) + omega0^2 / (4 w0^2) [-]: < 1 swinging, > 1 whirling."""
        theta0, omega0 = self._state0()
        with np.errstate(divide="ignore", invalid="ignore"):  # no gravity: inf (a turn), nan at rest
            return self.unflatten(np.sin(theta0 / 2) ** 2 + omega0**2 / (4 * self._w0_squared()))

    def _one_minus_modulus(self) -> np.ndarray:
        """1 - k^2 formed without cancellation near the top."""
        theta0, omega0 = self._state0()
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.cos(theta0 / 2) ** 2 - omega0**2 / (4 * self._w0_squared())

    @property
    def period(self) -> np.ndarray | float:
        """Exact period [s]: 4 K(k^2)/w0 when swinging (2 pi/w0 at rest at the bottom),
        2 K(1/k^2)/(k w0) per turn when whirling, inf on the separatrix."""
        w0 = np.sqrt(self._w0_squared())
        theta0, omega0 = self._state0()
        with np.errstate(divide="ignore", invalid="ignore"):
            m = np.broadcast_to(np.asarray(self.modulus, dtype=float), self.batch_shape).reshape(-1)
            complement = self._one_minus_modulus()
            swinging = 4 * ellipkm1(np.maximum(complement, 0.0)) / w0
            k = np.sqrt(np.maximum(m, 1.0))
            # 1 - 1/k^2 = -(1 - k^2)/k^2, without cancellation near the separatrix
            whirling = 2 * ellipkm1(np.maximum(-complement, 0.0) / np.maximum(m, 1.0)) / (k * w0)
            # No gravity (w0 = 0): a uniform turn, 2 pi / |omega0| per turn (inf at rest).
            uniform = 2 * np.pi / np.abs(omega0)
        period = np.where(complement > 0, swinging, np.where(complement < 0, whirling, np.inf))
        return self.unflatten(np.where(w0 == 0, uniform, period))

    def energy_of(self, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """E = 1/2 I omega^2 - M g d cos(theta) [J]; theta, omega (..., B)."""
        moment, mgd = self._moment_pivot(), self._mass() * self.gravity * self._distance()
        return 0.5 * moment * omega**2 - mgd * np.cos(theta)

    # --- closed form ---------------------------------------------------------------------------

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)[:, None]  # (T, 1) against (B,)
        theta0, omega0 = self._state0()
        w0 = np.sqrt(self._w0_squared())
        with np.errstate(divide="ignore", invalid="ignore"):  # w0 = 0 (no gravity): _uniform below
            m = np.sin(theta0 / 2) ** 2 + omega0**2 / (4 * w0**2)
            complement = self._one_minus_modulus()  # 1 - m, accurate near the top
        theta = np.empty((t.shape[0], theta0.size))
        omega = np.empty_like(theta)
        for b in range(theta0.size):
            if w0[b] == 0:
                motion = _uniform     # no gravity: no torque
            elif m[b] < HARMONIC_MODULUS:
                motion = _harmonic    # k^2 -> 0: sn(u)/k is 0/0 at rest at the bottom
            elif complement[b] > 0:
                motion = _swinging
            elif complement[b] < 0:
                motion = _whirling
            else:
                motion = _separatrix
            theta[:, b], omega[:, b] = motion(t[:, 0], theta0[b], omega0[b], w0[b], m[b], complement[b])
        energy = np.broadcast_to(self.energy_of(theta0, omega0), theta.shape)
        shape = (t.shape[0],) + self.batch_shape
        return {"theta": theta.reshape(shape), "omega": omega.reshape(shape),
                "energy": np.array(energy).reshape(shape)}

    # --- native model ----------------------------------------------------------------------------

    def native(self) -> NativeModel:
        """The hand kernel (hand_model) when the module's FAST_PATH is True, else the general engine
        (engine_model); the same observables either way."""
        model = self.hand_model() if FAST_PATH else self.engine_model()
        # the stability rate is the small-swing w0 = sqrt(M g d / I); near the top, the margin 1 - k^2
        return dataclasses.replace(model, rate=lambda method: np.sqrt(self._w0_squared()),
                                   separatrix_margin=self._one_minus_modulus())

    def engine_model(self) -> NativeModel:
        """The pendulum on the general engine: the scene's Layout as a TreeScene (rbody.Scene.from_layout), state
        y (B, 2) = (hinge qpos, hinge qvel) = (theta, omega). Batched physical parameters (a rod's length and
        mass) give each batch element the model row of its own Layout (one row per distinct set)."""
        theta0, omega0 = self._state0()
        physical = [name for name in self.batch_fields if name not in ("theta0", "omega0")]
        keys = np.stack([self.batched(name) for name in physical], axis=1) if physical else np.zeros((theta0.size, 0))
        distinct, which = np.unique(keys, axis=0, return_inverse=True)
        trees = [self._engine_tree(dict(zip(physical, row.tolist()))) for row in distinct]
        tree = dataclasses.replace(trees[0], qpos0=theta0[:, None], qvel0=omega0[:, None])
        model = tree.family_native()
        rows = [model.params[0]] + [other.native().params[0] for other in trees[1:]]
        if len({row.shape for row in rows}) != 1:
            raise ValueError(f"scene {self.describe()}: the engine's model rows differ in size across the batch")
        moment, mgd = self._moment_pivot(), self._mass() * self.gravity * self._distance()

        def observe(t, y):
            """theta, omega: the hinge's qpos and qvel; energy lazily, as the hand kernel's."""
            data = model.observe(t, y)
            theta, omega = data["qpos"][..., 0], data["qvel"][..., 0]  # arrays (the rest is lazy)
            return {"theta": theta, "omega": omega, "energy": lambda: _energy(moment, mgd, theta, omega)}

        return dataclasses.replace(model, params=np.stack(rows)[np.reshape(which, -1)], observe=observe)

    def _engine_tree(self, physics: dict[str, float]):
        """TreeScene of the Layout of one batch element with the physical parameters `physics`."""
        one = dataclasses.replace(self, theta0=0.0, omega0=0.0, **physics)
        return Scene.from_layout(one._layout(), t_end=self.t_end, name=self.name, gravity=self.gravity)

    def hand_model(self) -> NativeModel:
        """The hand-written kernel: y (B, 2) = (theta, omega), params (w0^2, I, M g d)."""
        theta0, omega0 = self._state0()
        moment, mgd = self._moment_pivot(), self._mass() * self.gravity * self._distance()
        params = np.stack([self._w0_squared(), moment, mgd], axis=1)

        def observe(t, y):
            """theta, omega: views of y (T, B, 2), no copy; energy lazily (module trajectory)."""
            theta, omega = y[..., 0], y[..., 1]
            return {"theta": theta, "omega": omega, "energy": lambda: _energy(moment, mgd, theta, omega)}

        return NativeModel(y0=np.stack([theta0, omega0], axis=1), params=params, rhs=pendulum_rhs,
                           accel=pendulum_accel, observe=observe)

    def why_not(self, method: str) -> str:
        return f"{method!r} is not a pendulum method"

    # --- what other simulators build ---------------------------------------------------------------

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        theta, omega = joints["hinge"]
        return {"theta": theta, "omega": omega, "energy": self.energy_of(theta, omega)}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """The hinge's angle is theta."""
        return {"hinge": observed(self, trajectory, "theta")}


ENERGY_BLOCK = 1 << 18  # elements per block of the energy: its temporaries stay a few MB


def _energy(moment: np.ndarray, mgd: np.ndarray, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """(T, B) E = 1/2 I omega^2 - M g d cos(theta) [J] from theta, omega (T, B) and I, M g d (B,), the
    arithmetic of Pendulum.energy_of, a block of samples at a time: the temporaries of the whole
    expression would be three more (T, B) arrays (2.4 GB for 10^6 rods and 101 samples)."""
    energy = np.empty(theta.shape)
    rows = max(1, ENERGY_BLOCK // max(1, theta.shape[-1]))
    for lo in range(0, theta.shape[0], rows):
        block = slice(lo, lo + rows)
        energy[block] = 0.5 * moment * omega[block] ** 2 - mgd * np.cos(theta[block])
    return energy


def _uniform(t: np.ndarray, theta0: float, omega0: float, w0: float, m: float, m1: float):
    """The limit of no torque, w0 = 0 (gravity 0): theta = theta0 + omega0 t, a uniform turn."""
    return theta0 + omega0 * t, np.full_like(t, omega0, dtype=np.float64)


# Below this k^2 the swing is harmonic to round-off: the relative error of sin(theta) ~ theta is
# ~ theta^2/6 ~ (2/3) k^2, and k^2 itself underflows (theta0 = 1e-200 gives k^2 = 0).
HARMONIC_MODULUS = 1e-20


def _harmonic(t: np.ndarray, theta0: float, omega0: float, w0: float, m: float, m1: float):
    """The limit k^2 -> 0 (at rest at the bottom, or amplitude below 1e-10 rad): theta = 2 pi n +
    delta0 cos(w0 t) + (omega0 / w0) sin(w0 t), delta0 = theta0 - 2 pi n; at rest theta stays theta0."""
    turns = 2 * np.pi * np.round(theta0 / (2 * np.pi))
    delta0 = theta0 - turns
    phase = w0 * t
    return (turns + delta0 * np.cos(phase) + omega0 / w0 * np.sin(phase),
            -delta0 * w0 * np.sin(phase) + omega0 * np.cos(phase))


def _swinging(t: np.ndarray, theta0: float, omega0: float, w0: float, m: float, m1: float):
    """sin(theta/2) = k sn(u), cos(theta/2) = dn(u), theta' = 2 k w0 cn(u), u = w0 t + u0; m1 = 1 - m > 0."""
    k = np.sqrt(m)
    turns = 2 * np.pi * np.round(theta0 / (2 * np.pi))  # the swing is about the nearest bottom
    half = (theta0 - turns) / 2
    # sn(u0) = sin(theta0/2)/k, cn(u0) = omega0/(2 k w0), dn(u0) = cos(theta0/2): u0 = F(am u0 | m) in
    # Carlson's form sn R_F(cn^2, dn^2, 1), from sn, cn, dn directly: an amplitude rounded to fl(pi/2) would
    # carry cos = 6e-17, not small beside sqrt(1 - m) near the top. cn < 0: F = 2K sign(sn) - F(pi - am).
    quarter = ellipkm1(m1)
    sn0, cn0, dn0 = np.sin(half) / k, omega0 / (2 * k * w0), np.cos(half)
    f = sn0 * elliprf(cn0 * cn0, dn0 * dn0, 1.0)
    u = w0 * t + (f if cn0 >= 0 else np.copysign(2 * quarter, sn0) - f)
    u = u - 4 * quarter * np.round(u / (4 * quarter))  # sn, cn have period 4K
    sn, cn, dn, _am = jacobi(u, m, m1)
    return turns + 2 * np.arctan2(k * sn, dn), 2 * k * w0 * cn


def _whirling(t: np.ndarray, theta0: float, omega0: float, w0: float, m: float, m1: float):
    """theta/2 = am(u | 1/m), theta' = 2 k w0 dn(u | 1/m), u = u0 +- k w0 t; m1 = 1 - m < 0."""
    k = np.sqrt(m)
    direction = 1.0 if omega0 > 0 else -1.0
    parameter, parameter1 = 1.0 / m, -m1 / m  # 1/k^2 and 1 - 1/k^2
    quarter = ellipkm1(parameter1)
    u = _elliptic_f(theta0 / 2, parameter1, quarter) + direction * k * w0 * t
    # am(u + 2nK) = am(u) + n pi: reduce u to [-K, K] and count the half turns of theta/2.
    turns = np.round(u / (2 * quarter))
    _sn, _cn, dn, am = jacobi(u - 2 * quarter * turns, parameter, parameter1)
    return 2 * (turns * np.pi + am), direction * 2 * k * w0 * dn


def _separatrix(t: np.ndarray, theta0: float, omega0: float, w0: float, m: float, m1: float):
    """k = 1: theta/2 = gd(u) = atan(sinh u), theta' = 2 w0 sech(u), u = u0 +- w0 t (towards the top)."""
    turns = 2 * np.pi * np.round(theta0 / (2 * np.pi))
    direction = 1.0 if omega0 > 0 else -1.0
    u = np.arctanh(np.sin((theta0 - turns) / 2)) + direction * w0 * t
    with np.errstate(over="ignore"):  # sinh, cosh -> inf: theta at the top, theta' = 0
        return turns + 2 * np.arctan(np.sinh(u)), direction * 2 * w0 / np.cosh(u)


def _elliptic_f(phi: float | np.ndarray, m1: float, quarter: float) -> np.ndarray:
    """Incomplete elliptic integral F(phi | m) for any phi, from m1 = 1 - m: Carlson's
    F = sin(phi) R_F(cos^2 phi, cos^2 phi + m1 sin^2 phi, 1) on [-pi/2, pi/2], and F(phi + n pi) = F(phi) + 2 n K."""
    n = np.round(np.asarray(phi) / np.pi)
    reduced = phi - n * np.pi
    s, c = np.sin(reduced), np.cos(reduced)
    return s * elliprf(c * c, c * c + m1 * s * s, 1.0) + 2 * n * quarter


def _hinge_frame(offset_body: np.ndarray, axis_body: np.ndarray) -> np.ndarray:
    """Rotation taking the body frame to the world at theta = 0: hinge axis -> world y, the part of
    (com - pivot) across the axis -> world -z (the centre of mass hangs below the pivot)."""
    e2 = axis_body
    across = offset_body - (offset_body @ e2) * e2
    e1 = across / np.linalg.norm(across)
    body_basis = np.column_stack([e1, e2, np.cross(e1, e2)])
    world_basis = np.column_stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    return world_basis @ body_basis.T


@dataclass(frozen=True, kw_only=True)
class CompoundPendulum(Pendulum):
    """Any Inertia swinging about the axis through `pivot` (3,) (body frame, [m])."""

    body: Inertia
    pivot: Any = (0.0, 0.0, 0.0)
    axis: AxisLike = "y"
    shapes: tuple[Shape, ...] = ()

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.body, Inertia):
            raise ValueError(f"body={self.body!r}: expected an rbody.Inertia")
        pivot = finite_array(self.pivot, "pivot", shape=(3,))
        axis = unit_axis(self.axis)
        offset = self.body.com - pivot
        distance = np.linalg.norm(offset - (offset @ axis) * axis)
        if distance <= 1e-12 * max(np.linalg.norm(offset), np.sqrt(self.body.moment(axis) / self.body.mass), 1e-300):
            raise ValueError(
                f"pivot={pivot.tolist()}: the hinge passes through the centre of mass {self.body.com.tolist()}, "
                "so gravity exerts no torque and there is no pendulum motion; move the pivot off the centre of mass")
        object.__setattr__(self, "pivot", tuple(pivot.tolist()))
        object.__setattr__(self, "axis", tuple(axis.tolist()))

    def _mass(self):
        return np.full(int(np.prod(self.batch_shape)), self.body.mass)

    def _moment_pivot(self):
        return np.full_like(self._mass(), self.body.moment(self.axis, through=self.pivot))

    def _distance(self):
        axis, offset = np.array(self.axis), self.body.com - np.array(self.pivot)
        return np.full_like(self._mass(), np.linalg.norm(offset - (offset @ axis) * axis))

    def _layout(self) -> Layout:
        pivot, axis = np.array(self.pivot), np.array(self.axis)
        rotation = _hinge_frame(self.body.com - pivot, axis)
        # Reference pose (theta = 0): the pivot sits at the world origin, the centre of mass below it.
        body = Body("body", self.body, shapes=self.shapes, pos=tuple((-rotation @ pivot).tolist()),
                    quat=tuple(quat_from_matrix(rotation).tolist()))
        hinge = Joint("hinge", "hinge", "body", axis=tuple(axis.tolist()), anchor=tuple(pivot.tolist()),
                      qpos0=float(self.theta0), qvel0=float(self.omega0))
        return Layout(bodies=(body,), joints=(hinge,))

    def describe(self) -> str:
        return f"{self.name}(m={self.body.mass:g} kg, theta0={self.theta0!r})"


@dataclass(frozen=True, kw_only=True)
class SwingingRod(Pendulum):
    """The chapter's rod of length L [m] and mass M [kg] swinging about one end: I = M L^2/3, d = L/2.

    The rod lies along its body z axis from the pivot (z = 0) to z = -L... its centre of mass at
    z = -L/2 in the frame whose origin is the pivot. length and mass may be arrays (a batch).
    """

    length: Any
    mass: Any = 1.0
    radius_fraction: float = 0.01  # drawing/collision radius as a fraction of L (MuJoCo needs a thickness)

    batch_fields: ClassVar[tuple[str, ...]] = ("theta0", "omega0", "length", "mass")

    def __post_init__(self) -> None:
        positive(self.length, "length")
        positive(self.mass, "mass")
        super().__post_init__()

    def _mass(self):
        return self.batched("mass")

    def _moment_pivot(self):
        return self.batched("mass") * self.batched("length") ** 2 / 3

    def _distance(self):
        return self.batched("length") / 2

    def rod_inertia(self) -> Inertia:
        """Mass properties of the (unbatched) rod in its body frame, pivot at the origin."""
        return Inertia.rod(float(self.mass), float(self.length), "z").translated([0, 0, -float(self.length) / 2])

    def _layout(self) -> Layout:
        length = float(self.length)
        radius = self.radius_fraction * length
        shape = Shape("rod", "capsule", (radius, length / 2), pos=(0.0, 0.0, -length / 2))
        return CompoundPendulum(name=self.name, t_end=self.t_end, gravity=self.gravity, body=self.rod_inertia(),
                                pivot=(0.0, 0.0, 0.0), axis="y", theta0=self.theta0, omega0=self.omega0,
                                shapes=(shape,))._layout()

    def describe(self) -> str:
        return f"{self.name}(L={self.length!r} m, theta0={self.theta0!r} rad)"


def compound_pendulum(body: Inertia, *, pivot, axis: AxisLike = "y", theta0, omega0=0.0, t_end: float,
                      gravity: float = 9.81, shapes: tuple[Shape, ...] = ()) -> CompoundPendulum:
    """Any rigid body swinging about the fixed axis through `pivot` (body frame [m]).

    theta0 [rad] and omega0 [rad/s] may be arrays (a batch). Observables theta, omega, energy.
    """
    scene_arguments(gravity, t_end)
    return representable(CompoundPendulum(name="compound_pendulum", t_end=t_end, gravity=gravity, body=body, pivot=pivot,
                            axis=axis, theta0=theta0, omega0=omega0, shapes=tuple(shapes)))


def swinging_rod(length, mass=1.0, *, theta0, omega0=0.0, t_end: float, gravity: float = 9.81) -> SwingingRod:
    """The chapter's swinging rod about its end (I = M L^2/3; equivalent simple pendulum 2L/3).

    length [m], mass [kg], theta0 [rad], omega0 [rad/s] may be arrays that broadcast to a batch.
    """
    scene_arguments(gravity, t_end)
    return representable(SwingingRod(name="swinging_rod", t_end=t_end, gravity=gravity, length=length, mass=mass,
                       theta0=theta0, omega0=omega0))
