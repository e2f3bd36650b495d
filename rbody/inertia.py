"""Mass properties of a rigid body: mass, centre of mass and the inertia tensor.

The chapter defines the inertia tensor of a system of particles as

    I_ab = sum_i m_i (|x_i|^2 d_ab - x_ia x_ib),

so the products of inertia (a != b) carry a minus sign. ``Inertia.tensor`` is always taken
about the centre of mass, in the axes of the frame the body is given in.  ``about(point)``
applies the parallel-axis theorem, ``rotated(R)`` maps the tensor to R I R^T; no name does both.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Iterable, Union

import numpy as np

from rbody.checks import finite_array, nonnegative, positive
from rbody.mesh import mass_properties

AxisLike = Union[str, Iterable[float], np.ndarray]

# Largest |tensor entry| [kg m^2] accepted: sums of a few moments (eigenvalues, the parallel-axis
# theorem, the triangle inequality) must stay finite in float64 (max 1.8e308).
LARGEST_MOMENT = 1e300
# Below this a mass or moment is carried by float64 with less than its 53 bits, or its round-off is (the
# smallest normal number / eps): subnormal arithmetic would silently change the tensor.
SMALLEST_CARRIED = float(np.finfo(float).tiny / np.finfo(float).eps)
# Relative tolerance of the symmetry and triangle-inequality checks on construction.
STRUCTURE_RTOL = 1e-12


def unit_axis(axis: AxisLike, name: str = "axis") -> np.ndarray:
    """(3,) unit vector from "x", "y", "z" or a non-zero 3-vector."""
    if isinstance(axis, str):
        table = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
        if axis not in table:
            raise ValueError(f"{name}={axis!r}: expected 'x', 'y', 'z' or a 3-vector")
        return np.array(table[axis])
    vector = finite_array(axis, name, shape=(3,))
    # Scaled by the largest component before squaring: |v|^2 of [1e300, 1e300, 0] overflows, of
    # [1e-200, 0, 0] underflows to 0, and neither changes the direction.
    largest = float(np.max(np.abs(vector)))
    if largest == 0.0:
        raise ValueError(f"{name}={vector.tolist()}: a direction must be non-zero")
    norm = np.linalg.norm(vector)
    if np.isfinite(norm) and norm > 0:
        return vector / norm
    scaled = vector / largest
    return scaled / np.linalg.norm(scaled)


def _positive(value, name: str) -> np.float64:
    """positive(), as a numpy float: moments like M L^2 then overflow to inf (refused by Inertia as not
    finite) instead of raising Python's OverflowError."""
    return np.float64(positive(value, name))


def _nonnegative(value, name: str) -> np.float64:
    return np.float64(nonnegative(value, name))


def _symmetric_tensor(moment_along: float, moment_across: float, axis: AxisLike) -> np.ndarray:
    """(3,3) tensor of a body symmetric about `axis`: moment_along n n^T + moment_across (1 - n n^T)."""
    n = unit_axis(axis)
    projector = np.outer(n, n)
    return moment_along * projector + moment_across * (np.eye(3) - projector)


def _readonly(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=np.float64)
    array.flags.writeable = False
    return array


def rotation_matrix(rotation: np.ndarray) -> np.ndarray:
    """(3,3) proper rotation from a (3,3) matrix or a (w, x, y, z) quaternion (normalised), checked."""
    rotation = finite_array(rotation, "R")
    if rotation.shape == (4,):
        from rbody.motion import quat_to_matrix

        return quat_to_matrix(rotation)
    if rotation.shape != (3, 3):
        raise ValueError(f"R has shape {rotation.shape}: expected a (3, 3) rotation matrix "
                         "or a (4,) quaternion (w, x, y, z)")
    matrix = rotation
    if not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-10) or np.linalg.det(matrix) < 0:
        raise ValueError(f"R={matrix.tolist()}: expected a proper rotation (R R^T = 1, det R = +1)")
    return matrix


@dataclass(frozen=True)
class Inertia:
    """Mass properties of one rigid body.

    mass:   total mass [kg], finite and > 0
    com:    (3,) centre of mass in the body's frame [m]
    tensor: (3,3) inertia tensor about the centre of mass, body-frame axes [kg m^2]
    """

    mass: float
    com: np.ndarray
    tensor: np.ndarray

    def __post_init__(self) -> None:
        mass = positive(finite_array(self.mass, "mass", shape=()), "mass")
        com = finite_array(self.com, "com", shape=(3,))
        tensor = finite_array(self.tensor, "tensor", shape=(3, 3))
        if mass < SMALLEST_CARRIED or 0 < np.max(np.abs(tensor)) < SMALLEST_CARRIED:
            raise ValueError(
                f"mass={float(mass):.3g} kg, largest |tensor| entry {float(np.max(np.abs(tensor))):.3g} kg m^2: "
                f"below {SMALLEST_CARRIED:.3g}, float64 carries them (or their round-off) as subnormal numbers "
                "with fewer digits; give the body in smaller units of length or mass")
        scale = max(float(np.max(np.abs(tensor))), np.finfo(float).tiny)
        if scale > LARGEST_MOMENT:
            raise ValueError(
                f"tensor={tensor.tolist()}: its largest entry {scale:.3g} kg m^2 is beyond {LARGEST_MOMENT:g}, "
                "where sums of moments (the principal moments, the parallel-axis theorem) overflow float64; "
                "give the body in larger units of length or mass")
        asymmetry = float(np.max(np.abs(tensor - tensor.T)))
        if asymmetry > STRUCTURE_RTOL * scale:
            raise ValueError(
                f"tensor={tensor.tolist()}: an inertia tensor must be symmetric "
                f"(largest |I - I^T| is {asymmetry:.3g}, relative {asymmetry / scale:.3g} > {STRUCTURE_RTOL})"
            )
        tensor = 0.5 * (tensor + tensor.T)
        moments = np.linalg.eigvalsh(tensor)
        if moments[0] < -STRUCTURE_RTOL * scale:
            raise ValueError(
                f"tensor has principal moments {moments.tolist()}: an inertia tensor must be positive "
                "semi-definite (no negative moment)"
            )
        if moments[0] + moments[1] < moments[2] - STRUCTURE_RTOL * scale:
            raise ValueError(
                f"tensor has principal moments {moments.tolist()}: they must obey the triangle "
                f"inequality A + B >= C ({moments[0]:.6g} + {moments[1]:.6g} < {moments[2]:.6g})"
            )
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "com", _readonly(com))
        object.__setattr__(self, "tensor", _readonly(tensor))

    @classmethod
    def as_given(cls, mass: float, com: Iterable[float], tensor: np.ndarray) -> "Inertia":
        """Mass properties exactly as a model file gives them, even when no body has them: every check of
        Inertia(...) (mass > 0, finite, symmetric, no subnormal or overflowing entry) except the two physical
        ones, a positive semi-definite tensor and the triangle inequality A + B >= C. For importers that load a
        file's dynamics as written (rbody.urdf names each such body and the size of its violation); such an
        Inertia must not be passed to operations that build a new one (rotated, __add__), which check again."""
        tensor = finite_array(tensor, "tensor", shape=(3, 3))
        scale = max(float(np.max(np.abs(tensor))), np.finfo(float).tiny)
        if 0 < float(np.max(np.abs(tensor))) < SMALLEST_CARRIED or scale > LARGEST_MOMENT:
            raise ValueError(f"tensor={tensor.tolist()}: its largest entry {scale:.3g} kg m^2 is outside "
                             f"[{SMALLEST_CARRIED:.3g}, {LARGEST_MOMENT:g}], where float64 cannot carry its sums")
        asymmetry = float(np.max(np.abs(tensor - tensor.T)))
        if asymmetry > STRUCTURE_RTOL * scale:
            raise ValueError(f"tensor={tensor.tolist()}: an inertia tensor must be symmetric (largest |I - I^T| is "
                             f"{asymmetry:.3g})")
        inertia = cls(mass, com, np.zeros((3, 3)))  # every other check
        object.__setattr__(inertia, "tensor", _readonly(0.5 * (tensor + tensor.T)))
        return inertia

    # ----- constructors: uniform bodies centred on the origin -----------------------------------

    @classmethod
    def point_masses(cls, masses: Iterable[float], positions: Iterable[Iterable[float]]) -> "Inertia":
        """System of particles: masses (n,) [kg], positions (n, 3) [m].

        Tensor about the centre of mass, I_ab = sum m (|y|^2 d_ab - y_a y_b), y = x - R.
        """
        masses = finite_array(masses, "masses", ndim=1)
        if len(masses) == 0:
            raise ValueError("masses=[]: a system of particles needs at least one particle")
        positions = finite_array(positions, "positions", shape=(len(masses), 3))
        if np.any(masses <= 0):
            raise ValueError(f"masses={masses.tolist()}: every particle mass must be > 0 [kg]")
        total = masses.sum()
        # The centre of mass as the first particle plus the mean offset from it: the offsets are of the
        # size of the body, not of its distance from the origin (at x = 1e16 a mean of the positions
        # themselves loses the metres that set the moments).
        offsets = positions - positions[0]
        com_offset = masses @ offsets / total
        com = positions[0] + com_offset
        y = offsets - com_offset
        # Moments scaled by the largest offset before squaring (no overflow), then scaled back.
        size = float(np.max(np.abs(y)))
        if size == 0.0:
            return cls(total, com, np.zeros((3, 3)))
        u = y / size
        tensor = (np.eye(3) * np.sum(masses * np.sum(u * u, axis=1)) - (masses[:, None] * u).T @ u) * size
        with np.errstate(over="raise"):
            try:
                tensor = tensor * size
            except FloatingPointError:
                raise ValueError(f"positions span {size:.3g} m: the moments m |x|^2 overflow float64") from None
        # Particles within ~1e-146 m of their centre have moments below float64's normal range: to float64 the set
        # is a point mass (as the sum of two point bodies so close is: __add__), not a body given in wrong units
        tensor[np.abs(tensor) < SMALLEST_CARRIED] = 0.0
        return cls(total, com, tensor)

    @classmethod
    def rod(cls, mass: float, length: float, axis: AxisLike = "z") -> "Inertia":
        """Thin rod along `axis`: M L^2 / 12 across, zero along it."""
        length = _positive(length, "length")
        return cls(mass, np.zeros(3), _symmetric_tensor(0.0, _positive(mass, "mass") * length**2 / 12, axis))

    @classmethod
    def hoop(cls, mass: float, radius: float, axis: AxisLike = "z") -> "Inertia":
        """Thin ring normal to `axis`: M a^2 about the axis, M a^2 / 2 across."""
        moment = _positive(mass, "mass") * _positive(radius, "radius") ** 2
        return cls(mass, np.zeros(3), _symmetric_tensor(moment, moment / 2, axis))

    @classmethod
    def disc(cls, mass: float, radius: float, axis: AxisLike = "z") -> "Inertia":
        """Thin disc normal to `axis`: M a^2 / 2 about the axis, M a^2 / 4 across."""
        moment = _positive(mass, "mass") * _positive(radius, "radius") ** 2
        return cls(mass, np.zeros(3), _symmetric_tensor(moment / 2, moment / 4, axis))

    @classmethod
    def solid_cylinder(cls, mass: float, radius: float, length: float, axis: AxisLike = "z") -> "Inertia":
        """Uniform cylinder: M a^2 / 2 about the axis, M (3 a^2 + L^2) / 12 across."""
        mass, radius = _positive(mass, "mass"), _positive(radius, "radius")
        length = _positive(length, "length")
        return cls(mass, np.zeros(3), _symmetric_tensor(
            mass * radius**2 / 2, mass * (3 * radius**2 + length**2) / 12, axis))

    @classmethod
    def hollow_cylinder(
        cls, mass: float, inner_radius: float, outer_radius: float, length: float, axis: AxisLike = "z"
    ) -> "Inertia":
        """Thick-walled tube: M (a^2 + b^2) / 2 about the axis, M (3 (a^2 + b^2) + L^2) / 12 across,
        a = inner_radius >= 0, b = outer_radius > 0 [m], length L > 0 [m].

        inner_radius == outer_radius is the thin-walled cylinder, M a^2 about its axis;
        inner_radius == 0 is the solid cylinder.
        """
        mass = _positive(mass, "mass")
        inner = _nonnegative(inner_radius, "inner_radius")
        outer = _positive(outer_radius, "outer_radius")
        length = _positive(length, "length")
        if inner > outer:
            raise ValueError(
                f"inner_radius={inner} > outer_radius={outer}: the bore must fit inside the tube")
        squares = inner**2 + outer**2
        return cls(mass, np.zeros(3), _symmetric_tensor(
            mass * squares / 2, mass * (3 * squares + length**2) / 12, axis))

    @classmethod
    def solid_sphere(cls, mass: float, radius: float) -> "Inertia":
        """Uniform ball: 2/5 M a^2 about every axis."""
        moment = 0.4 * _positive(mass, "mass") * _positive(radius, "radius") ** 2
        return cls(mass, np.zeros(3), moment * np.eye(3))

    @classmethod
    def spherical_shell(cls, mass: float, radius: float) -> "Inertia":
        """Thin spherical shell: 2/3 M a^2 about every axis."""
        moment = 2.0 / 3.0 * _positive(mass, "mass") * _positive(radius, "radius") ** 2
        return cls(mass, np.zeros(3), moment * np.eye(3))

    @classmethod
    def box(cls, mass: float, size: Iterable[float]) -> "Inertia":
        """Uniform cuboid with full side lengths size (3,) = (a, b, c) [m]:
        I_xx = M (b^2 + c^2) / 12, I_yy = M (a^2 + c^2) / 12, I_zz = M (a^2 + b^2) / 12.

        One side may be 0: a thin rectangular plate (lamina), for which I_zz = I_xx + I_yy
        (the chapter's perpendicular-axis theorem, for c = 0).
        """
        mass = _positive(mass, "mass")
        size = finite_array(size, "size", shape=(3,))
        if np.any(size < 0) or np.sum(size == 0) > 1:
            raise ValueError(f"size={size.tolist()}: side lengths must be >= 0 [m] with at most one "
                             "zero (a plate); use Inertia.rod for a line")
        a2, b2, c2 = size**2
        return cls(mass, np.zeros(3), mass / 12 * np.diag([b2 + c2, a2 + c2, a2 + b2]))

    @classmethod
    def from_mesh(cls, mesh, *, density: float | None = None, mass: float | None = None,
                  shell: bool = False) -> "Inertia":
        """Mass properties of a triangle mesh: trimesh.Trimesh (or Scene), or a path trimesh can load; exactly one of
        density [kg/m^3, or kg/m^2 for shell=True] and mass [kg] (rbody.mesh.mass_properties, which says what is
        checked and how)."""
        return cls(*mass_properties(mesh, density=density, mass=mass, shell=shell))

    # ----- operations ----------------------------------------------------------------------------

    def about(self, point: Iterable[float]) -> np.ndarray:
        """(3,3) tensor about `point` (body frame) [kg m^2]: I_c + M (|d|^2 1 - d d^T), d = com - point."""
        d = self.com - finite_array(point, "point", shape=(3,))
        return self.tensor + self.mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))

    def moment(self, axis: AxisLike, through: Iterable[float] | None = None) -> float:
        """n^T I n [kg m^2] about the line along `axis` through `through` (default: the centre of mass)."""
        n = unit_axis(axis)
        tensor = self.tensor if through is None else self.about(through)
        return float(n @ tensor @ n)

    def rotated(self, rotation: np.ndarray) -> "Inertia":
        """The body turned by R (3x3 or (w,x,y,z)): tensor R I R^T, centre of mass R c."""
        matrix = rotation_matrix(rotation)
        return Inertia(self.mass, matrix @ self.com, matrix @ self.tensor @ matrix.T)

    def translated(self, offset: Iterable[float]) -> "Inertia":
        """The body moved by offset (3,) [m]; the tensor about its centre of mass is unchanged."""
        return dataclasses.replace(self, com=self.com + finite_array(offset, "offset", shape=(3,)))

    def principal(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments ascending (3,) [kg m^2] and axes (3,3) as columns, a proper rotation."""
        moments, axes = np.linalg.eigh(self.tensor)
        if np.linalg.det(axes) < 0:
            axes[:, 2] = -axes[:, 2]
        return moments, axes

    def __add__(self, other: "Inertia") -> "Inertia":
        """The two bodies joined: masses add, com mass-weighted, tensors shifted to the new com."""
        if not isinstance(other, Inertia):
            return NotImplemented
        mass = self.mass + other.mass
        com = (self.mass * self.com + other.mass * other.com) / mass
        tensor = self.about(com) + other.about(com)
        # A shift by a round-off of com (coincident bodies) can leave a subnormal entry: it is zero, not a body
        # too small for float64 (each part was checked), so it is not refused.
        tensor[np.abs(tensor) < SMALLEST_CARRIED] = 0.0
        return Inertia(mass, com, tensor)

    def angular_momentum(self, omega: Iterable[float]) -> np.ndarray:
        """L = I w [kg m^2/s] about the centre of mass; omega (..., 3) [rad/s]."""
        omega = finite_array(omega, "omega")
        return omega @ self.tensor  # I is symmetric, so w I = (I w)^T row by row

    def kinetic_energy(self, omega: Iterable[float]) -> np.ndarray | float:
        """T = 1/2 w^T I w [J] of rotation about the centre of mass; omega (..., 3) [rad/s]."""
        omega = finite_array(omega, "omega")
        return 0.5 * np.einsum("...a,ab,...b->...", omega, self.tensor, omega)

    def __repr__(self) -> str:
        return (f"Inertia(mass={self.mass!r}, com={self.com.tolist()!r}, "
                f"tensor={self.tensor.tolist()!r})")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Inertia):
            return NotImplemented
        return (self.mass == other.mass and np.array_equal(self.com, other.com)
                and np.array_equal(self.tensor, other.tensor))

    __hash__ = None  # type: ignore[assignment]
