"""N particles with pair forces: the chapter's conservation laws (section 5.1).

Each particle i (mass m_i, position x_i) feels the pair forces F_ij of the others, with Newton's third
law F_ij = -F_ji. No external force acts: uniform gravity is accepted for the common signature and
NOT applied, because the chapter's statements are about internal forces. Then

- total momentum P = sum m_i x_i' is conserved (5.1): the pair forces cancel;
- dL/dt = sum_{i<j} (x_i - x_j) x F_ij for the angular momentum L = sum m_i x_i x x_i' about the
  origin, which vanishes when F_ij is parallel to x_i - x_j (the strong form of the third law):
  L is conserved (5.2);
- when F_ij = -grad_i V_ij(|x_i - x_j|), E = T + sum_{i<j} V_ij is conserved.

forces="central": softened gravity, V_ij = -k m_i m_j / sqrt(r^2 + s^2), so
F_ij = -k m_i m_j (x_i - x_j) / (r^2 + s^2)^(3/2): along the line, from a potential. P, L and E are
all conserved.

forces="noncentral": F_ij = k m_i m_j e_z x (x_i - x_j) / (r^2 + s^2)^(3/2): equal and opposite but
perpendicular to the line joining the pair. P is still conserved; L is not, as the chapter warns: the
pair torque (x_i - x_j) x F_ij = k m_i m_j (|d|^2 e_z - d_z d) / (r^2 + s^2)^(3/2), d = x_i - x_j,
turns L_z up at the rate sum k m_i m_j (d_x^2 + d_y^2) / (r^2 + s^2)^(3/2) > 0. The force has a curl,
so it has no potential and the energy is not conserved either: the "energy" observable is then the
kinetic energy alone, changing at the rate sum_i F_i . x_i'.

Initial state, from numpy's default_rng(seed): masses uniform in [0.5, 1.5] / n [kg] (about 1 kg in
all), positions uniform in the cube [-0.5, 0.5]^3 [m], velocities normal with standard deviation
0.5 m/s in each component. With k = 1 and s = 0.1 m the motions take about a second.

Native model: y = (x_1..x_n, x_1'..x_n') (6n numbers); the O(n^2) pair loop is a numba kernel that
computes each F_ij once and adds it to i and subtracts it from j, so sum_i F_i = 0 up to the round-off
of the accumulation; every method then keeps P to round-off whatever dt: each step changes it by the
roundings of the updates, about eps (sum_i m_i |v_i| + h sum |F_ij|) (tested: within
steps * n * eps * (|P| + sum m |v|)). Verlet keeps L to round-off with central forces: a kick changes L by
h/2 sum_{i<j} (x_i - x_j) x F_ij = 0, a drift by h sum m_i x_i' x x_i' = 0; so does gauss6 (it keeps
every quadratic invariant), while rk4 and euler do not.

There is no layout for other simulators: no body touches or is jointed to another, and forces
between free points are not a MuJoCo or pymunk model in this project.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
from numba import njit

from rbody.checks import finite_array, one_of, positive, representable, scene_arguments
from rbody.particles import Particles
from rbody.layout import Layout
from rbody.engine.native import NativeModel
from rbody.scene import Scene

FORCE_KINDS = ("central", "noncentral")
PARTICLE_METHODS = ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6", "reference")

# q = (x_1, ..., x_n) (3n,); params = (k, s^2, noncentral (0 or 1), m_1, ..., m_n)


@njit(cache=True)
def pair_forces(q, p, out):
    """out (3n,) = F_i = sum_j F_ij, each pair computed once."""
    n = q.size // 3
    k, soft2, noncentral = p[0], p[1], p[2] != 0.0
    for j in range(3 * n):
        out[j] = 0.0
    for i in range(n):
        xi, yi, zi = q[3 * i], q[3 * i + 1], q[3 * i + 2]
        fx_i, fy_i, fz_i = 0.0, 0.0, 0.0
        for j in range(i + 1, n):
            dx, dy, dz = xi - q[3 * j], yi - q[3 * j + 1], zi - q[3 * j + 2]
            r2 = dx * dx + dy * dy + dz * dz + soft2
            c = k * p[3 + i] * p[3 + j] / (r2 * np.sqrt(r2))
            if noncentral:  # c e_z x d
                fx, fy, fz = -c * dy, c * dx, 0.0
            else:           # -c d
                fx, fy, fz = -c * dx, -c * dy, -c * dz
            fx_i += fx
            fy_i += fy
            fz_i += fz
            out[3 * j] -= fx
            out[3 * j + 1] -= fy
            out[3 * j + 2] -= fz
        out[3 * i] += fx_i
        out[3 * i + 1] += fy_i
        out[3 * i + 2] += fz_i


@njit(cache=True)
def particles_accel(q, p, out):
    pair_forces(q, p, out)
    for i in range(q.size // 3):
        inverse_mass = 1.0 / p[3 + i]
        out[3 * i] *= inverse_mass
        out[3 * i + 1] *= inverse_mass
        out[3 * i + 2] *= inverse_mass


@njit(cache=True)
def particles_rhs(y, p, out):
    m = y.size // 2
    for j in range(m):
        out[j] = y[m + j]
    particles_accel(y[:m], p, out[m:])


@njit(cache=True)
def pair_potential(q, p):
    """sum_{i<j} V_ij = -k sum m_i m_j / sqrt(r^2 + s^2) [J] (central forces)."""
    n = q.size // 3
    total = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            dx, dy, dz = q[3 * i] - q[3 * j], q[3 * i + 1] - q[3 * j + 1], q[3 * i + 2] - q[3 * j + 2]
            total -= p[0] * p[3 + i] * p[3 + j] / np.sqrt(dx * dx + dy * dy + dz * dz + p[1])
    return total


@njit(cache=True)
def pair_torque(q, p, out):
    """out (3,) = sum_{i<j} (x_i - x_j) x F_ij [N m]."""
    n = q.size // 3
    k, soft2, noncentral = p[0], p[1], p[2] != 0.0
    out[0], out[1], out[2] = 0.0, 0.0, 0.0
    for i in range(n):
        for j in range(i + 1, n):
            dx, dy, dz = q[3 * i] - q[3 * j], q[3 * i + 1] - q[3 * j + 1], q[3 * i + 2] - q[3 * j + 2]
            r2 = dx * dx + dy * dy + dz * dz + soft2
            c = k * p[3 + i] * p[3 + j] / (r2 * np.sqrt(r2))
            if noncentral:
                fx, fy, fz = -c * dy, c * dx, 0.0
            else:
                fx, fy, fz = -c * dx, -c * dy, -c * dz
            out[0] += dy * fz - dz * fy
            out[1] += dz * fx - dx * fz
            out[2] += dx * fy - dy * fx


@njit(cache=True)
def _potentials(q, p, out):
    for s in range(q.shape[0]):
        out[s] = pair_potential(q[s], p)


@njit(cache=True)
def _torques(q, p, out):
    for s in range(q.shape[0]):
        pair_torque(q[s], p, out[s])


@dataclass(frozen=True, kw_only=True)
class ParticleSystem(Scene):
    """n particles with pair forces and no external force (random start from `seed`).

    forces: "central" (softened gravity, from a potential) or "noncentral" (perpendicular to the line
    joining each pair); strength k [N m^2/kg^2] and softening s [m] set F_ij's size
    k m_i m_j |d| / (|d|^2 + s^2)^(3/2). Observables momentum (T, 3) [kg m/s], angular_momentum (T, 3)
    about the origin [kg m^2/s], energy (T,) [J].
    """

    n: int
    seed: int
    forces: str = "central"
    strength: float = 1.0
    softening: float = 0.1

    observables: ClassVar[tuple[str, ...]] = ("momentum", "angular_momentum", "energy")
    main_observable: ClassVar[str] = "energy"
    planar: ClassVar[bool] = False
    preferred_methods: ClassVar[tuple[str, ...]] = PARTICLE_METHODS
    applies_gravity: ClassVar[bool] = False  # internal forces only

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("n", "seed"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise ValueError(f"{name}={value!r}: expected a whole number")
        if self.n < 2:
            raise ValueError(f"n={self.n!r}: need at least 2 particles for a pair force")
        if self.seed < 0:
            raise ValueError(f"seed={self.seed!r}: must be >= 0 (numpy.random.default_rng)")
        one_of(self.forces, "forces", FORCE_KINDS)
        object.__setattr__(self, "strength", positive(self.strength, "strength"))
        object.__setattr__(self, "softening", positive(self.softening, "softening"))
        if np.ndim(self.strength) or np.ndim(self.softening):
            raise ValueError("strength and softening must be single numbers (the scene is not batched)")

    @cached_property
    def initial(self) -> Particles:
        """The particles at t = 0, drawn from numpy.random.default_rng(seed)."""
        rng = np.random.default_rng(self.seed)
        masses = rng.uniform(0.5, 1.5, self.n) / self.n
        positions = rng.uniform(-0.5, 0.5, (self.n, 3))
        velocities = rng.normal(0.0, 0.5, (self.n, 3))
        return Particles(masses, positions, velocities)

    def params(self) -> np.ndarray:
        """(3 + n,) k, s^2, noncentral flag, masses: what the kernels read."""
        return np.concatenate([[self.strength, self.softening**2, float(self.forces == "noncentral")],
                               self.initial.masses])

    # --- observables -------------------------------------------------------------------------

    def observe_states(self, positions: np.ndarray, velocities: np.ndarray) -> dict[str, np.ndarray]:
        """Observables from positions and velocities (T, n, 3)."""
        masses = self.initial.masses
        momentum = np.einsum("i,tij->tj", masses, velocities)
        angular = np.einsum("i,tij->tj", masses, np.cross(positions, velocities))
        energy = 0.5 * np.einsum("i,tij,tij->t", masses, velocities, velocities)
        if self.forces == "central":
            potential = np.empty(positions.shape[0])
            _potentials(np.ascontiguousarray(positions.reshape(positions.shape[0], -1)), self.params(), potential)
            energy = energy + potential
        return {"momentum": momentum, "angular_momentum": angular, "energy": energy}

    def internal_torque(self, positions) -> np.ndarray:
        """sum_{i<j} (x_i - x_j) x F_ij (T, 3) [N m] at positions (T, n, 3) [m]: dL/dt."""
        positions = finite_array(positions, "positions")
        if positions.ndim != 3 or positions.shape[1:] != (self.n, 3):
            raise ValueError(f"positions has shape {positions.shape}: expected (T, {self.n}, 3)")
        torque = np.empty((positions.shape[0], 3))
        _torques(np.ascontiguousarray(positions.reshape(positions.shape[0], -1)), self.params(), torque)
        return torque

    def exact(self, t) -> dict[str, np.ndarray]:
        """The conserved quantities at times t (T,): momentum always; angular momentum and energy for
        central forces only (the non-central ones change them, with no closed form)."""
        t = finite_array(t, "t").reshape(-1)
        start = self.initial
        values = {"momentum": start.momentum}
        if self.forces == "central":
            energy = self.observe_states(start.positions[None], start.velocities[None])["energy"][0]
            values.update(angular_momentum=start.angular_momentum(), energy=np.array(energy))
        return {name: np.broadcast_to(value, (t.size,) + value.shape).copy() for name, value in values.items()}

    # --- native model ----------------------------------------------------------------------------

    def native(self) -> NativeModel:
        start = self.initial
        n = self.n

        def observe(t, y):
            positions = y[:, 0, :3 * n].reshape(t.size, n, 3)
            velocities = y[:, 0, 3 * n:].reshape(t.size, n, 3)
            return {name: value[:, None] for name, value in self.observe_states(positions, velocities).items()}

        y0 = np.concatenate([start.positions.ravel(), start.velocities.ravel()])[None, :]
        return NativeModel(y0=y0, params=self.params()[None, :], rhs=particles_rhs, accel=particles_accel,
                           observe=observe)

    def why_not(self, method: str) -> str:
        return f"{method!r} is not a particle-system method (no exact splitting of the n-body flow)"

    def _layout(self) -> Layout:
        raise NotImplementedError(
            "the particle system has no layout for other simulators: no body touches or is jointed to "
            "another, and pair forces between free points are not a MuJoCo or pymunk model in this project")

    def describe(self) -> str:
        return (f"{self.name}(n={self.n}, seed={self.seed}, forces={self.forces!r}, strength={self.strength!r}, "
                f"softening={self.softening!r} m)")


def particles(n: int, *, seed: int, forces: str = "central", strength: float = 1.0, softening: float = 0.1,
              t_end: float, gravity: float = 9.81) -> ParticleSystem:
    """n particles (n >= 2) with pair forces, no external force: the chapter's conservation laws.

    forces "central" (softened gravity; P, L and E conserved) or "noncentral" (perpendicular to the line
    joining each pair; P conserved, L and E not). Random masses, positions and velocities from seed.
    gravity is accepted and not applied. Observables momentum, angular_momentum, energy.
    """
    scene_arguments(gravity, t_end)
    return representable(ParticleSystem(name="particles", t_end=t_end, gravity=gravity, n=n, seed=seed, forces=forces,
                          strength=strength, softening=softening))
