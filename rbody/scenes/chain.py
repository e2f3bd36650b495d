"""The pendulum chain: n uniform rods hinged end to end in a vertical plane (the double rod pendulum
and longer chains), the first hinged to a fixed pivot at the origin.

Coordinates: the absolute angles theta_i of the rods from the downward vertical (not the angles
between neighbours), positive turning about +y as for the swinging rod, so rod i points along
u_i = (-sin theta_i, 0, -cos theta_i). Rod i has length l_i, mass m_i, its centre of mass at l_i/2
along it and moment m_i l_i^2/12 about its centre.

Lagrange's equations in the angles. With S_j = sum_{i >= j} m_i the mass from rod j outwards,

    nu_j    = m_j/2 + S_{j+1}             (rod j's own half plus everything hung below it)
    mu_jk   = nu_max(j,k) for j != k,      mu_jj = m_j/3 + S_{j+1}

the kinetic and potential energies are (chapter: T = 1/2 sum m v^2 + 1/2 I_CoM w^2 for each rod)

    T = 1/2 theta'^T M(theta) theta',     M_jk = mu_jk l_j l_k cos(theta_j - theta_k)
    V = -g sum_j nu_j l_j cos(theta_j)

and the equations of motion are

    sum_k M_jk theta_k'' = -l_j [ sum_k mu_jk l_k sin(theta_j - theta_k) theta_k'^2 + g nu_j sin(theta_j) ],

a small symmetric positive-definite linear system for the accelerations at each evaluation (solved
by Cholesky). There is no closed form for n >= 2 (the motion is chaotic at large amplitude); runs
are checked by the conservation of E = T + V and against a tight reference (method="reference").
For n = 1 it is the chapter's swinging rod. Small oscillations about the hanging pose obey
M0 theta'' = -K theta with M0 = M(0), K = g diag(nu_j l_j): the normal modes (normal_modes()).

The mass matrix depends on the angles, so theta'' depends on theta' and the Hamiltonian is not
separable: the explicit symplectic methods (symplectic_euler, verlet, yoshida6) do not apply;
gauss6 is symplectic for any Hamiltonian.

Native model: the scene's Layout (nested links, one hinge each, the model MuJoCo and pymunk read) runs on the
general engine (rbody.Scene.from_layout, the articulated-body algorithm, cost linear in n). Its hinges measure
each rod's angle from its parent's, so the engine's state is (relative angles, their rates) and the
observables are their cumulative sums. The hand-written chain_rhs above (absolute angles, a dense Cholesky
solve, cost cubic in n) is the engine's oracle in the tests; it would be the fast path for chains of up to
HAND_KERNEL_MAX_LINKS rods, were it more than 1.5x cheaper per step there (it is not: that constant is 0).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any, ClassVar, Sequence

import numpy as np
from numba import njit

from rbody.checks import finite_array, positive, representable, scene_arguments
from rbody.inertia import Inertia
from rbody.layout import Body, Joint, Layout, Shape
from rbody.engine.native import NativeModel
from rbody.poses import observed
from rbody.scene import Scene

# native() runs the hand-written chain_rhs for chains of at most this many rods, the general engine on the
# Layout for longer ones (0: always the engine). With the engine's planar path (rbody.engine.planar) the engine is
# the cheaper at every length measured, so no chain keeps the hand kernel: rk4 ns per step, hand kernel / engine,
# one chain, dt = 1e-3: n = 1: 461 / 227, 2: 663 / 456, 8: 2383 / 1836, 16: 6263 / 3598, 32: 25524 / 7115
# (python benchmarks/fast_paths.py --repeats 5, 2026-11-23, commit a920624, AMD EPYC, 2 cores, idle).
# Before the planar path the hand kernel was > 1.5x cheaper up to 24 rods.
HAND_KERNEL_MAX_LINKS = 0

# params (p,) = (n, g, lengths (n), masses (n), nu (n), mu_diagonal (n)); y = (theta (n), theta' (n))


@njit(cache=True)
def chain_rhs(y, p, out):
    """y' = (theta', theta'') with M(theta) theta'' = f(theta, theta'); y, out (2n,), p as above."""
    n = int(p[0])
    g = p[1]
    lengths = p[2:2 + n]
    nu = p[2 + 2 * n:2 + 3 * n]
    diagonal = p[2 + 3 * n:2 + 4 * n]
    work = np.empty(n * n + 3 * n)
    M = work[:n * n].reshape((n, n))  # lower triangle used, then overwritten by its Cholesky factor
    c = work[n * n:n * n + n]
    s = work[n * n + n:n * n + 2 * n]
    f = work[n * n + 2 * n:]
    for j in range(n):
        c[j] = np.cos(y[j])
        s[j] = np.sin(y[j])
    for j in range(n):
        centripetal = 0.0
        for k in range(n):
            if k == j:
                continue
            mu = nu[max(j, k)]
            if k < j:
                M[j, k] = mu * lengths[j] * lengths[k] * (c[j] * c[k] + s[j] * s[k])  # cos(theta_j - theta_k)
            centripetal += mu * lengths[k] * (s[j] * c[k] - c[j] * s[k]) * y[n + k] * y[n + k]
        M[j, j] = diagonal[j] * lengths[j] * lengths[j]
        f[j] = -lengths[j] * (centripetal + g * nu[j] * s[j])
    # Cholesky M = L L^T in place (lower triangle), then L z = f, L^T theta'' = z.
    for j in range(n):
        d = M[j, j]
        for k in range(j):
            d -= M[j, k] * M[j, k]
        d = np.sqrt(d)
        M[j, j] = d
        for i in range(j + 1, n):
            acc = M[i, j]
            for k in range(j):
                acc -= M[i, k] * M[j, k]
            M[i, j] = acc / d
    for i in range(n):
        acc = f[i]
        for k in range(i):
            acc -= M[i, k] * f[k]
        f[i] = acc / M[i, i]
    for i in range(n - 1, -1, -1):
        acc = f[i]
        for k in range(i + 1, n):
            acc -= M[k, i] * out[n + k]
        out[n + i] = acc / M[i, i]
    for j in range(n):
        out[j] = y[n + j]


# gauss6 first, the default: symplectic and symmetric for this non-separable Hamiltonian. The explicit
# symplectic methods (symplectic_euler, verlet, yoshida6) need q'' = a(q) and do not apply.
CHAIN_METHODS = ("gauss6", "rk4", "euler", "reference")
MAX_LINKS = 32


@dataclass(frozen=True, kw_only=True, eq=False)
class PendulumChain(Scene):
    """n uniform rods hinged end to end, the first to a fixed pivot at the origin.

    lengths: (n,) rod lengths [m]; masses: (n,) rod masses [kg]
    theta0:  (..., n) absolute initial angles from the downward vertical [rad]; leading axes are a batch
    omega0:  (..., n) or scalar, absolute initial angular velocities [rad/s]
    radius_fraction: capsule radius of the drawn/collision shape as a fraction of each length
    """

    lengths: Any
    masses: Any
    theta0: Any
    omega0: Any = 0.0
    radius_fraction: float = 0.01

    observables: ClassVar[tuple[str, ...]] = ("theta", "omega", "energy")
    main_observable: ClassVar[str] = "theta"
    preferred_methods: ClassVar[tuple[str, ...]] = CHAIN_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("theta0", "omega0")

    def __post_init__(self) -> None:
        super().__post_init__()
        lengths = finite_array(self.lengths, "lengths", ndim=1)
        n = lengths.size
        if not 1 <= n <= MAX_LINKS:
            raise ValueError(f"lengths={lengths.tolist()}: a chain needs 1 to {MAX_LINKS} rods, got {n}")
        positive(lengths, "lengths")
        masses = finite_array(self.masses, "masses", ndim=1)
        if masses.shape != (n,):
            raise ValueError(f"masses={masses.tolist()}: expected one mass per rod, {n} of them")
        positive(masses, "masses")
        theta0 = finite_array(self.theta0, "theta0")
        if theta0.ndim == 0 or theta0.shape[-1] != n:
            raise ValueError(f"theta0 has shape {theta0.shape}: expected (..., {n}), one angle per rod")
        omega0 = finite_array(self.omega0, "omega0")
        if omega0.ndim > 0 and omega0.shape[-1] != n:
            raise ValueError(f"omega0 has shape {omega0.shape}: expected a scalar or (..., {n}), one rate per rod")
        try:
            np.broadcast_shapes(theta0.shape, omega0.shape)
        except ValueError:
            raise ValueError(f"theta0 of shape {theta0.shape} and omega0 of shape {omega0.shape} do not "
                             "broadcast to one batch") from None
        radius_fraction = positive(self.radius_fraction, "radius_fraction")
        for name, value in (("lengths", lengths), ("masses", masses), ("theta0", theta0), ("omega0", omega0)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "radius_fraction", float(radius_fraction))

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(np.array_equal(getattr(self, f), getattr(other, f)) for f in
                   ("name", "t_end", "gravity", "lengths", "masses", "theta0", "omega0", "radius_fraction"))

    __hash__ = None  # type: ignore[assignment]

    # ----- batches --------------------------------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of rods."""
        return self.lengths.size

    @cached_property
    def batch_shape(self) -> tuple[int, ...]:
        """theta0's leading axes (broadcast with omega0's)."""
        return tuple(np.broadcast_shapes(self.theta0.shape, self.omega0.shape)[:-1])

    def _state0(self) -> tuple[np.ndarray, np.ndarray]:
        """theta0, omega0 broadcast to (B, n)."""
        shape = self.batch_shape + (self.n,)
        return (np.broadcast_to(self.theta0, shape).reshape(-1, self.n),
                np.broadcast_to(self.omega0, shape).reshape(-1, self.n))

    def item(self, index: int | tuple = ()) -> "PendulumChain":
        """One chain of the batch (index into batch_shape), as an unbatched scene."""
        if not self.batch_shape:
            return self
        shape = self.batch_shape + (self.n,)
        theta0 = np.broadcast_to(self.theta0, shape)[index]
        omega0 = np.broadcast_to(self.omega0, shape)[index]
        if theta0.shape != (self.n,):
            raise ValueError(f"index={index!r} picks {theta0.shape[:-1]} chains from batch {self.batch_shape}: "
                             "expected one")
        return replace(self, theta0=theta0.copy(), omega0=omega0.copy())

    # ----- the mechanics, in numpy ------------------------------------------------------------------

    @cached_property
    def _coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """nu (n,) = m_j/2 + S_{j+1} and the diagonal mu_jj (n,) = m_j/3 + S_{j+1} [kg]."""
        below = np.concatenate([np.cumsum(self.masses[::-1])[::-1][1:], [0.0]])  # S_{j+1}
        return self.masses / 2 + below, self.masses / 3 + below

    def mass_matrix(self, theta: np.ndarray) -> np.ndarray:
        """M (..., n, n) [kg m^2] at absolute angles theta (..., n): T = 1/2 theta'^T M theta'."""
        theta = np.asarray(theta, dtype=np.float64)
        nu, diagonal = self._coefficients
        index = np.arange(self.n)
        mu = nu[np.maximum.outer(index, index)]
        mu[index, index] = diagonal
        cos = np.cos(theta[..., :, None] - theta[..., None, :])
        return mu * np.outer(self.lengths, self.lengths) * cos

    def stiffness(self) -> np.ndarray:
        """K (n, n) [N m]: V = 1/2 theta^T K theta + const for small angles, K = g diag(nu_j l_j)."""
        nu, _ = self._coefficients
        return np.diag(self.gravity * nu * self.lengths)

    def normal_modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Small oscillations about the hanging pose: angular frequencies (n,) ascending [rad/s] and the
        mode shapes (n, n) as columns of absolute angles, from K v = w^2 M0 v (M0 = M(0))."""
        from scipy.linalg import eigh

        squares, shapes = eigh(self.stiffness(), self.mass_matrix(np.zeros(self.n)))
        return np.sqrt(squares), shapes

    def centres_of_mass(self, theta: np.ndarray) -> np.ndarray:
        """(..., n, 3) centres of the rods, world frame [m], at absolute angles theta (..., n)."""
        theta = np.asarray(theta, dtype=np.float64)
        rods = np.stack([-np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=-1) * self.lengths[:, None]
        pivots = np.cumsum(rods, axis=-2) - rods  # pivot of rod i: sum over k < i of l_k u_k
        return pivots + rods / 2

    def energy_of(self, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """E = T + V [J] (...,) from theta, omega (..., n): each rod's 1/2 m v^2 of its centre plus
        1/2 (m l^2/12) w^2 about it, and m g z of its centre."""
        theta, omega = np.asarray(theta, dtype=np.float64), np.asarray(omega, dtype=np.float64)
        # d/dt of l_k u_k = l_k w_k (-cos theta_k, -0, sin theta_k)
        vx, vz = -self.lengths * omega * np.cos(theta), self.lengths * omega * np.sin(theta)
        cx = np.cumsum(vx, axis=-1) - vx / 2
        cz = np.cumsum(vz, axis=-1) - vz / 2
        kinetic = 0.5 * np.sum(self.masses * (cx**2 + cz**2 + self.lengths**2 * omega**2 / 12), axis=-1)
        z = -self.lengths * np.cos(theta)
        height = np.cumsum(z, axis=-1) - z / 2
        return kinetic + self.gravity * np.sum(self.masses * height, axis=-1)

    # ----- native model ------------------------------------------------------------------------------

    def native(self) -> NativeModel:
        """The hand kernel (hand_model) for chains of at most HAND_KERNEL_MAX_LINKS rods, else the general
        engine (engine_model); the same observables either way."""
        model = self.hand_model() if self.n <= HAND_KERNEL_MAX_LINKS else self.engine_model()
        # the stability rate from the Jacobian, also at the hanging rest state (the fastest normal mode)
        return replace(model, rate=None, rate_from_jacobian=True, rest=np.zeros(2 * self.n))

    def engine_model(self) -> NativeModel:
        """The chain on the general engine: the scene's Layout as a TreeScene (rbody.Scene.from_layout), state
        y (B, 2n) = (hinge qpos, hinge qvel): the angles of each rod from its parent and their rates."""
        theta0, omega0 = self._state0()
        tree = Scene.from_layout(self._layout(), t_end=self.t_end, name=self.name, gravity=self.gravity,
                                 qpos0=np.diff(theta0, axis=1, prepend=0.0), qvel0=np.diff(omega0, axis=1, prepend=0.0))
        model = tree.family_native()

        def observe(t, y):
            """Absolute angles and rates: cumulative sums of the relative ones along the chain."""
            data = model.observe(t, y)
            qpos, qvel = data["qpos"], data["qvel"]  # arrays (the rest is lazy)
            theta, omega = np.cumsum(qpos, axis=-1), np.cumsum(qvel, axis=-1)
            return {"theta": theta, "omega": omega, "energy": self.energy_of(theta, omega)}

        return replace(model, observe=observe)

    def hand_model(self) -> NativeModel:
        """The hand-written kernel chain_rhs: y (B, 2n) = (absolute angles, their rates)."""
        theta0, omega0 = self._state0()
        nu, diagonal = self._coefficients
        row = np.concatenate([[self.n, self.gravity], self.lengths, self.masses, nu, diagonal])
        n = self.n

        def observe(t, y):
            theta, omega = y[..., :n], y[..., n:]
            return {"theta": theta, "omega": omega, "energy": self.energy_of(theta, omega)}

        return NativeModel(y0=np.concatenate([theta0, omega0], axis=1), params=np.tile(row, (theta0.shape[0], 1)),
                           rhs=chain_rhs, observe=observe)

    def exact(self, t) -> dict[str, np.ndarray]:
        raise NotImplementedError(
            "a pendulum chain has no closed-form motion: check a run by its energy and against "
            "simulate(scene, dt=..., method='reference') (scipy DOP853 at rtol 1e-13)")

    def why_not(self, method: str) -> str:
        if method in ("symplectic_euler", "verlet", "yoshida6"):
            return (f"{method!r} needs a separable Hamiltonian, theta'' = a(theta); the chain's mass matrix "
                    "M(theta) depends on the angles, so theta'' depends on theta' too (use gauss6, symplectic "
                    "for any Hamiltonian)")
        if method == "splitting":
            return "the chain has no splitting into exactly solvable flows"
        return f"{method!r} is not a pendulum chain method"

    # ----- what other simulators build --------------------------------------------------------------

    def _layout(self) -> Layout:
        theta0, omega0 = self._state0()
        relative = np.diff(theta0[0], prepend=0.0)  # MuJoCo's nested hinges measure from the parent
        relative_rate = np.diff(omega0[0], prepend=0.0)
        bodies, joints = [], []
        for i, (length, mass) in enumerate(zip(self.lengths.tolist(), self.masses.tolist())):
            rod = Inertia.rod(mass, length, "z").translated([0.0, 0.0, -length / 2])
            shape = Shape(f"rod_{i}", "capsule", (self.radius_fraction * length, length / 2),
                          pos=(0.0, 0.0, -length / 2))
            parent = "world" if i == 0 else f"link_{i - 1}"
            pos = (0.0, 0.0, 0.0) if i == 0 else (0.0, 0.0, -float(self.lengths[i - 1]))
            bodies.append(Body(f"link_{i}", rod, shapes=(shape,), parent=parent, pos=pos))
            joints.append(Joint(f"hinge_{i}", "hinge", f"link_{i}", axis=(0.0, 1.0, 0.0),
                                qpos0=float(relative[i]), qvel0=float(relative_rate[i])))
        return Layout(bodies=tuple(bodies), joints=tuple(joints))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        """theta, omega (T, n) as cumulative sums of the hinges' relative (qpos, qvel); energy (T,)."""
        relative = np.stack([np.asarray(joints[f"hinge_{i}"][0], dtype=np.float64) for i in range(self.n)], axis=-1)
        rates = np.stack([np.asarray(joints[f"hinge_{i}"][1], dtype=np.float64) for i in range(self.n)], axis=-1)
        theta, omega = np.cumsum(relative, axis=-1), np.cumsum(rates, axis=-1)
        return {"theta": theta, "omega": omega, "energy": self.energy_of(theta, omega)}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Each hinge turns its rod from its parent's: the differences of the absolute angles theta (T, n)."""
        relative = np.diff(observed(self, trajectory, "theta", (self.n,)), axis=1, prepend=0.0)
        return {f"hinge_{i}": relative[:, i] for i in range(self.n)}

    def describe(self) -> str:
        return (f"{self.name}(n={self.n}, L={self.lengths.tolist()} m, m={self.masses.tolist()} kg, "
                f"theta0={np.asarray(self.theta0).tolist() if self.theta0.size <= 8 else self.theta0.shape})")


def pendulum_chain(links: int | Sequence[float], *, masses: Sequence[float] | None = None, theta0,
                   omega0=0.0, t_end: float, gravity: float = 9.81) -> PendulumChain:
    """n uniform rods hinged end to end in the vertical x-z plane, the first to a pivot at the origin.

    links:   n (n unit rods), or the lengths (n,) [m]; 1 <= n <= 32 (n = 1 is the swinging rod)
    masses:  (n,) [kg], default 1 kg each
    theta0:  (..., n) ABSOLUTE angles of the rods from the downward vertical [rad] (not the angles between
             neighbours; the MuJoCo layout's hinges get the relative ones); leading axes make a batch
    omega0:  scalar or (..., n) absolute angular velocities [rad/s]
    Observables: theta (T, *batch, n), omega (T, *batch, n), energy (T, *batch).
    """
    if isinstance(links, (bool, np.bool_)):
        raise ValueError(f"links={links!r}: expected a number of rods or a sequence of lengths [m]")
    if isinstance(links, (int, np.integer)):
        if links < 1:
            raise ValueError(f"links={links!r}: a chain needs at least one rod")
        lengths = np.ones(int(links))
    else:
        lengths = finite_array(links, "links", ndim=1)
    masses = np.ones(lengths.size) if masses is None else masses
    scene_arguments(gravity, t_end)
    return representable(PendulumChain(name="pendulum_chain", t_end=t_end, gravity=gravity, lengths=lengths, masses=masses,
                         theta0=theta0, omega0=omega0))
