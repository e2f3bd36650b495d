"""Ellipsoids in rbody's narrow phase: a point's exact signed distance, the support point, a plane's distance and a
segment's closest point, compiled.

An ellipsoid is given as MuJoCo gives it (mjGEOM_ELLIPSOID, type code 4 in geometry.py): its world centre pc (3,)
[m], its world axes Rc (3, 3) (columns: the ellipsoid's axes) and its semi-axes s (3,) [m] along them, all > 0 (as
MuJoCo requires; a zero semi-axis, a flat disc, is not handled). In the ellipsoid's axes, y = Rc^T (x - pc), its
surface is sum_i (y_i / s_i)^2 = 1.

A point's distance (ellipsoid_distance) follows D. Eberly, "Distance from a Point to an Ellipse, an Ellipsoid, or a
Hyperellipsoid" (Geometric Tools, 2013), exact to round-off, no closed form existing (the nearest point is a root of
a sextic). The nearest surface point x of y satisfies the Lagrange condition y - x = t grad(q)(x) / 2 with
q(x) = sum (x_i / e_i)^2, so x_i = e_i^2 y_i / (t + e_i^2), and t (the signed distance over |x / e^2|, > 0
outside) is a root of

    F(t) = sum_i (e_i y_i / (t + e_i^2))^2 - 1.

By the symmetry of the ellipsoid the point is taken in the first octant (y_i >= 0, the signs restored after) with
the semi-axes sorted, e0 >= e1 >= e2. With every y_i > 0 the nearest point lies in the same octant, so t + e_i^2 > 0
for every i: t lies in (-e2^2, inf), where F falls monotonically from +inf to -1, and its one root there is the
nearest point's, outside (t > 0) and inside (t in (-e2^2, 0)); the sextic's other real roots, the surface's other
points normal to the line from y (of greater distance), lie below -e2^2. Eberly's scaled form (s = t / e2^2,
r_i = (e_i / e2)^2, z_i = y_i / e_i) is bisected here in u = s + 1 = (t + e2^2) / e2^2 rather than in s: the
denominators s + r_i = u + (r_i - 1) are then sums of non-negatives (r_i - 1 = (e_i - e2)(e_i + e2) / e2^2 to its
relative round-off), and u is found to its own last bit, where Eberly's s resolves t + e2^2 only to ulp(e2^2):
an interior point near the plane of the smallest axis has u small, and its nearest point x2 = y2 / u lost up to 38
ulp of the scale that way. The bracket is [z2, 1] inside (F(1) = q(y) - 1 < 0), [z2, |(r0 z0, r1 z1, z2)|] outside.

A point on a plane of symmetry (y_i = 0, or y_i < ON_PLANE e_i: moving it onto the plane changes the distance by
less than 2^-64 e_i, and keeps u, which is >= z_i, a normal float, its bisection short) may have its nearest point
off that plane (x_i != 0 where t = -e_i^2). Eberly's cases: a point on the plane of the two largest axes, near the
centre, has it at x2 = e2 sqrt(1 - (e0 y0 / (e0^2 - e2^2))^2 - (e1 y1 / (e1^2 - e2^2))^2) off the plane, in closed
form, and its ellipse's analogue; otherwise the problem is that of the ellipse in the plane. A point on an axis:
the ellipse's or the pole's closed form; a sphere (all semi-axes equal): |y| - e. The outward normal at x is
x_i / e_i^2 normalised, accurate to its components' relative round-off (not (y - x) / |y - x|, which cancels near
the surface); the signed distance is -|y - x| inside (q(y) < 1).

The support point along d (ellipsoid_support, closed form): the ellipsoid is the image of the unit sphere under
x = pc + R S w (S = diag(s)), so max over x of d.x is d.pc + |S R^T d|, at x = pc + R S^2 R^T d / |S R^T d|. A
plane's distance (plane_ellipsoid) is that of the support point along -n: n.(pc - pp) - |S R^T n|.

A segment's closest point (segment_ellipsoid_closest): the signed distance of a convex set is convex, so its slope
along a segment, grad.u at the segment's point, is nondecreasing, and the ends of the interval where it is within
SLOPE_TOLERANCE of 0 are found by bisection on its sign to the last bit of the parameter, as
geometry.segment_cylinder_closest does for a cylinder.
"""

from __future__ import annotations

import numpy as np
from numba import njit

SLOPE_TOLERANCE = 1e-12  # the rate of distance along a segment [m/m] below which it runs parallel to the surface
ON_PLANE = 2.0 ** -64  # y_i / e_i below this: the point is on that plane of symmetry (moving it there changes the
# distance by less than 2^-64 e_i, and keeps the root u >= z_i a normal float, resolved to its last bit)
ROOT_ITERATIONS = 1200  # bisection steps at most (a guard: they end at the last bit first): a bracket [z, 1] inside
# takes at most 64 + 53 halvings (u >= 2^-64), outside [z, |y| / e2] about log2(|y| / e2) + 53


@njit(cache=True, inline="always")
def _length2(a, b):
    """|(a, b)| without overflow or underflow (scaled by the larger magnitude)."""
    m = max(abs(a), abs(b))
    if m == 0.0:
        return 0.0
    a, b = a / m, b / m
    return m * np.sqrt(a * a + b * b)


@njit(cache=True, inline="always")
def _length3(a, b, c):
    """|(a, b, c)| without overflow or underflow (scaled by the largest magnitude)."""
    m = max(abs(a), abs(b), abs(c))
    if m == 0.0:
        return 0.0
    a, b, c = a / m, b / m, c / m
    return m * np.sqrt(a * a + b * b + c * c)


@njit(cache=True)
def _root2(r0, a0, z0, z1, g):
    """Eberly's GetRoot for an ellipse, shifted: the root u = s + 1 of (r0 z0 / (u + a0))^2 + (z1 / u)^2 - 1
    (s = t / e1^2, r0 = (e0 / e1)^2 >= 1, a0 = r0 - 1, z_i = y_i / e_i > 0, g = z0^2 + z1^2 - 1 its value at
    u = 1), by bisection to the last bit of u on [z1, 1] inside (g < 0), [z1, |(r0 z0, z1)|] outside; F falls
    monotonically there."""
    n0 = r0 * z0
    u0 = z1
    u1 = 1.0 if g < 0.0 else _length2(n0, z1)
    u = 1.0
    for _ in range(ROOT_ITERATIONS):
        u = 0.5 * (u0 + u1)
        if u == u0 or u == u1:
            break
        q0, q1 = n0 / (u + a0), z1 / u
        f = q0 * q0 + q1 * q1 - 1.0
        if f > 0.0:
            u0 = u
        elif f < 0.0:
            u1 = u
        else:
            break
    return u


@njit(cache=True)
def _root3(r0, r1, a0, a1, z0, z1, z2, g):
    """Eberly's GetRoot for an ellipsoid, shifted: the root u = s + 1 of (r0 z0 / (u + a0))^2 + (r1 z1 / (u + a1))^2
    + (z2 / u)^2 - 1 (s = t / e2^2, r_i = (e_i / e2)^2, a_i = r_i - 1 >= 0, z_i = y_i / e_i > 0, g its value at
    u = 1), by bisection to the last bit of u on [z2, 1] inside (g < 0), [z2, |(r0 z0, r1 z1, z2)|] outside; F
    falls monotonically there."""
    n0, n1 = r0 * z0, r1 * z1
    u0 = z2
    u1 = 1.0 if g < 0.0 else _length3(n0, n1, z2)
    u = 1.0
    for _ in range(ROOT_ITERATIONS):
        u = 0.5 * (u0 + u1)
        if u == u0 or u == u1:
            break
        q0, q1, q2 = n0 / (u + a0), n1 / (u + a1), z2 / u
        f = q0 * q0 + q1 * q1 + q2 * q2 - 1.0
        if f > 0.0:
            u0 = u
        elif f < 0.0:
            u1 = u
        else:
            break
    return u


@njit(cache=True, inline="always")
def _ellipse_nearest(e0, e1, y0, y1):
    """(x0, x1): the point of the ellipse (x0 / e0)^2 + (x1 / e1)^2 = 1 nearest to (y0, y1), for e0 >= e1 > 0 and
    y0, y1 >= 0 (Eberly's DistancePointEllipse)."""
    if y0 < ON_PLANE * e0:  # on an axis to below round-off: on it (module docstring)
        y0 = 0.0
    if y1 < ON_PLANE * e1:
        y1 = 0.0
    if y1 > 0.0:
        if y0 > 0.0:
            z0, z1 = y0 / e0, y1 / e1
            g = z0 * z0 + z1 * z1 - 1.0
            if g == 0.0:
                return y0, y1
            r0 = (e0 / e1) * (e0 / e1)
            a0 = (e0 - e1) * (e0 + e1) / (e1 * e1)  # r0 - 1, to its relative round-off
            u = _root2(r0, a0, z0, z1, g)
            return r0 * y0 / (u + a0), y1 / u  # x_i = e_i^2 y_i / (t + e_i^2)
        return 0.0, e1  # on the minor axis: its pole
    denom0 = (e0 - e1) * (e0 + e1)  # on the major axis (y1 = 0): off it where t = -e1^2 gives |x0| <= e0
    numer0 = e0 * y0
    if numer0 < denom0:
        xde0 = numer0 / denom0  # x0 / e0 at t = -e1^2
        return e0 * xde0, e1 * np.sqrt(1.0 - xde0 * xde0)
    return e0, 0.0


@njit(cache=True, inline="always")
def _ellipsoid_nearest(e0, e1, e2, y0, y1, y2):
    """(x0, x1, x2): the point of the ellipsoid sum (x_i / e_i)^2 = 1 nearest to (y0, y1, y2), for
    e0 >= e1 >= e2 > 0 and y_i >= 0 (Eberly's DistancePointEllipsoid: the root of F in the open octant, the closed
    forms on the planes of symmetry, else the ellipse in the plane)."""
    if y0 < ON_PLANE * e0:  # on a plane of symmetry to below round-off: on it (module docstring)
        y0 = 0.0
    if y1 < ON_PLANE * e1:
        y1 = 0.0
    if y2 < ON_PLANE * e2:
        y2 = 0.0
    if y2 > 0.0:
        if y1 > 0.0:
            if y0 > 0.0:
                z0, z1, z2 = y0 / e0, y1 / e1, y2 / e2
                g = z0 * z0 + z1 * z1 + z2 * z2 - 1.0
                if g == 0.0:
                    return y0, y1, y2
                r0, r1 = (e0 / e2) * (e0 / e2), (e1 / e2) * (e1 / e2)
                a0, a1 = (e0 - e2) * (e0 + e2) / (e2 * e2), (e1 - e2) * (e1 + e2) / (e2 * e2)  # r_i - 1
                u = _root3(r0, r1, a0, a1, z0, z1, z2, g)
                return r0 * y0 / (u + a0), r1 * y1 / (u + a1), y2 / u  # x_i = e_i^2 y_i / (t + e_i^2)
            x1, x2 = _ellipse_nearest(e1, e2, y1, y2)  # y0 = 0: t > -e2^2 >= -e0^2, so x0 = 0
            return 0.0, x1, x2
        if y0 > 0.0:
            x0, x2 = _ellipse_nearest(e0, e2, y0, y2)  # y1 = 0: x1 = 0
            return x0, 0.0, x2
        return 0.0, 0.0, e2  # on the minor axis: its pole
    # y2 = 0: off the plane where t = -e2^2 gives a point of the ellipsoid (x2 = e2 sqrt(discr))
    denom0, denom1 = (e0 - e2) * (e0 + e2), (e1 - e2) * (e1 + e2)  # e_i^2 - e2^2 to its relative round-off
    numer0, numer1 = e0 * y0, e1 * y1
    if numer0 < denom0 and numer1 < denom1:
        xde0, xde1 = numer0 / denom0, numer1 / denom1  # x_i / e_i at t = -e2^2
        discr = 1.0 - xde0 * xde0 - xde1 * xde1
        if discr > 0.0:
            return e0 * xde0, e1 * xde1, e2 * np.sqrt(discr)
    x0, x1 = _ellipse_nearest(e0, e1, y0, y1)  # else the ellipse in the plane
    return x0, x1, 0.0


@njit(cache=True)
def _distance(x0, x1, x2, pc, Rc, s):
    """(d, g0, g1, g2): ellipsoid_distance on scalars (no arrays: the segment's bisection calls it)."""
    d0, d1, d2 = x0 - pc[0], x1 - pc[1], x2 - pc[2]
    l0 = Rc[0, 0] * d0 + Rc[1, 0] * d1 + Rc[2, 0] * d2  # y = Rc^T (x - pc): the point in the ellipsoid's axes
    l1 = Rc[0, 1] * d0 + Rc[1, 1] * d1 + Rc[2, 1] * d2
    l2 = Rc[0, 2] * d0 + Rc[1, 2] * d1 + Rc[2, 2] * d2
    if s[0] == s[1] and s[1] == s[2]:  # a sphere: |y| - r, along y (at the centre: the first axis)
        length = _length3(l0, l1, l2)
        if length > 0.0:
            n0, n1, n2 = l0 / length, l1 / length, l2 / length
        else:
            n0, n1, n2 = 1.0, 0.0, 0.0
        d = length - s[0]
    else:
        # sort the semi-axes, e0 >= e1 >= e2: local axes i0, i1, i2
        i0, i1, i2 = 0, 1, 2
        if s[i0] < s[i1]:
            i0, i1 = i1, i0
        if s[i1] < s[i2]:
            i1, i2 = i2, i1
        if s[i0] < s[i1]:
            i0, i1 = i1, i0
        e0, e1, e2 = s[i0], s[i1], s[i2]
        la = l0 if i0 == 0 else (l1 if i0 == 1 else l2)
        lb = l0 if i1 == 0 else (l1 if i1 == 1 else l2)
        lc = l0 if i2 == 0 else (l1 if i2 == 1 else l2)
        y0, y1, y2 = abs(la), abs(lb), abs(lc)  # the first octant
        x0n, x1n, x2n = _ellipsoid_nearest(e0, e1, e2, y0, y1, y2)
        a, b, c = x0n - y0, x1n - y1, x2n - y2
        d = _length3(a, b, c)
        q0, q1, q2 = y0 / e0, y1 / e1, y2 / e2
        if q0 * q0 + q1 * q1 + q2 * q2 < 1.0:  # inside
            d = -d
        # the outward normal at the nearest point: x_i / e_i^2, its signs those of y, normalised
        m0, m1, m2 = x0n / (e0 * e0), x1n / (e1 * e1), x2n / (e2 * e2)
        if la < 0.0:
            m0 = -m0
        if lb < 0.0:
            m1 = -m1
        if lc < 0.0:
            m2 = -m2
        length = _length3(m0, m1, m2)
        m0, m1, m2 = m0 / length, m1 / length, m2 / length
        n0 = m0 if i0 == 0 else (m1 if i1 == 0 else m2)  # back to the ellipsoid's axes
        n1 = m0 if i0 == 1 else (m1 if i1 == 1 else m2)
        n2 = m0 if i0 == 2 else (m1 if i1 == 2 else m2)
    g0 = Rc[0, 0] * n0 + Rc[0, 1] * n1 + Rc[0, 2] * n2  # R n: the world frame
    g1 = Rc[1, 0] * n0 + Rc[1, 1] * n1 + Rc[1, 2] * n2
    g2 = Rc[2, 0] * n0 + Rc[2, 1] * n1 + Rc[2, 2] * n2
    return d, g0, g1, g2


@njit(cache=True)
def ellipsoid_distance(x, pc, Rc, s, grad):
    """The signed distance [m] of a point from an ellipsoid's surface (< 0 inside), exact to round-off (Eberly's
    robust bisection, module docstring).

    x: (3,) point, world frame [m]
    pc: (3,) the ellipsoid's centre, world frame [m]
    Rc: (3, 3) its axes, world frame (columns)
    s: (3,) its semi-axes along them, > 0 [m]
    grad: (3,) out: the outward unit normal at the surface's point nearest to x (the distance's gradient; at a point
        with several nearest points, such as the centre, the normal at one of them)
    """
    d, g0, g1, g2 = _distance(x[0], x[1], x[2], pc, Rc, s)
    grad[0], grad[1], grad[2] = g0, g1, g2
    return d


@njit(cache=True, inline="always")
def _support(d0, d1, d2, pc, Rc, s):
    """(x0, x1, x2): the support point along (d0, d1, d2) (ellipsoid_support) on scalars."""
    m = max(abs(d0), abs(d1), abs(d2))
    if m == 0.0:  # every point maximises 0: the end of the first axis
        return pc[0] + s[0] * Rc[0, 0], pc[1] + s[0] * Rc[1, 0], pc[2] + s[0] * Rc[2, 0]
    d0, d1, d2 = d0 / m, d1 / m, d2 / m  # scaled: |S R^T d| neither overflows nor underflows
    w0 = s[0] * (Rc[0, 0] * d0 + Rc[1, 0] * d1 + Rc[2, 0] * d2)  # w = S R^T d
    w1 = s[1] * (Rc[0, 1] * d0 + Rc[1, 1] * d1 + Rc[2, 1] * d2)
    w2 = s[2] * (Rc[0, 2] * d0 + Rc[1, 2] * d1 + Rc[2, 2] * d2)
    length = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    v0, v1, v2 = s[0] * w0 / length, s[1] * w1 / length, s[2] * w2 / length  # S w / |w|, in the ellipsoid's axes
    return (pc[0] + Rc[0, 0] * v0 + Rc[0, 1] * v1 + Rc[0, 2] * v2,
            pc[1] + Rc[1, 0] * v0 + Rc[1, 1] * v1 + Rc[1, 2] * v2,
            pc[2] + Rc[2, 0] * v0 + Rc[2, 1] * v1 + Rc[2, 2] * v2)


@njit(cache=True)
def ellipsoid_support(d, pc, Rc, s, out):
    """The ellipsoid's point farthest along a direction: x = pc + R S^2 R^T d / |S R^T d| (closed form; the image of
    the unit sphere's point S R^T d / |S R^T d| under x = pc + R S w). d = 0: the end of the first axis (every point
    maximises 0).

    d: (3,) direction, world frame, any length
    pc: (3,) the ellipsoid's centre, world frame [m]
    Rc: (3, 3) its axes, world frame (columns)
    s: (3,) its semi-axes, > 0 [m]
    out: (3,) out: the support point, world frame [m]
    """
    out[0], out[1], out[2] = _support(d[0], d[1], d[2], pc, Rc, s)


@njit(cache=True)
def plane_ellipsoid(pp, n, pc, Rc, s, point):
    """The signed distance [m] of an ellipsoid from a plane, the ellipsoid on the plane's +n side (< 0: it reaches
    below the plane): n.(pc - pp) - |S R^T n| (closed form: the height of its support point along -n).

    pp: (3,) a point of the plane, world frame [m]
    n: (3,) the plane's unit normal, world frame
    pc: (3,) the ellipsoid's centre, world frame [m]
    Rc: (3, 3) its axes, world frame (columns)
    s: (3,) its semi-axes, > 0 [m]
    point: (3,) out: the ellipsoid's point lowest towards the plane (its support point along -n), world frame [m]
    """
    w0 = s[0] * (Rc[0, 0] * n[0] + Rc[1, 0] * n[1] + Rc[2, 0] * n[2])  # w = S R^T n
    w1 = s[1] * (Rc[0, 1] * n[0] + Rc[1, 1] * n[1] + Rc[2, 1] * n[2])
    w2 = s[2] * (Rc[0, 2] * n[0] + Rc[1, 2] * n[1] + Rc[2, 2] * n[2])
    reach = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)  # the support function along n, less n.pc
    point[0], point[1], point[2] = _support(-n[0], -n[1], -n[2], pc, Rc, s)
    return n[0] * (pc[0] - pp[0]) + n[1] * (pc[1] - pp[1]) + n[2] * (pc[2] - pp[2]) - reach


@njit(cache=True, inline="always")
def _slope(p, u, t, pc, Rc, s):
    """d/dt of the signed distance of p + t u from the ellipsoid: grad.u (nondecreasing in t: the distance is
    convex)."""
    _d, g0, g1, g2 = _distance(p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2], pc, Rc, s)
    return g0 * u[0] + g1 * u[1] + g2 * u[2]


@njit(cache=True)
def _slope_bracket(p, u, half, pc, Rc, s, level, inclusive):
    """(a, b): where along the segment the distance's slope (nondecreasing) first reaches `level` (inclusive:
    slope >= level, else slope > level), bisected to the last bit: b the first point that does, a the last that does
    not (both -half when the start does, both half when the end does not)."""
    a, b = -half, half
    start = _slope(p, u, a, pc, Rc, s)
    if start > level or (inclusive and start == level):
        return a, a
    end = _slope(p, u, b, pc, Rc, s)
    if not (end > level or (inclusive and end == level)):
        return b, b
    for _ in range(ROOT_ITERATIONS):
        m = 0.5 * (a + b)
        if m <= a or m >= b:
            break
        slope = _slope(p, u, m, pc, Rc, s)
        if slope > level or (inclusive and slope == level):
            b = m
        else:
            a = m
    return a, b


@njit(cache=True)
def segment_ellipsoid_closest(p, u, half, pc, Rc, s):
    """(t, lo, hi): the parameter t [m] in [-half, half] of the segment's point p + t u closest to the ellipsoid,
    and the interval [lo, hi] [m] about it where the distance's slope is within SLOPE_TOLERANCE of 0 (one point
    unless the segment runs parallel to the surface; t is its middle). The signed distance of a convex set is
    convex along a segment, so its slope is nondecreasing: each end of the interval is found by bisection on the
    slope's sign, to the last bit of t (as geometry.segment_cylinder_closest).

    p: (3,) the segment's centre, world frame [m]
    u: (3,) its unit direction, world frame
    half: its half-length [m]
    pc: (3,) the ellipsoid's centre, world frame [m]
    Rc: (3, 3) its axes, world frame (columns)
    s: (3,) its semi-axes, > 0 [m]
    """
    _a, lo = _slope_bracket(p, u, half, pc, Rc, s, -SLOPE_TOLERANCE, True)
    hi, _b = _slope_bracket(p, u, half, pc, Rc, s, SLOPE_TOLERANCE, False)
    if hi < lo:
        lo, hi = hi, lo
    return 0.5 * (lo + hi), lo, hi


__all__ = ["ellipsoid_distance", "ellipsoid_support", "plane_ellipsoid", "segment_ellipsoid_closest",
           "SLOPE_TOLERANCE"]
