"""Spatial algebra in Featherstone's notation, as small compiled functions on float64 arrays.

A motion vector m = (omega; v_O) (angular velocity; velocity of the body point at the origin O of the
frame it is written in), a force vector f = (n_O; f) (moment about O; force). Both (6,).

    motion cross   m x m2  = (w x w2;  w x v2 + v x w2)
    force cross    m x* f  = (w x n + v x f;  w x f)
    power          m . f   = w . n + v . f

A rigid body's spatial inertia about O is held as (mass, h, Ibar): h = mass c (first moment, c the
centre of mass [m]), Ibar = Ic + mass (|c|^2 1 - c c^T) its rotational inertia about O; as a matrix

    I = [[Ibar, [h]x], [[h]x^T, mass 1]],   I m = (Ibar w + h x v;  mass v - h x w)

and composite inertias add component by component. A Plucker transform from frame A to frame B is
held as (E, r): E (3, 3) the rotation taking A's coordinates to B's, r (3,) B's origin in A's
coordinates: X m = (E w; E (v - r x w)), X* f = (E (n - r x f); E f), never as a 6 x 6 matrix. Quaternions are (w, x, y, z).

Every function writes into `out` (no allocation) and is inlined where it is called.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_JIT = dict(cache=True, inline="always")


# ----- 3-vectors and quaternions ------------------------------------------------------------------

@njit(**_JIT)
def cross3(a, b, out):
    """out = a x b (out must not alias a or b)."""
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(**_JIT)
def quat_multiply(a, b, out):
    """out = a (x) b, the rotation b followed by a (out must not alias a or b)."""
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]


@njit(**_JIT)
def quat_to_matrix(q, R):
    """R (3, 3) of the unit quaternion q (4,)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = 1 - 2 * (x * x + y * y)


@njit(**_JIT)
def matrix_vector(R, v, out):
    """out = R v for R (3, 3)."""
    for a in range(3):
        out[a] = R[a, 0] * v[0] + R[a, 1] * v[1] + R[a, 2] * v[2]


@njit(**_JIT)
def quat_rotate(q, v, out):
    """out = R(q) v: v' = v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)."""
    ux, uy, uz, w = q[1], q[2], q[3], q[0]
    tx = 2.0 * (uy * v[2] - uz * v[1])
    ty = 2.0 * (uz * v[0] - ux * v[2])
    tz = 2.0 * (ux * v[1] - uy * v[0])
    out[0] = v[0] + w * tx + uy * tz - uz * ty
    out[1] = v[1] + w * ty + uz * tx - ux * tz
    out[2] = v[2] + w * tz + ux * ty - uy * tx


@njit(**_JIT)
def quat_axis_angle(axis, angle, out):
    """out = (cos(angle/2), sin(angle/2) axis) for a unit axis (3,)."""
    s = np.sin(0.5 * angle)
    out[0] = np.cos(0.5 * angle)
    out[1] = s * axis[0]
    out[2] = s * axis[1]
    out[3] = s * axis[2]


@njit(**_JIT)
def quat_exp(phi, out):
    """out = exp(phi): the unit quaternion of the rotation vector phi (3,) [rad] (unit by construction:
    cos^2 + sin^2 of one angle, with sin(t/2)/t from its series near 0)."""
    angle = np.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    if angle < 1e-4:
        scale = 0.5 - angle * angle / 48.0  # sin(t/2)/t
    else:
        scale = np.sin(0.5 * angle) / angle
    out[0] = np.cos(0.5 * angle)
    out[1] = scale * phi[0]
    out[2] = scale * phi[1]
    out[3] = scale * phi[2]


@njit(**_JIT)
def dexp_inverse3(p0, p1, p2, w0, w1, w2):
    """phi' such that R exp(phi) turns at body angular velocity omega = (w0, w1, w2): the inverse of the
    right Jacobian of SO(3), phi' = omega + 1/2 phi x omega + c phi x (phi x omega),
    c = 1/t^2 - (1 + cos t) / (2 t sin t) (t = |phi|; series 1/12 + t^2/720 near 0); phi = (p0, p1, p2)."""
    t2 = p0 * p0 + p1 * p1 + p2 * p2
    if t2 < 1e-6:
        c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    else:
        t = np.sqrt(t2)
        c = 1.0 / t2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t))
    ax = p1 * w2 - p2 * w1
    ay = p2 * w0 - p0 * w2
    az = p0 * w1 - p1 * w0
    bx = p1 * az - p2 * ay
    by = p2 * ax - p0 * az
    bz = p0 * ay - p1 * ax
    return w0 + 0.5 * ax + c * bx, w1 + 0.5 * ay + c * by, w2 + 0.5 * az + c * bz


@njit(**_JIT)
def dexp_inverse(phi, omega, out):
    """out (3,) = dexp_inverse3 of phi (3,) and omega (3,) (out must not alias them)."""
    out[0], out[1], out[2] = dexp_inverse3(phi[0], phi[1], phi[2], omega[0], omega[1], omega[2])


# sin and cos by polynomial (the kernels of fdlibm, as in musl's __sin and __cos): branch-free arithmetic that
# LLVM vectorises across a loop, within 1 ulp of the correctly rounded value for |x| < 1e2 and 2 ulp below
# REDUCED_RANGE (|x| is cut to [-pi/4, pi/4] less a multiple k of pi/2 in three exact pieces of pi/2).
REDUCED_RANGE = 1e5
_ROUND = 6755399441055744.0  # 1.5 * 2^52: (x + _ROUND) - _ROUND rounds x to the nearest integer (|x| < 2^51)
_TWO_OVER_PI = 0.63661977236758134308
_PIO2_1 = 1.57079632673412561417e+00  # the first 33 bits of pi/2: k * _PIO2_1 is exact for |k| < 2^20
_PIO2_2 = 6.07710050630396597660e-11  # the next 33
_PIO2_3 = 2.02226624879595063154e-21  # the rest
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@njit(**_JIT)
def sin_cos(x):
    """(sin x, cos x) for |x| < REDUCED_RANGE (beyond: use np.sin, np.cos), by polynomial."""
    k = (x * _TWO_OVER_PI + _ROUND) - _ROUND
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    z = r * r
    sine = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    hz = 0.5 * z
    one = 1.0 - hz
    cosine = one + (((1.0 - one) - hz) + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))))
    n = int(k)
    odd = (n & 1) != 0
    sign = float(1 - (n & 2))
    return sign * (cosine if odd else sine), sign * (-sine if odd else cosine)


# ----- spatial vectors -------------------------------------------------------------------------------

@njit(**_JIT)
def motion_cross(m, n, scale, out):
    """out += scale (m x n) for motion vectors m, n (6,)."""
    out[0] += scale * (m[1] * n[2] - m[2] * n[1])
    out[1] += scale * (m[2] * n[0] - m[0] * n[2])
    out[2] += scale * (m[0] * n[1] - m[1] * n[0])
    out[3] += scale * (m[1] * n[5] - m[2] * n[4] + m[4] * n[2] - m[5] * n[1])
    out[4] += scale * (m[2] * n[3] - m[0] * n[5] + m[5] * n[0] - m[3] * n[2])
    out[5] += scale * (m[0] * n[4] - m[1] * n[3] + m[3] * n[1] - m[4] * n[0])


@njit(**_JIT)
def force_cross(m, f, out):
    """out += m x* f for a motion vector m and a force vector f (6,)."""
    out[0] += m[1] * f[2] - m[2] * f[1] + m[4] * f[5] - m[5] * f[4]
    out[1] += m[2] * f[0] - m[0] * f[2] + m[5] * f[3] - m[3] * f[5]
    out[2] += m[0] * f[1] - m[1] * f[0] + m[3] * f[4] - m[4] * f[3]
    out[3] += m[1] * f[5] - m[2] * f[4]
    out[4] += m[2] * f[3] - m[0] * f[5]
    out[5] += m[0] * f[4] - m[1] * f[3]


@njit(**_JIT)
def dot6(a, b):
    """a . b for (6,) vectors (a motion and a force: power)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]


@njit(**_JIT)
def inertia_apply(mass, h, Ibar, m, out):
    """out = I m, I = (mass, h (3,), Ibar (3, 3)) about the origin (module docstring)."""
    w0, w1, w2, v0, v1, v2 = m[0], m[1], m[2], m[3], m[4], m[5]
    out[0] = Ibar[0, 0] * w0 + Ibar[0, 1] * w1 + Ibar[0, 2] * w2 + h[1] * v2 - h[2] * v1
    out[1] = Ibar[1, 0] * w0 + Ibar[1, 1] * w1 + Ibar[1, 2] * w2 + h[2] * v0 - h[0] * v2
    out[2] = Ibar[2, 0] * w0 + Ibar[2, 1] * w1 + Ibar[2, 2] * w2 + h[0] * v1 - h[1] * v0
    out[3] = mass * v0 - (h[1] * w2 - h[2] * w1)
    out[4] = mass * v1 - (h[2] * w0 - h[0] * w2)
    out[5] = mass * v2 - (h[0] * w1 - h[1] * w0)


@njit(**_JIT)
def inertia_matrix(mass, h, Ibar, out):
    """out (6, 6) = the matrix of I = (mass, h, Ibar): [[Ibar, [h]x], [[h]x^T, mass 1]]."""
    for a in range(3):
        for b in range(3):
            out[a, b] = Ibar[a, b]
            out[3 + a, 3 + b] = 0.0
        out[3 + a, 3 + a] = mass
    out[0, 3], out[0, 4], out[0, 5] = 0.0, -h[2], h[1]
    out[1, 3], out[1, 4], out[1, 5] = h[2], 0.0, -h[0]
    out[2, 3], out[2, 4], out[2, 5] = -h[1], h[0], 0.0
    for a in range(3):
        for b in range(3):
            out[3 + b, a] = out[a, 3 + b]


@njit(**_JIT)
def symmetric_apply(M, x, out):
    """out = M x for a symmetric (6, 6) M of which only the upper triangle (column >= row) is read."""
    for a in range(6):
        acc = M[a, a] * x[a]
        for c in range(a):
            acc += M[c, a] * x[c]
        for c in range(a + 1, 6):
            acc += M[a, c] * x[c]
        out[a] = acc


@njit(**_JIT)
def inertia_in_world(mass, com, Ic, R, origin, h, Ibar):
    """A body's inertia about the world origin, world axes: mass [kg], com (3,) its centre of mass in the
    body frame, Ic (3, 3) its tensor about the com in body axes, R (3, 3) and origin (3,) the body frame's
    orientation and origin (world). Writes h = mass c and Ibar = R Ic R^T + mass (|c|^2 1 - c c^T)."""
    c0 = R[0, 0] * com[0] + R[0, 1] * com[1] + R[0, 2] * com[2] + origin[0]
    c1 = R[1, 0] * com[0] + R[1, 1] * com[1] + R[1, 2] * com[2] + origin[1]
    c2 = R[2, 0] * com[0] + R[2, 1] * com[1] + R[2, 2] * com[2] + origin[2]
    h[0], h[1], h[2] = mass * c0, mass * c1, mass * c2
    c2sum = c0 * c0 + c1 * c1 + c2 * c2
    for a in range(3):
        ca = c0 if a == 0 else (c1 if a == 1 else c2)
        for b in range(a, 3):
            cb = c0 if b == 0 else (c1 if b == 1 else c2)
            acc = 0.0
            for k in range(3):
                acc += R[a, k] * (Ic[k, 0] * R[b, 0] + Ic[k, 1] * R[b, 1] + Ic[k, 2] * R[b, 2])
            Ibar[a, b] = acc - mass * ca * cb
            Ibar[b, a] = Ibar[a, b]
        Ibar[a, a] += mass * c2sum


@njit(**_JIT)
def transform_motion(E, r, m, out):
    """out = X m for the Plucker transform X = (E, r) (module docstring): (E w; E (v - r x w))."""
    d0 = m[3] - (r[1] * m[2] - r[2] * m[1])
    d1 = m[4] - (r[2] * m[0] - r[0] * m[2])
    d2 = m[5] - (r[0] * m[1] - r[1] * m[0])
    for a in range(3):
        out[a] = E[a, 0] * m[0] + E[a, 1] * m[1] + E[a, 2] * m[2]
        out[3 + a] = E[a, 0] * d0 + E[a, 1] * d1 + E[a, 2] * d2


@njit(**_JIT)
def transform_force(E, r, f, out):
    """out = X* f for X = (E, r): (E (n - r x f); E f)."""
    d0 = f[0] - (r[1] * f[5] - r[2] * f[4])
    d1 = f[1] - (r[2] * f[3] - r[0] * f[5])
    d2 = f[2] - (r[0] * f[4] - r[1] * f[3])
    for a in range(3):
        out[a] = E[a, 0] * d0 + E[a, 1] * d1 + E[a, 2] * d2
        out[3 + a] = E[a, 0] * f[3] + E[a, 1] * f[4] + E[a, 2] * f[5]
