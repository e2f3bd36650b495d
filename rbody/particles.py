"""Systems of particles (the chapter's section 5.1): centre of mass, momentum, angular momentum,
the split of kinetic energy, and the reduced mass of a pair."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np

from rbody.checks import finite_array, positive


@dataclass(frozen=True)
class Particles:
    """masses (n,) [kg] > 0; positions (n, 3) [m]; velocities (n, 3) [m/s]."""

    masses: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray

    def __post_init__(self) -> None:
        masses = finite_array(self.masses, "masses", ndim=1)
        if masses.size == 0 or np.any(masses <= 0):
            raise ValueError(f"masses={masses.tolist()}: need at least one particle, every mass > 0 [kg]")
        n = masses.size
        for name, value in (("masses", masses),
                            ("positions", finite_array(self.positions, "positions", shape=(n, 3))),
                            ("velocities", finite_array(self.velocities, "velocities", shape=(n, 3)))):
            value.flags.writeable = False
            object.__setattr__(self, name, value)

    @property
    def total_mass(self) -> float:
        """M = sum m_i [kg]."""
        return float(self.masses.sum())

    @property
    def centre_of_mass(self) -> np.ndarray:
        """(3,) R = sum m_i x_i / M [m]."""
        return self.masses @ self.positions / self.total_mass

    @property
    def centre_of_mass_velocity(self) -> np.ndarray:
        """(3,) R' [m/s]."""
        return self.masses @ self.velocities / self.total_mass

    @property
    def momentum(self) -> np.ndarray:
        """(3,) P = sum m_i x_i' = M R' [kg m/s]."""
        return self.masses @ self.velocities

    def angular_momentum(self, about: Iterable[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """(3,) L = sum m_i (x_i - Q) x x_i' about the fixed point Q [kg m^2/s]."""
        about = finite_array(about, "about", shape=(3,))
        return np.sum(self.masses[:, None] * np.cross(self.positions - about, self.velocities), axis=0)

    @property
    def kinetic_energy(self) -> float:
        """T = 1/2 sum m_i |x_i'|^2 [J]."""
        return 0.5 * float(np.sum(self.masses * np.sum(self.velocities**2, axis=1)))

    def kinetic_energy_split(self) -> tuple[float, float]:
        """(1/2 M |R'|^2, 1/2 sum m_i |y_i'|^2) [J]: the chapter's (5.3), centre-of-mass plus internal."""
        relative = self.relative_to_centre()
        v = self.centre_of_mass_velocity
        return 0.5 * self.total_mass * float(v @ v), relative.kinetic_energy

    def relative_to_centre(self) -> "Particles":
        """The same particles in the centre-of-mass frame: y_i = x_i - R, y_i' = x_i' - R'."""
        return Particles(self.masses, self.positions - self.centre_of_mass,
                         self.velocities - self.centre_of_mass_velocity)


def reduced_mass(m1: float, m2: float) -> float:
    """mu = m1 m2 / (m1 + m2) [kg]."""
    m1, m2 = positive(m1, "m1"), positive(m2, "m2")
    return m1 * m2 / (m1 + m2)


def two_body(m1: float, x1, v1, m2: float, x2, v2) -> dict[str, np.ndarray | float]:
    """Centre-of-mass and relative coordinates of a pair.

    Returns R (3,) [m], R_dot (3,) [m/s], r = x1 - x2 (3,) [m], r_dot (3,) [m/s], mu [kg].
    """
    m1, m2 = positive(m1, "m1"), positive(m2, "m2")
    x1, v1 = finite_array(x1, "x1", shape=(3,)), finite_array(v1, "v1", shape=(3,))
    x2, v2 = finite_array(x2, "x2", shape=(3,)), finite_array(v2, "v2", shape=(3,))
    total = m1 + m2
    return {
        "R": (m1 * x1 + m2 * x2) / total,
        "R_dot": (m1 * v1 + m2 * v2) / total,
        "r": x1 - x2,
        "r_dot": v1 - v2,
        "mu": reduced_mass(m1, m2),
    }
