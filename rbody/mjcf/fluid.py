"""MJCF fluid forces -> rbody.layout.Fluid: <option density viscosity wind>, and geoms' fluidshape and fluidcoef,
as MuJoCo's compiler forms them (user_objects.cc mjCGeom::SetFluidCoefs, engine_util_misc.c mju_geomSemiAxes).

A body with mass uses the ellipsoid model for every geom of its own that has fluidshape="ellipsoid" (MuJoCo:
one such geom switches the whole body to it; its other geoms then feel nothing), else the inertia-box model with
its principal axes. Massless bodies feel nothing (MuJoCo skips them).
"""

from __future__ import annotations

import math


from rbody.layout import FLUID_COEFFICIENTS

# 15-point Gauss-Kronrod quadrature of MuJoCo's GetAddedMassKappa (weights, nodes l = x^3 / (1 - x)^2, dl/dx).
KRONROD_W = (0.01146766, 0.03154605, 0.05239501, 0.07032663, 0.08450236, 0.09517529, 0.10221647, 0.10474107,
             0.10221647, 0.09517529, 0.08450236, 0.07032663, 0.05239501, 0.03154605, 0.01146766)
KRONROD_L = (7.865151709349917e-08, 1.7347976913907274e-05, 0.0003548008144506193, 0.002846636252924549,
             0.014094260903596077, 0.053063261727396636, 0.17041978741317773, 0.5, 1.4036301548686991,
             3.9353484827022642, 11.644841677041734, 39.53187807410903, 177.5711362220801, 1429.4772912937397,
             54087.416549217705)
KRONROD_D = (5.538677720489877e-05, 0.002080868285293228, 0.016514126520723166, 0.07261900344370877,
             0.23985243401862602, 0.6868318249020725, 1.8551129519182894, 5.0, 14.060031152313941, 43.28941239611009,
             156.58546376397112, 747.9826085305024, 5827.4042950027115, 116754.0197944512, 25482945.327264845)
MJ_EPS = 1e-14


def semiaxes(kind: str, size) -> tuple[float, float, float]:
    """The ellipsoid of a geom (MuJoCo's mju_geomSemiAxes): sphere (r, r, r); capsule (r, r, h + r); cylinder
    (r, r, h); ellipsoid and box their three sizes."""
    if kind == "sphere":
        return (float(size[0]),) * 3
    if kind == "capsule":
        return float(size[0]), float(size[0]), float(size[1] + size[0])
    if kind == "cylinder":
        return float(size[0]), float(size[0]), float(size[1])
    return float(size[0]), float(size[1]), float(size[2])


def _kappa(dx: float, dy: float, dz: float) -> float:
    """MuJoCo's GetAddedMassKappa: int_0^inf dx dy dz / sqrt((dx^2 + l)^3 (dy^2 + l) (dz^2 + l)) dl by its
    quadrature."""
    invdx2, invdy2, invdz2 = 1.0 / (dx * dx), 1.0 / (dy * dy), 1.0 / (dz * dz)
    scale = (dx * dx * dx * dy * dz) ** 0.4
    kappa = 0.0
    for w, l, d in zip(KRONROD_W, KRONROD_L, KRONROD_D):
        lam = scale * l
        denom = (1 + lam * invdx2) * math.sqrt((1 + lam * invdx2) * (1 + lam * invdy2) * (1 + lam * invdz2))
        kappa += scale * d / denom * w
    return kappa * invdx2


def added_mass(axes: tuple[float, float, float]) -> tuple[tuple, tuple]:
    """(virtual mass (3,), virtual inertia (3,)) of an ellipsoid of semiaxes `axes`, as MuJoCo's SetFluidCoefs."""
    dx, dy, dz = axes
    volume = 4.0 / 3.0 * math.pi * dx * dy * dz
    kx, ky, kz = _kappa(dx, dy, dz), _kappa(dy, dz, dx), _kappa(dz, dx, dy)

    def factor(a, b, ka, kb):
        return (a * a - b * b) ** 2 * abs(kb - ka) / max(MJ_EPS, abs(2 * (a * a - b * b) + (a * a + b * b) * (ka - kb)))

    inertia = (factor(dy, dz, ky, kz), factor(dz, dx, kz, kx), factor(dx, dy, kx, ky))
    mass = tuple(volume * k / max(MJ_EPS, 2 - k) for k in (kx, ky, kz))
    return mass, tuple(volume * f / 5 for f in inertia)


def coefficients(element, attrib, numbers) -> tuple[float, ...]:
    """The geom's fluidcoef (blunt, slender, angular drag, Kutta, Magnus lift), MuJoCo's defaults where absent."""
    if "fluidcoef" not in attrib:
        return FLUID_COEFFICIENTS
    values = numbers(element, "fluidcoef", attrib)
    if not 1 <= len(values) <= 5:
        raise element.error(f"fluidcoef={attrib['fluidcoef']!r}: expected up to 5 numbers")
    return tuple(values.tolist()) + FLUID_COEFFICIENTS[len(values):]


__all__ = ["semiaxes", "added_mass", "coefficients"]
