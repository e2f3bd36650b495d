"""Rigid motion: r' = R' + w x (r - R), and unit quaternions (w, x, y, z), scalar first.

The chapter shows that every point of a rigid body moves with r' = R' + w x (r - R) for any
reference point R fixed in the body, and that w is the same whichever reference point is chosen.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np

from rbody.checks import finite_array


def _vectors(value, name: str, size: int) -> np.ndarray:
    """(..., size) float64 array, finite, last axis of length `size`."""
    array = finite_array(value, name)
    if array.ndim == 0 or array.shape[-1] != size:
        raise ValueError(f"{name} has shape {array.shape}: expected (..., {size})")
    return array


def point_velocity(r: np.ndarray, R: np.ndarray, V: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """(..., 3) velocity [m/s] of the body point r [m], given reference point R [m] moving at V [m/s]
    and angular velocity omega [rad/s] (world frame); broadcasts over leading axes."""
    r, R, V, omega = (_vectors(a, name, 3) for a, name in ((r, "r"), (R, "R"), (V, "V"), (omega, "omega")))
    try:
        return V + np.cross(omega, r - R)
    except ValueError as error:
        raise ValueError(f"r {r.shape}, R {R.shape}, V {V.shape}, omega {omega.shape}: "
                         f"leading axes do not broadcast ({error})") from None


@dataclass(frozen=True)
class RigidMotion:
    """Instantaneous motion of a rigid body: reference point R (3,) [m] with velocity V (3,) [m/s],
    angular velocity omega (3,) [rad/s], all in the world frame."""

    R: np.ndarray
    V: np.ndarray
    omega: np.ndarray

    def __post_init__(self) -> None:
        for name in ("R", "V", "omega"):
            array = finite_array(getattr(self, name), name, shape=(3,))
            array.flags.writeable = False
            object.__setattr__(self, name, array)

    def velocity_at(self, r: np.ndarray) -> np.ndarray:
        """(..., 3) velocity of the body point(s) r [m/s]."""
        return point_velocity(r, self.R, self.V, self.omega)

    def about(self, Q: Iterable[float]) -> "RigidMotion":
        """The same motion described from reference point Q: same omega, V_Q = V + w x (Q - R)."""
        Q = finite_array(Q, "Q", shape=(3,))
        return RigidMotion(Q, self.velocity_at(Q), self.omega)

    def instantaneous_axis(self) -> tuple[np.ndarray, np.ndarray]:
        """Point (3,) [m] on the instantaneous screw axis nearest R, and its unit direction (3,).

        The points on the axis move only along it (for rolling without slipping they are at rest:
        the axis passes through the contact point). Raises ValueError for a pure translation.
        """
        w2 = float(self.omega @ self.omega)
        if w2 == 0.0:
            raise ValueError("omega=[0, 0, 0]: a pure translation has no rotation axis")
        point = self.R + np.cross(self.omega, self.V) / w2
        return point, self.omega / np.sqrt(w2)


# ----- quaternions (w, x, y, z) ------------------------------------------------------------------

def quat_normalize(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternion; raises ValueError for a zero or non-finite quaternion."""
    q = _vectors(q, "quaternion", 4)
    # Scaled by the largest component before squaring: no overflow (1e200) or underflow (1e-200).
    largest = np.max(np.abs(q), axis=-1, keepdims=True)
    zero = largest == 0
    if np.any(zero):
        rows = np.argwhere(zero[..., 0])
        where = f"row {tuple(int(i) for i in rows[0])}" if q.ndim > 1 else "it"
        raise ValueError(f"quaternion of shape {q.shape}: {len(rows)} of {q.size // 4} are zero (first: {where}); "
                         "a rotation needs a non-zero quaternion (w, x, y, z)")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.all(np.isfinite(norm)) and np.all(norm > 0):
        return q / norm
    scaled = q / largest  # |q|^2 overflowed or underflowed: the same direction from the scaled quaternion
    return scaled / np.linalg.norm(scaled, axis=-1, keepdims=True)


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(..., 4) Hamilton product p q (apply q, then p)."""
    p, q = _vectors(p, "p", 4), _vectors(q, "q", 4)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """(..., 4) conjugate, the inverse rotation of a unit quaternion."""
    q = _vectors(q, "q", 4)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_axis_angle(axis: Iterable[float], angle: float | np.ndarray) -> np.ndarray:
    """(..., 4) rotation by `angle` [rad] about `axis` (3,), right-handed."""
    axis = finite_array(axis, "axis", shape=(3,))
    norm = np.linalg.norm(axis)
    if norm == 0:
        raise ValueError("axis=[0, 0, 0]: a rotation axis must be non-zero")
    half = 0.5 * finite_array(angle, "angle")[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis / norm], axis=-1)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrix of the unit quaternion q (..., 4)."""
    w, x, y, z = np.moveaxis(quat_normalize(q), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def quat_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion with w >= 0 of a proper rotation matrix (3, 3) (Shepperd's method)."""
    m = finite_array(matrix, "matrix", shape=(3, 3))
    if not np.allclose(m @ m.T, np.eye(3), atol=1e-10) or np.linalg.det(m) < 0:
        raise ValueError(f"matrix={m.tolist()}: expected a proper rotation (R R^T = 1, det R = +1)")
    trace = np.trace(m)
    candidates = [trace, m[0, 0], m[1, 1], m[2, 2]]
    k = int(np.argmax(candidates))
    if k == 0:
        s = 2.0 * np.sqrt(1.0 + trace)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif k == 1:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif k == 2:
        s = 2.0 * np.sqrt(1.0 - m[0, 0] + m[1, 1] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 - m[0, 0] - m[1, 1] + m[2, 2])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return quat_normalize(q if q[0] >= 0 else -q)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., 3) vector v rotated by the unit quaternion q: v' = q v q*."""
    return np.einsum("...ab,...b->...a", quat_to_matrix(q), _vectors(v, "v", 3))


def quat_exp(rotation_vector: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternion of the rotation vector phi (..., 3) [rad]: exp(phi/2), exact for any |phi|."""
    phi = _vectors(rotation_vector, "rotation_vector", 3)
    angle = np.linalg.norm(phi, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(|phi|/2)/|phi| written with sinc so that it stays exact as |phi| -> 0.
    scale = 0.5 * np.sinc(half / np.pi)
    return np.concatenate([np.cos(half), scale * phi], axis=-1)


def quat_integrate_body(q: np.ndarray, omega_body: np.ndarray, dt: float) -> np.ndarray:
    """(..., 4) orientation after turning at the constant body rate omega_body (..., 3) [rad/s] for dt [s]:
    q(t + dt) = q(t) exp(omega_body dt / 2), the exact exponential map."""
    dt = finite_array(dt, "dt")
    return quat_multiply(q, quat_exp(_vectors(omega_body, "omega_body", 3) * dt[..., None]))
