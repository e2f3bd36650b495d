"""Quaternions and frames as MuJoCo's compiler forms them (src/user/user_util.cc, user_objects.cc:
mjuu_normvec, mjuu_quat2mat, mjuu_mulquat, mjuu_z2quat, mjuu_frame2quat), so that every frame rbody reads from
MJCF is the one MuJoCo compiles, to the last bit where the operations are the same."""

from __future__ import annotations

import math

import numpy as np

MJ_EPS = 1e-14      # mjEPS: MuJoCo's smallest meaningful norm, mass or volume here


def quat_matrix(quat) -> np.ndarray:
    """(3,3) rotation of a unit quaternion (w, x, y, z), as MuJoCo's mjuu_quat2mat."""
    w, x, y, z = (float(v) for v in quat)
    return np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ])


def unit(vector: np.ndarray) -> np.ndarray:
    """MuJoCo's mjuu_normvec: unchanged when the norm is within 1e-14 of 1."""
    norm = math.sqrt(float(sum(v * v for v in vector)))
    if norm * norm < MJ_EPS:
        return vector
    return vector / norm if abs(norm - 1) > MJ_EPS else vector


def quat_product(p, q) -> np.ndarray:
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def normalize(vector: np.ndarray) -> tuple[np.ndarray, float]:
    """MuJoCo's mjuu_normvec: no division when the norm is within 1e-14 of 1; norm 0 below 1e-14."""
    squared = float(sum(v * v for v in vector))
    if squared < MJ_EPS:
        return vector, 0.0
    norm = math.sqrt(squared)
    return (vector / norm if abs(norm - 1) > MJ_EPS else vector), norm


def z_to_quat(vector: np.ndarray) -> np.ndarray:
    """The rotation taking z to `vector` (MuJoCo's mjuu_z2quat)."""
    axis, s = normalize(np.cross([0.0, 0.0, 1.0], vector))
    if s < 1e-10:
        axis = np.array([1.0, 0.0, 0.0])
    angle = math.atan2(s, vector[2])
    return np.concatenate([[math.cos(angle / 2)], axis * math.sin(angle / 2)])


def frame_to_quat(x, y, z) -> np.ndarray:
    """Quaternion of the rotation whose columns are x, y, z (MuJoCo's mjuu_frame2quat)."""
    m = (x, y, z)  # m[c][r]
    if m[0][0] + m[1][1] + m[2][2] > 0:
        w = 0.5 * math.sqrt(1 + m[0][0] + m[1][1] + m[2][2])
        q = [w, 0.25 * (m[1][2] - m[2][1]) / w, 0.25 * (m[2][0] - m[0][2]) / w, 0.25 * (m[0][1] - m[1][0]) / w]
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        a = 0.5 * math.sqrt(1 + m[0][0] - m[1][1] - m[2][2])
        q = [0.25 * (m[1][2] - m[2][1]) / a, a, 0.25 * (m[1][0] + m[0][1]) / a, 0.25 * (m[2][0] + m[0][2]) / a]
    elif m[1][1] > m[2][2]:
        b = 0.5 * math.sqrt(1 - m[0][0] + m[1][1] - m[2][2])
        q = [0.25 * (m[2][0] - m[0][2]) / b, 0.25 * (m[1][0] + m[0][1]) / b, b, 0.25 * (m[2][1] + m[1][2]) / b]
    else:
        c = 0.5 * math.sqrt(1 - m[0][0] - m[1][1] + m[2][2])
        q = [0.25 * (m[0][1] - m[1][0]) / c, 0.25 * (m[2][0] + m[0][2]) / c, 0.25 * (m[2][1] + m[1][2]) / c, c]
    return normalize(np.array(q))[0]
