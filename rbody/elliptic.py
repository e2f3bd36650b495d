"""Jacobi elliptic functions that stay accurate as the parameter m -> 1.

scipy.special.ellipj loses accuracy near m = 1 (the pendulum near its top, free rotation near the
intermediate axis): it works from m and so from 1 - m rounded. Here the complement m1 = 1 - m is
given separately, formed by the caller without cancellation.
"""

from __future__ import annotations

import numpy as np


def jacobi(u: np.ndarray, m: float, m1: float):
    """sn, cn, dn, am of u (T,) at parameter m in [0, 1], with m1 = 1 - m given exactly.

    Descending Landen transformation by the arithmetic-geometric mean (Abramowitz & Stegun 16.4),
    started from b0 = sqrt(m1) so that it stays accurate as m -> 1; dn = sqrt(cn^2 + m1 sn^2)
    avoids the cancellation in 1 - m sn^2 near the turning points.
    """
    a, c = [1.0], [np.sqrt(m)]
    b = np.sqrt(m1)
    while abs(c[-1]) > np.finfo(float).eps * a[-1] and len(a) < 64:
        previous = a[-1]
        c.append((previous - b) / 2)
        a.append((previous + b) / 2)
        b = np.sqrt(previous * b)
    phi = 2.0 ** (len(a) - 1) * a[-1] * np.asarray(u, dtype=np.float64)
    for i in range(len(a) - 1, 0, -1):
        phi = (np.arcsin(c[i] * np.sin(phi) / a[i]) + phi) / 2
    sn, cn = np.sin(phi), np.cos(phi)
    return sn, cn, np.sqrt(cn * cn + m1 * sn * sn), phi
