"""Free rotation of a rigid body: Euler's equations, solved with Jacobi's elliptic functions.

No torque acts about the centre of mass, so the angular momentum L = I w (the chapter's relation
between L and w, which need not be parallel) is fixed in the world and the kinetic energy
T = 1/2 w^T I w is conserved. In the principal frame (moments I1 < I2 < I3) L turns against the
body, which is Euler's equations

    I1 w1' = (I2 - I3) w2 w3,    I2 w2' = (I3 - I1) w3 w1,    I3 w3' = (I1 - I2) w1 w2,

and the orientation R (principal axes to world) follows R' = R [w]x, i.e. q' = 1/2 q (0, w).

Exact motion (Landau & Lifshitz, Mechanics, section 37). With 2T = sum I w^2, L^2 = sum I^2 w^2 and
the three non-negative combinations (each formed as a sum of terms of one sign, without
cancellation)

    D3 = 2T I3 - L^2 = I1 w1^2 (I3 - I1) + I2 w2^2 (I3 - I2)
    D1 = L^2 - 2T I1 = I2 w2^2 (I2 - I1) + I3 w3^2 (I3 - I1)
    d  = L^2 - 2T I2 = I3 w3^2 (I3 - I2) - I1 w1^2 (I2 - I1)

the polhode encircles axis 3 when d > 0:

    w1 = A1 cn(u | m),  w2 = A2 sn(u | m),  w3 = s3 A3 dn(u | m),  u = u0 + lam t,
    A1^2 = D3 / (I1 (I3 - I1)),  A2^2 = D3 / (I2 (I3 - I2)),  A3^2 = D1 / (I3 (I3 - I1)),
    lam = s3 sqrt((I3 - I2) D1 / (I1 I2 I3)),  m = (I2 - I1) D3 / ((I3 - I2) D1),
    1 - m = (I3 - I1) d / ((I3 - I2) D1),   s3 = sign w3(0),   am(u0) = atan2(w2/A2, w1/A1).

When d < 0 it encircles axis 1: the same formulas hold in the frame E whose axes are
(3, -2, 1) of the principal frame (a proper rotation, which keeps the form of Euler's equations),
with the moments (I3, I2, I1) and lam = s3 sign(I3' - I2') |lam| = -s3 |lam|. omega_body is
periodic with period 4 K(m) / |lam|: near the intermediate axis this is the time between the
flips of the tennis racket. On the separatrix d = 0 (m = 1) the motion is the limit
w1 = s1 A1 sech u, w2 = A2 tanh u, w3 = s3 A3 sech u, lam = s1 s3 sign(I3' - I2') |lam|: one flip,
never repeated.
A body with two equal moments precesses uniformly (m = 0: cn = cos, sn = sin, dn = 1).

Orientation: in frame E, Euler angles (Z X Z) with L along the fixed world direction S e_z,
R_E = S Rz(phi) Rx(theta) Rz(psi), where L_E = |L| (sin theta sin psi, sin theta cos psi, cos theta)
gives theta and psi from w, and phi' = |L| (I1 w1^2 + I2 w2^2) / (I1^2 w1^2 + I2^2 w2^2) integrates to

    phi = |L| t / I3 + |L| (I3 - I1) / (I1 I3 lam) [Pi(-n; am u | m) - Pi(-n; am u0 | m)],
    n = I3 (I2 - I1) / (I1 (I3 - I2)),

with Pi the incomplete elliptic integral of the third kind (Carlson's R_F and R_J). Every elliptic
function is evaluated from the complementary parameter 1 - m above, so that it stays accurate as the
spin approaches the intermediate axis.

Native model: y = (q (4,), w (3,)), the orientation of the principal axes and the angular velocity
in them. "splitting" is the symmetric splitting of T = sum L_i^2 / (2 I_i) into the three exactly
integrable rotations about the principal axes (McLachlan 1993; Dullweber, Leimkuhler & McLachlan
1997): for T_i = L_i^2 / (2 I_i) over a time h the body turns about its axis i by the angle
h L_i / I_i = h w_i, so q <- q (cos(h w_i / 2), sin(h w_i / 2) e_i) and the body components of L
turn about e_i by -h w_i (L_world fixed). The step 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2) is symmetric,
symplectic and keeps L_world and |q| to round-off (the energy only stays bounded); "yoshida6" is its
6th-order composition. euler, rk4 and gauss6 integrate q' = 1/2 q (0, w) as it stands: the quaternion
is reported as integrated, never renormalised, so its drift in |q| shows.

Two native paths, the same observables (native() picks one by FAST_PATH):
- the hand kernel above (hand_model): the engine's oracle in the tests, and the scene's fast path while
  FAST_PATH says it is more than 1.5x cheaper per step;
- the general engine (engine_model): the scene's Layout (one body on a free joint, the model MuJoCo reads)
  as a TreeScene, state (qpos: origin of the body frame and its quaternion, qvel: that origin's world velocity
  and the angular velocity in the Inertia's axes, phi: the rotation within a step). omega_body is the free
  joint's angular velocity, quaternion its quaternion, which stays unit by construction under every method
  (Runge-Kutta-Munthe-Kaas), unlike the hand kernel's. The engine has no splitting into exact flows: there
  "splitting" and "yoshida6" run the family's own free_rotation_step, on the engine's state mapped to the
  principal frame and back each step (free_rotation_tree_step), the centre of mass held where it is.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numba import njit
from scipy.special import elliprf, elliprj

from rbody.elliptic import jacobi
from rbody.checks import finite_array, representable, scene_arguments
from rbody.engine import integrators, spatial
from rbody.inertia import Inertia
from rbody.motion import quat_conjugate, quat_exp, quat_from_matrix, quat_multiply, quat_to_matrix
from rbody.layout import Body, Joint, Layout, Shape
from rbody.engine.native import NativeModel
from rbody.poses import observed
from rbody.scene import BodyStates, Scene

# Principal moments closer than this fraction of the largest are one repeated moment: eigh returns
# them only to ~1e-16 of the largest, so a smaller difference is not a property of the body.
MOMENT_RTOL = 1e-12

# Thinnest side of the drawing box, as a fraction of its longest (a lamina, I1 + I2 = I3, has none).
MIN_BOX_FRACTION = 1e-3

FREE_ROTATION_METHODS = ("splitting", "euler", "rk4", "yoshida6", "gauss6", "reference")

# y = (qw, qx, qy, qz, w1, w2, w3), principal frame; params = (I1, I2, I3) [kg m^2]


@njit(cache=True)
def free_rotation_rhs(y, p, out):
    qw, qx, qy, qz = y[0], y[1], y[2], y[3]
    w1, w2, w3 = y[4], y[5], y[6]
    # q' = 1/2 q (0, w)
    out[0] = -0.5 * (qx * w1 + qy * w2 + qz * w3)
    out[1] = 0.5 * (qw * w1 + qy * w3 - qz * w2)
    out[2] = 0.5 * (qw * w2 - qx * w3 + qz * w1)
    out[3] = 0.5 * (qw * w3 + qx * w2 - qy * w1)
    # Euler's equations
    out[4] = (p[1] - p[2]) * w2 * w3 / p[0]
    out[5] = (p[2] - p[0]) * w3 * w1 / p[1]
    out[6] = (p[0] - p[1]) * w1 * w2 / p[2]


@njit(cache=True)
def _axis_flow(y, p, i, h):
    """Exact flow of T_i = L_i^2 / (2 I_i) for a time h: rotation about body axis i by h w_i."""
    j, k = (i + 1) % 3, (i + 2) % 3
    angle = h * y[4 + i]
    c, s = np.cos(angle), np.sin(angle)
    # L_body turns about e_i by -angle (L' = L x w); w_i is unchanged.
    lj, lk = p[j] * y[4 + j], p[k] * y[4 + k]
    y[4 + j] = (c * lj + s * lk) / p[j]
    y[4 + k] = (c * lk - s * lj) / p[k]
    # q <- q (cos(angle/2), sin(angle/2) e_i)
    ch, sh = np.cos(0.5 * angle), np.sin(0.5 * angle)
    qw, qi, qj, qk = y[0], y[1 + i], y[1 + j], y[1 + k]
    y[0] = ch * qw - sh * qi
    y[1 + i] = ch * qi + sh * qw
    y[1 + j] = ch * qj + sh * qk
    y[1 + k] = ch * qk - sh * qj


@njit(cache=True)
def free_rotation_step(y, p, h):
    """One symmetric step 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2) of the splitting, in place."""
    _axis_flow(y, p, 0, 0.5 * h)
    _axis_flow(y, p, 1, 0.5 * h)
    _axis_flow(y, p, 2, h)
    _axis_flow(y, p, 1, 0.5 * h)
    _axis_flow(y, p, 0, 0.5 * h)


# Which kernel native() runs: True, the hand-written free_rotation_rhs (and its splitting); False, the general
# engine on the scene's Layout. Hand kernel 78 ns against the engine's 3276 ns per rk4 step, 42x cheaper (one
# body, dt = 1e-3; python benchmarks/fast_paths.py --repeats 5, 2026-11-23, commit a920624, AMD EPYC, 2 cores,
# idle). The splitting costs about the same on either state (202 / 282 ns).
FAST_PATH = True

# The columns free_rotation_tree_step reads after the engine's model row: principal moments (3) [kg m^2],
# the quaternion (4) of the principal axes in the Inertia's frame, the centre of mass (3) in that frame [m].
TREE_STEP_COLUMNS = 10


@njit(cache=True)
def free_rotation_tree_step(y, p, h):
    """One step of free_rotation_step on the engine's state y = (origin (3), quat (4), v (3), w_body (3), phi
    (3)), in place: to the principal frame (q_p = q (x) q_axes, w_p = P^T w_body), the family's step, and back;
    the centre of mass stays where it was and the origin moves with it rigidly (v = -R (w_body x com)).
    p: the engine's row, then TREE_STEP_COLUMNS columns (above). phi is zero between steps and left so."""
    t = p.shape[0] - TREE_STEP_COLUMNS
    moments, axes, com = p[t:t + 3], p[t + 3:t + 7], p[t + 7:t + 10]
    z = np.empty(20)
    principal, inverse, arm_before, arm_after, spin = z[0:7], z[7:11], z[11:14], z[14:17], z[17:20]
    inverse[0], inverse[1], inverse[2], inverse[3] = axes[0], -axes[1], -axes[2], -axes[3]
    spatial.quat_rotate(y[3:7], com, arm_before)  # R com before the step
    spatial.quat_multiply(y[3:7], axes, principal[0:4])
    spatial.quat_rotate(inverse, y[10:13], principal[4:7])
    free_rotation_step(principal, moments, h)
    spatial.quat_multiply(principal[0:4], inverse, y[3:7])
    spatial.quat_rotate(axes, principal[4:7], y[10:13])
    spatial.quat_rotate(y[3:7], com, arm_after)
    for a in range(3):
        y[a] += arm_before[a] - arm_after[a]  # the centre, origin + R com, stays put
    spin[0] = com[1] * y[12] - com[2] * y[11]  # com x w_body = -(w_body x com)
    spin[1] = com[2] * y[10] - com[0] * y[12]
    spin[2] = com[0] * y[11] - com[1] * y[10]
    spatial.quat_rotate(y[3:7], spin, y[7:10])  # v = R (com x w_body)


# The relabelling (1, 2, 3) -> (3, -2, 1): principal coordinates x_p = FLIP x_E (a proper rotation).
FLIP = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])


@dataclass(frozen=True, kw_only=True)
class FreeRotation(Scene):
    """A rigid body turning freely about its centre of mass, which stays at rest.

    inertia: the body's mass properties; every principal moment must be > 0
    omega0:  (..., 3) initial angular velocity [rad/s], in the Inertia's axes (= world axes at
             t = 0, where the orientation is the identity); leading axes are a batch
    gravity: always 0: uniform gravity exerts no torque about the centre of mass and would only
             move the centre, which this scene holds at rest (MuJoCo is given zero gravity)
    Observables: omega_body (3,) in the Inertia's axes [rad/s], L_world (3,) [kg m^2/s],
    energy [J], quaternion (4,) body to world (w, x, y, z).
    """

    inertia: Inertia
    omega0: Any
    gravity: float = 0.0

    observables: ClassVar[tuple[str, ...]] = ("omega_body", "L_world", "energy", "quaternion")
    main_observable: ClassVar[str] = "omega_body"
    planar: ClassVar[bool] = False
    preferred_methods: ClassVar[tuple[str, ...]] = FREE_ROTATION_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("omega0",)  # carries a trailing vector axis (3,)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.gravity != 0.0:
            raise ValueError(
                f"gravity={self.gravity!r}: a free rotation has gravity 0 (uniform gravity exerts no torque "
                "about the centre of mass and would only move it)")
        if not isinstance(self.inertia, Inertia):
            raise ValueError(f"inertia={self.inertia!r}: expected an rbody.Inertia")
        omega0 = finite_array(self.omega0, "omega0")
        if omega0.ndim == 0 or omega0.shape[-1] != 3:
            raise ValueError(f"omega0 has shape {omega0.shape}: expected (3,) or a batch (..., 3) [rad/s]")
        omega0.flags.writeable = False
        object.__setattr__(self, "omega0", omega0)
        moments, _axes = self.inertia.principal()
        if not moments[0] > MOMENT_RTOL * moments[2]:
            raise ValueError(
                f"inertia has principal moments {moments.tolist()} kg m^2: free rotation needs every principal "
                f"moment > 0 (> {MOMENT_RTOL:g} of the largest); a thin rod or a point mass has none about some "
                "axis, so its spin about that axis is undefined")

    # --- batches ------------------------------------------------------------------------------------

    @cached_property
    def batch_shape(self) -> tuple[int, ...]:
        """omega0.shape[:-1]: the leading axes of omega0."""
        return tuple(np.shape(self.omega0)[:-1])

    def batched(self, name: str) -> np.ndarray:
        """omega0 flattened to (B, 3) [rad/s]."""
        if name != "omega0":
            raise ValueError(f"name={name!r}: the only batched parameter of a free rotation is 'omega0'")
        return np.asarray(self.omega0).reshape(-1, 3)

    def item(self, index: int | tuple = ()) -> "FreeRotation":
        """The unbatched scene of omega0[index]."""
        if not self.batch_shape:
            return self
        omega = np.asarray(self.omega0)[index]
        if omega.shape != (3,):
            raise ValueError(f"index={index!r} picks omega0 of shape {omega.shape}: expected one (3,) vector")
        return dataclasses.replace(self, omega0=omega.copy())

    # --- the principal frame -----------------------------------------------------------------------

    @cached_property
    def _principal(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments ascending (3,) [kg m^2], equal ones made exactly equal, and the axes
        P (3,3) as columns of the Inertia's frame (x_body = P x_principal)."""
        moments, axes = self.inertia.principal()
        return _merge_equal(moments), axes

    @property
    def principal_moments(self) -> np.ndarray:
        """(3,) principal moments ascending [kg m^2] (moments equal to MOMENT_RTOL made equal)."""
        return self._principal[0].copy()

    def _tensor(self) -> np.ndarray:
        moments, axes = self._principal
        return axes @ np.diag(moments) @ axes.T

    @cached_property
    def _tops(self) -> list["_EulerTop"]:
        moments, axes = self._principal
        return [_EulerTop(moments, axes, omega) for omega in self.batched("omega0")]

    @property
    def period(self) -> np.ndarray | float:
        """Period of omega_body [s], batch_shape: 4 K(m) / |lam| (2 pi / |lam| for a spin about the
        largest or smallest axis, the period of a small wobble), inf on the separatrix and where
        omega_body is constant with no wobble about it (equal moments across the spin)."""
        return self.unflatten(np.array([top.period for top in self._tops]))

    # --- closed form -------------------------------------------------------------------------------

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)
        omega0 = self.batched("omega0")
        omega = np.stack([top.omega_body(t) for top in self._tops], axis=1)
        quaternion = np.stack([top.quaternion(t) for top in self._tops], axis=1)
        tensor = self._tensor()
        momentum = omega0 @ tensor  # L = I w0, the body axes being the world's at t = 0
        energy = 0.5 * np.einsum("ba,ba->b", omega0, momentum)
        shape = (t.size,) + self.batch_shape
        return {"omega_body": omega.reshape(shape + (3,)),
                "L_world": np.broadcast_to(momentum, (t.size,) + momentum.shape).reshape(shape + (3,)).copy(),
                "energy": np.broadcast_to(energy, (t.size,) + energy.shape).reshape(shape).copy(),
                "quaternion": quaternion.reshape(shape + (4,))}

    # --- native model ------------------------------------------------------------------------------

    def native(self) -> NativeModel:
        """The hand kernel (hand_model) when the module's FAST_PATH is True, else the general engine
        (engine_model); the same observables either way."""
        model = self.hand_model() if FAST_PATH else self.engine_model()
        return dataclasses.replace(model, rate=lambda method: rotation_rates(self, method))

    def engine_model(self) -> NativeModel:
        """The body on the general engine: the scene's Layout (a free joint) as a TreeScene. The Layout puts the
        body frame (the Inertia's) at the world origin with the identity orientation, so omega0 is the free
        joint's body-frame angular velocity, and the origin moves with omega0 x (0 - com) (the centre at rest).
        "splitting" and "yoshida6": free_rotation_tree_step, the family's own flows (module docstring)."""
        omega0 = self.batched("omega0")
        com = self.inertia.com
        first = self.item((0,) * len(self.batch_shape))  # the batch shares one body: the first element's Layout
        tree = Scene.from_layout(first._layout(), t_end=self.t_end, name=self.name, gravity=0.0)
        qvel0 = np.concatenate([np.cross(omega0, -com), omega0], axis=1)
        model = dataclasses.replace(tree, qvel0=qvel0).native()
        moments, axes = self._principal
        tail = np.concatenate([moments, quat_from_matrix(axes), com])
        params = np.concatenate([model.params, np.broadcast_to(tail, (model.params.shape[0], tail.size))], axis=1)
        tensor = self._tensor()

        def observe(t, y):
            data = model.observe(t, y)
            qpos, qvel = data["qpos"], data["qvel"]  # arrays (the rest is lazy)
            quaternion, omega = qpos[..., 3:7], qvel[..., 3:6]
            momentum = omega @ tensor  # body frame (the tensor is symmetric)
            return {"omega_body": omega, "quaternion": quaternion,
                    "L_world": np.einsum("...ab,...b->...a", quat_to_matrix(quaternion), momentum),
                    "energy": 0.5 * np.sum(omega * momentum, axis=-1)}

        step = free_rotation_tree_step
        return dataclasses.replace(model, params=params, observe=observe,
                                   split={"splitting": (step, np.ones(1)), "yoshida6": (step, integrators.YOSHIDA6)})

    def hand_model(self) -> NativeModel:
        """The hand-written kernel: y (B, 7) = (quaternion of the principal axes, w in them), params (I1, I2, I3)."""
        moments, axes = self._principal
        q_axes = quat_from_matrix(axes)
        omega0 = self.batched("omega0")
        batch = omega0.shape[0]
        y0 = np.concatenate([np.broadcast_to(q_axes, (batch, 4)), omega0 @ axes], axis=1)
        params = np.broadcast_to(moments, (batch, 3)).copy()

        def observe(t, y):
            q, w = y[..., :4], y[..., 4:]
            momentum_principal = w * moments
            return {
                "omega_body": w @ axes.T,
                # the quaternion as integrated (|q| drifts under euler and rk4), of the Inertia's axes
                "quaternion": quat_multiply(q, quat_conjugate(q_axes)),
                "L_world": np.einsum("...ab,...b->...a", quat_to_matrix(q), momentum_principal),
                "energy": 0.5 * np.sum(w * momentum_principal, axis=-1),
            }

        step = free_rotation_step
        return NativeModel(y0=y0, params=params, rhs=free_rotation_rhs, observe=observe,
                           split={"splitting": (step, np.ones(1)), "yoshida6": (step, integrators.YOSHIDA6)})

    def why_not(self, method: str) -> str:
        if method in ("symplectic_euler", "verlet"):
            return (f"{method!r} needs q'' = a(q) from a separable potential, and a free body has none: its "
                    "energy T = sum L_i^2 / (2 I_i) is all kinetic; use 'splitting' (its exact rotations "
                    "about the principal axes) or 'yoshida6' (the 6th-order composition of that splitting)")
        return f"{method!r} is not a free-rotation method"

    # --- what other simulators build ---------------------------------------------------------------

    def _layout(self) -> Layout:
        moments, axes = self._principal
        mass = self.inertia.mass
        # Box of side s_i with these principal moments: I1 = M (s2^2 + s3^2) / 12, ... gives
        # s1^2 = 6 (I2 + I3 - I1) / M, cyclically (s3 = 0 for a lamina, I1 + I2 = I3).
        sides = np.sqrt(np.maximum(6.0 * (moments.sum() - 2.0 * moments) / mass, 0.0))
        sides = np.maximum(sides, MIN_BOX_FRACTION * sides.max())
        shape = Shape("body", "box", tuple((sides / 2).tolist()), pos=tuple(self.inertia.com.tolist()),
                      quat=tuple(quat_from_matrix(axes).tolist()))
        body = Body("body", self.inertia, shapes=(shape,))
        omega = np.asarray(self.omega0, dtype=np.float64)
        # The centre of mass is at rest, so the body-frame origin moves with w x (0 - com).
        velocity = np.cross(omega, -self.inertia.com)
        free = Joint("free", "free", "body", qvel0=(tuple(velocity.tolist()), tuple(omega.tolist())))
        return Layout(bodies=(body,), joints=(free,))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        states: BodyStates = bodies["body"]
        quat = np.asarray(states.quat, dtype=np.float64)
        rotation = quat_to_matrix(quat)
        omega_body = np.einsum("tba,tb->ta", rotation, np.asarray(states.omega, dtype=np.float64))
        momentum_body = omega_body @ self._tensor()
        return {"omega_body": omega_body,
                "L_world": np.einsum("tab,tb->ta", rotation, momentum_body),
                "energy": 0.5 * np.sum(omega_body * momentum_body, axis=-1),
                "quaternion": quat}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """The free joint's (position, quaternion) (T, 7): the body turns by `quaternion` about its centre of
        mass, which stays where it starts (at inertia.com, the body frame starting at the origin)."""
        quat = observed(self, trajectory, "quaternion", (4,))
        com = np.asarray(self.inertia.com, dtype=np.float64)
        origin = com - np.einsum("tab,b->ta", quat_to_matrix(quat), com)
        return {"free": np.concatenate([origin, quat], axis=1)}

    def describe(self) -> str:
        moments = ", ".join(f"{m:.6g}" for m in self._principal[0])
        omega = np.asarray(self.omega0)
        shown = omega.tolist() if omega.ndim == 1 else f"batch {self.batch_shape}"
        return f"{self.name}(I=({moments}) kg m^2, omega0={shown} rad/s)"


def free_rotation(inertia: Inertia, *, omega0, t_end: float) -> FreeRotation:
    """A rigid body turning freely about its resting centre of mass (Euler's equations).

    inertia: the body (every principal moment > 0; the tensor need not be diagonal)
    omega0:  (3,) or a batch (..., 3) initial angular velocity in the Inertia's axes [rad/s]
    t_end:   duration [s]
    The scene has no gravity (unlike every other factory this one takes no `gravity`: uniform gravity
    exerts no torque about the centre of mass, so it could only move the centre, which stays at rest).
    Observables omega_body, L_world, energy, quaternion; `period` is the period of omega_body.
    """
    scene_arguments(0.0, t_end)
    return representable(FreeRotation(name="free_rotation", t_end=t_end, gravity=0.0, inertia=inertia, omega0=omega0))


def _merge_equal(moments: np.ndarray) -> np.ndarray:
    """Ascending moments with those closer than MOMENT_RTOL of the largest made exactly equal."""
    moments = np.array(moments, dtype=np.float64)
    tolerance = MOMENT_RTOL * moments[2]
    low, high = moments[1] - moments[0] <= tolerance, moments[2] - moments[1] <= tolerance
    if low and high:
        moments[:] = moments.mean()
    elif low:
        moments[:2] = moments[:2].mean()
    elif high:
        moments[1:] = moments[1:].mean()
    return moments


# ----- the exact motion of one body ------------------------------------------------------------------

class _EulerTop:
    """Exact free rotation of one body: principal moments ascending (3,), axes P (3,3) (columns, in
    the Inertia's frame), initial angular velocity (3,) in the Inertia's frame."""

    def __init__(self, moments: np.ndarray, axes: np.ndarray, omega0: np.ndarray) -> None:
        self.omega0 = np.array(omega0, dtype=np.float64)
        w = axes.T @ self.omega0  # principal components
        I1, I2, I3 = moments
        d = I3 * w[2] ** 2 * (I3 - I2) - I1 * w[0] ** 2 * (I2 - I1)  # L^2 - 2T I2
        # Frame E: the axis the polhode encircles is E's third axis.
        self.frame = FLIP if d < 0 else np.eye(3)
        self.to_body = axes @ self.frame           # x_body = P F x_E
        self.I = I = moments.copy() if d >= 0 else moments[::-1].copy()
        w = self.frame.T @ w
        I1, I2, I3 = I
        # In frame E both carry the sign of I3 - I1, so every ratio below is >= 0.
        D3 = I1 * w[0] ** 2 * (I3 - I1) + I2 * w[1] ** 2 * (I3 - I2)  # 2T I3 - L^2
        D1 = I2 * w[1] ** 2 * (I2 - I1) + I3 * w[2] ** 2 * (I3 - I1)  # L^2 - 2T I1
        self.L = float(np.sqrt(np.sum((I * w) ** 2)))
        equal = moments[0] == moments[1] or moments[1] == moments[2]
        # omega_body is constant along a principal axis (D3 = 0: L along E's third axis) or in a
        # plane of equal moments, and at rest about the intermediate axis.
        self.constant = D3 == 0.0 or (d == 0.0 and (equal or (w[0] == 0.0 and w[2] == 0.0)))
        if self.constant:
            # about the largest or smallest axis: the period of a small wobble, 2 pi / |lam|
            wobble = D3 == 0.0 and d != 0.0
            self.period = 2.0 * np.pi / np.sqrt((I3 - I2) * D1 / (I1 * I2 * I3)) if wobble else np.inf
            return
        speed = np.sqrt((I3 - I2) * D1 / (I1 * I2 * I3))  # |lam|
        self.m = min(max((I2 - I1) * D3 / ((I3 - I2) * D1), 0.0), 1.0)
        self.m1 = min(max((I3 - I1) * d / ((I3 - I2) * D1), 0.0), 1.0)  # 1 - m, without cancellation
        self.separatrix = self.m1 == 0.0
        if self.separatrix:
            self.m = 1.0
        self.K = float(elliprf(0.0, self.m1, 1.0)) if not self.separatrix else np.inf
        self.period = 4.0 * self.K / speed
        self.A = np.sqrt([D3 / (I1 * (I3 - I1)), D3 / (I2 * (I3 - I2)), D1 / (I3 * (I3 - I1))])
        self.s1 = 1.0 if w[0] >= 0 else -1.0
        self.s3 = 1.0 if w[2] >= 0 else -1.0
        self.n = I3 * (I2 - I1) / (I1 * (I3 - I2))  # >= 0
        cn0, sn0 = w[0] / self.A[0], w[1] / self.A[1]
        if self.separatrix:
            # w1 = s1 A1 sech u: sinh u0 = tanh u0 / sech u0
            self.lam = self.s1 * self.s3 * np.sign(I3 - I2) * speed
            self.u0 = float(np.arcsinh(sn0 / abs(cn0)))
        else:
            self.lam = self.s3 * np.sign(I3 - I2) * speed
            # u0 = F(am u0 | m) from sn and cn themselves (Carlson), exact near am = pi/2 too;
            # F(pi - x) = 2K - F(x) when cn0 < 0.
            f = sn0 * elliprf(cn0 * cn0, cn0 * cn0 + self.m1 * sn0 * sn0, 1.0)
            self.u0 = float(f if cn0 >= 0 else np.copysign(2.0 * self.K, sn0) - f)
        self.pi_complete = (float(elliprf(0.0, self.m1, 1.0) - self.n / 3.0 * elliprj(0.0, self.m1, 1.0, 1.0 + self.n))
                            if not self.separatrix else np.inf)
        # Euler angles at t = 0 fix the world direction of L: S = R_E(0) (Rx(theta0) Rz(psi0))^T, phi(0) = 0.
        theta0, psi0, _ = self._angles(np.array([self.u0]))
        self.q_frame = quat_from_matrix(self.to_body)
        self.q_S = quat_multiply(self.q_frame, quat_conjugate(quat_multiply(_qx(theta0), _qz(psi0))))[0]

    def _phase(self, u: np.ndarray):
        """sn, cn, dn of u (T,), each to a relative accuracy; the angle of (cn, sn), unwrapped; and
        int_0^u dv / (1 + n sn^2 v) = Pi(-n; am u | m)."""
        if self.separatrix:
            decay = np.exp(-2.0 * np.abs(u))
            sn, sech = np.tanh(u), 2.0 * np.sqrt(decay) / (1.0 + decay)  # 1 / cosh u, without overflow
            angle = np.arctan2(sn, sech)
            if self.s1 < 0:
                angle = np.pi - angle
            # with sn = tanh: d/du [u + sqrt(n) atan(sqrt(n) tanh u)] = (1 + n) / (1 + n tanh^2 u)
            root = np.sqrt(self.n)
            integral = (u + root * np.arctan(root * sn)) / (1.0 + self.n)
            return sn, self.s1 * sech, sech, angle, integral
        quarter, m, m1 = self.K, self.m, self.m1
        turns = np.floor((u + quarter) / (2.0 * quarter))  # u = 2 K j + r, r in [-K, K)
        r = u - 2.0 * quarter * turns
        sn, cn, dn, _am = jacobi(r, m, m1)
        far = np.abs(r) > quarter / 2
        if np.any(far):
            # sn(K - w) = cn w / dn w, cn(K - w) = sqrt(m1) sn w / dn w, dn(K - w) = sqrt(m1) / dn w:
            # cn and dn keep their relative accuracy where they are small (near the separatrix).
            snw, cnw, dnw, _ = jacobi(quarter - np.abs(r[far]), m, m1)
            sn[far] = np.sign(r[far]) * cnw / dnw
            cn[far] = np.sqrt(m1) * snw / dnw
            dn[far] = np.sqrt(m1) / dnw
        integral = self._integral(r, sn, cn, dn) + 2.0 * turns * self.pi_complete
        angle = np.arctan2(sn, cn) + turns * np.pi  # cn >= 0 on [-K, K]
        parity = 1.0 - 2.0 * (turns % 2)  # sn(u + 2K) = -sn(u), cn(u + 2K) = -cn(u)
        return parity * sn, parity * cn, dn, angle, integral

    def _integral(self, r: np.ndarray, sn: np.ndarray, cn: np.ndarray, dn: np.ndarray) -> np.ndarray:
        """int_0^r dv / (1 + n sn^2 v) for r in [-K, K], given sn, cn, dn of r.

        Directly, Pi(-n; am r | m) = sn R_F(cn^2, dn^2, 1) - n/3 sn^3 R_J(cn^2, dn^2, 1, 1 + n sn^2)
        (Carlson), whose error is that of am r over dn r. Near r = +-K with m -> 1 (dn r < m1^(1/8)), instead
        Pi(-n | m) - G(K - |r|), where sn(K - w) = cd w gives 1 / (1 + n cd^2) = (1 - m sn^2) / ((1 + n)(1 - N sn^2)),
        N = (m + n) / (1 + n), and so G(w) = (m w + n m1 Pi(N; am w | m) / (1 + n)) / (m + n): the
        ill-conditioned part carries the factor m1.
        """
        m, m1, n = self.m, self.m1, self.n
        reflect = dn < m1**0.125 if m1 < 0.5 else np.zeros(r.shape, dtype=bool)
        direct = ~reflect
        out = np.empty_like(r)
        s, c = sn[direct], cn[direct]
        out[direct] = (s * elliprf(c * c, dn[direct] ** 2, 1.0)
                       - n / 3.0 * s**3 * elliprj(c * c, dn[direct] ** 2, 1.0, 1.0 + n * s * s))
        if np.any(reflect):
            w = self.K - np.abs(r[reflect])
            s, c, d, _am = jacobi(w, m, m1)
            N = (m + n) / (1.0 + n)
            pi_n = (s * elliprf(c * c, d * d, 1.0)
                    + N / 3.0 * s**3 * elliprj(c * c, d * d, 1.0, c * c + m1 / (1.0 + n) * s * s))
            g = (m * w + n * m1 * pi_n / (1.0 + n)) / (m + n)
            out[reflect] = np.sign(r[reflect]) * (self.pi_complete - g)
        return out

    def _omega_e(self, sn, cn, dn) -> np.ndarray:
        return np.stack([self.A[0] * cn, self.A[1] * sn, self.s3 * self.A[2] * dn], axis=-1)

    def _angles(self, u: np.ndarray):
        """Euler angles theta, psi (T,) of L in frame E, and Pi(-n; am u | m)."""
        sn, cn, dn, angle, integral = self._phase(u)
        I1, I2, I3 = self.I
        a, b = I1 * self.A[0], I2 * self.A[1]
        # L_E / |L| = (sin theta sin psi, sin theta cos psi, cos theta)
        theta = np.arctan2(np.hypot(a * cn, b * sn), I3 * self.s3 * self.A[2] * dn)
        # psi = atan2(a cn, b sn) = pi/2 - chi, with chi = atan2(b sn, a cn) unwrapped along the angle
        chi = angle + np.arctan2((b - a) * sn * cn, a * cn * cn + b * sn * sn)
        return theta, 0.5 * np.pi - chi, integral

    def omega_body(self, t: np.ndarray) -> np.ndarray:
        """(T, 3) angular velocity in the Inertia's axes [rad/s]."""
        if self.constant:
            return np.broadcast_to(self.omega0, (t.size, 3)).copy()
        sn, cn, dn, _angle, _integral = self._phase(self.u0 + self.lam * t)
        return self._omega_e(sn, cn, dn) @ self.to_body.T

    def quaternion(self, t: np.ndarray) -> np.ndarray:
        """(T, 4) orientation of the Inertia's axes, body to world (w, x, y, z); identity at t = 0."""
        if self.constant:
            return quat_exp(np.outer(t, self.omega0))
        I1, _I2, I3 = self.I
        theta, psi, integral = self._angles(self.u0 + self.lam * t)
        _theta0, _psi0, integral0 = self._angles(np.array([self.u0]))
        # phi' = |L|/I3 + |L| (I3 - I1) / (I1 I3 (1 + n sn^2 u)), du = lam dt
        if self.n == 0.0:
            # I1 = I2 in frame E (a symmetric top): 1 + n sn^2 = 1, so phi' = |L| / I1, the uniform precession,
            # exactly; the general form would divide the difference of two integrals of size u0 by lam, which
            # loses all accuracy when w3 and so lam are tiny (a spin across the symmetry axis)
            phi = self.L * t / I1
        else:
            phi = self.L * t / I3 + self.L * (I3 - I1) / (I1 * I3 * self.lam) * (integral - integral0)
        q = quat_multiply(quat_multiply(quat_multiply(self.q_S, _qz(phi)), _qx(theta)), _qz(psi))
        return quat_multiply(q, quat_conjugate(self.q_frame))


def _qz(angle: np.ndarray) -> np.ndarray:
    angle = np.asarray(angle, dtype=np.float64)
    zero = np.zeros_like(angle)
    return np.stack([np.cos(angle / 2), zero, zero, np.sin(angle / 2)], axis=-1)


def _qx(angle: np.ndarray) -> np.ndarray:
    angle = np.asarray(angle, dtype=np.float64)
    zero = np.zeros_like(angle)
    return np.stack([np.cos(angle / 2), np.sin(angle / 2), zero, zero], axis=-1)


# ----- the stability rate (rbody.engine.stability reads it through NativeModel.rate) -----------------------------

ROTATION_SAMPLES = 65  # samples of the exact motion over one period (or the run) for the fastest rate


def rotation_rates(scene, method: str | None = None) -> np.ndarray:
    """(B,) the fastest rate of a free rotation (rbody.scenes.FreeRotation) along one period of its exact motion:
    |omega|/2 and the eigenvalues of Euler's equations linearised; for "splitting" also |omega_perp| sqrt(I3/I1),
    for "yoshida6" a quarter of that.

    omega_perp is the part of omega across the axis of the smallest moment: the rate at which the exact
    sub-rotations about the other axes move angular momentum onto that axis, where omega_1 = L_1 / I1. The
    splitting's error grows as (dt |omega_perp| sqrt(I3/I1))^2 (measured on tumbling needles: 0.0165 (I3/I1)
    (dt |omega|)^2 over 2 s, for I3/I1 from 17 to 1.7e7), so a needle's splitting needs far smaller steps than
    its dynamics. yoshida6 (6th order) gets a quarter of that rate: measured on the same needles its error is
    ~1.4e-11 (dt |omega_perp| sqrt(I3/I1))^6 (6.6e-8 at 4.1, 6 % at 41)."""
    split = {"splitting": 1.0, "yoshida6": 0.25}.get(method, 0.0)
    moments = scene.principal_moments
    _moments, axes = scene.inertia.principal()
    omega = np.empty((len(scene._tops), ROTATION_SAMPLES, 3))
    for b, top in enumerate(scene._tops):  # the batch shares one body: each element its own exact motion
        span = scene.t_end if not np.isfinite(top.period) else min(top.period, scene.t_end)
        omega[b] = top.omega_body(np.linspace(0.0, span, ROTATION_SAMPLES)) @ axes  # principal components
    # Euler's equations linearised about omega: d(delta w)/dt = I^-1 ([L]x - [w]x I) delta w, L = I w
    jacobians = (_cross_matrices(moments * omega) - _cross_matrices(omega) * moments) / moments[:, None]
    rates = np.maximum(0.5 * np.linalg.norm(omega, axis=-1), np.max(np.abs(np.linalg.eigvals(jacobians)), axis=-1))
    if split:  # the rotations about axes 2 and 3 move L onto axis 1, where omega_1 = L_1 / I1
        rates = np.maximum(rates, split * np.hypot(omega[..., 1], omega[..., 2]) * math.sqrt(moments[2] / moments[0]))
    return np.max(rates, axis=-1)


def _cross_matrices(v: np.ndarray) -> np.ndarray:
    """[v]x (..., 3, 3) of vectors v (..., 3): [v]x u = v x u."""
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out
