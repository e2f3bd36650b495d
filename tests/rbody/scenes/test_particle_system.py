"""The chapter's conservation laws for N particles with pair forces (section 5.1).

With F_ij = -F_ji and no external force: P is conserved (5.1); dL/dt = sum_{i<j} (x_i - x_j) x F_ij,
zero when F_ij is along x_i - x_j (5.2); E = T + sum V_ij(|x_i - x_j|) is conserved for forces from a
potential. Non-central pair forces change L, by the torque above.
"""

from __future__ import annotations

import numpy as np
import pytest

import rbody
from rbody.scenes import particles
from rbody.engine import integrators
from rbody.scenes.particles import pair_forces

EPS = np.finfo(float).eps


def _states(scene, dt, steps):
    """(steps + 1, 6n) states of the native rk4 run (what simulate integrates before observing)."""
    model = scene.native()
    out = np.empty((steps + 1, 1, model.y0.shape[1]))
    failed = integrators.run_rk4(model.rhs, model.y0, model.params, dt, steps, 1, out)
    assert failed[0] == -1
    return out[:, 0]


# ----- momentum ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("forces", ["central", "noncentral"])
@pytest.mark.parametrize("method", ["euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6"])
def test_momentum_is_conserved_to_round_off_whatever_dt(method, forces):
    """Each F_ij is formed once, added to i and subtracted from j: sum_i F_i = 0 up to the round-off of
    the accumulation, so P changes by at most ~ n eps sum m|v| per step, at coarse and fine dt alike."""
    scene = particles(10, seed=3, forces=forces, t_end=1.0)
    masses = scene.initial.masses
    for dt in (0.05, 0.01):
        run = rbody.simulate(scene, dt=dt, method=method)
        P = run["momentum"]
        speed_scale = np.max(np.abs(P)) + np.sum(masses * np.linalg.norm(scene.initial.velocities, axis=1))
        bound = run.t.size * scene.n * EPS * speed_scale
        assert np.max(np.abs(P - P[0])) <= bound
        np.testing.assert_allclose(P[0], masses @ scene.initial.velocities, rtol=1e-15)


def test_a_thousand_particles_keep_momentum_and_angular_momentum():
    scene = particles(1000, seed=7, t_end=0.01)
    run = rbody.simulate(scene, dt=1e-3, method="verlet")
    P, L = run["momentum"], run["angular_momentum"]
    start = scene.initial
    scale = np.sum(start.masses * np.linalg.norm(start.velocities, axis=1))
    steps = run.t.size
    assert np.max(np.abs(P - P[0])) <= steps * 10 * EPS * scale
    assert np.max(np.abs(L - L[0])) <= steps * 10 * EPS * scale   # |x| <= sqrt(3)/2 m at the start
    np.testing.assert_allclose(L[0], start.angular_momentum(), rtol=1e-14)


# ----- angular momentum -----------------------------------------------------------------------------------

@pytest.mark.parametrize("method", ["verlet", "gauss6"])
def test_central_forces_keep_angular_momentum_with_symplectic_methods(method):
    """Verlet: a kick changes L by h/2 sum (x_i - x_j) x F_ij = 0, a drift by h sum m v x v = 0; gauss6
    keeps every quadratic invariant. Both to round-off, at coarse dt."""
    scene = particles(10, seed=5, t_end=2.0)
    run = rbody.simulate(scene, dt=0.02, method=method)
    L = run["angular_momentum"]
    scale = np.sum(scene.initial.masses * np.linalg.norm(scene.initial.velocities, axis=1))
    assert np.max(np.abs(L - L[0])) <= run.t.size * 10 * EPS * scale


def test_rk4_changes_angular_momentum_within_its_order():
    """rk4 keeps linear invariants (P) but not quadratic ones: L drifts, far above round-off, and the
    drift falls at least as fast as dt^4 (here about 2^5 per halving)."""
    scene = particles(10, seed=5, t_end=2.0)
    scale = np.sum(scene.initial.masses * np.linalg.norm(scene.initial.velocities, axis=1))

    def drift(dt):
        L = rbody.simulate(scene, dt=dt, method="rk4")["angular_momentum"]
        return np.max(np.abs(L - L[0]))

    coarse, fine = drift(0.01), drift(0.005)
    assert fine > 1e6 * EPS * scale
    assert coarse / fine > 16 * 0.9


def test_central_torque_vanishes():
    scene = particles(20, seed=2, t_end=1.0)
    torque = scene.internal_torque(scene.initial.positions[None])
    forces = np.empty(3 * scene.n)
    pair_forces(scene.initial.positions.ravel(), scene.params(), forces)
    assert np.max(np.abs(torque)) <= 100 * EPS * np.sum(np.abs(forces))


# ----- energy ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("method, order, dt", [("verlet", 2, 0.01), ("rk4", 4, 0.01), ("yoshida6", 6, 0.01),
                                               ("gauss6", 6, 0.02)])
def test_energy_is_conserved_to_the_methods_order(method, order, dt):
    scene = particles(10, seed=1, t_end=2.0)
    exact = scene.exact([0.0])["energy"][0]

    def error(step):
        run = rbody.simulate(scene, dt=step, method=method)
        assert run["energy"][0] == pytest.approx(exact, rel=1e-15)
        return np.max(np.abs(run["energy"] - exact))

    ratio = error(dt) / error(dt / 2)
    assert 2**order * 0.6 < ratio < 2**order * 1.6


def test_energy_is_kinetic_plus_pair_potential():
    scene = particles(4, seed=9, t_end=1.0)
    start = scene.initial
    x, m = start.positions, start.masses
    potential = sum(-m[i] * m[j] / np.sqrt(np.sum((x[i] - x[j]) ** 2) + 0.1**2)
                    for i in range(4) for j in range(i + 1, 4))
    assert scene.exact([0.0])["energy"][0] == pytest.approx(start.kinetic_energy + potential, rel=1e-14)


# ----- non-central forces -------------------------------------------------------------------------------------

def test_noncentral_forces_change_angular_momentum_by_the_torque():
    """dL/dt = sum_{i<j} (x_i - x_j) x F_ij: the central difference of L (rk4 at dt = 1e-3, so the
    method's error ~1e-12 and the difference's ~ dt^2 |L'''| ~ 1e-6 of L') against the torque."""
    scene = particles(10, seed=4, forces="noncentral", t_end=1.0)
    dt = 1e-3
    run = rbody.simulate(scene, dt=dt, method="rk4")
    L = run["angular_momentum"]
    n = scene.n
    positions = _states(scene, dt, run.t.size - 1)[:, :3 * n].reshape(-1, n, 3)
    torque = scene.internal_torque(positions)
    rate = (L[2:] - L[:-2]) / (2 * dt)
    # the central difference is off by dt^2 L'''/6; L''' from the third differences of L itself
    third = np.max(np.abs(np.diff(L, 3, axis=0))) / dt**3
    np.testing.assert_allclose(rate, torque[1:-1], rtol=0, atol=1.5 * dt**2 * third / 6 + 1e-9)
    # e_z x d forces turn L_z up: the torque's z component is sum c (d_x^2 + d_y^2) > 0
    assert np.all(torque[:, 2] > 0) and np.all(np.diff(L[:, 2]) > 0)
    assert L[-1, 2] - L[0, 2] > 0.1 * np.abs(L[0]).max()
    # and the total: L(t) - L(0) = integral of the torque (Simpson's rule, error ~ dt^4)
    change = (dt / 3) * (torque[0] + 4 * torque[1:-1:2].sum(axis=0) + 2 * torque[2:-1:2].sum(axis=0) + torque[-1])
    np.testing.assert_allclose(L[-1] - L[0], change, rtol=0, atol=1e-9 * np.abs(change).max())


def test_noncentral_forces_change_the_kinetic_energy_by_their_power():
    """No potential exists: 'energy' is the kinetic energy, and dT/dt = sum_i F_i . v_i."""
    scene = particles(10, seed=4, forces="noncentral", t_end=0.5)
    dt = 1e-3
    run = rbody.simulate(scene, dt=dt, method="rk4")
    T = run["energy"]
    states = _states(scene, dt, run.t.size - 1)
    power = np.empty(run.t.size)
    forces = np.empty(3 * scene.n)
    for s, state in enumerate(states):
        pair_forces(np.ascontiguousarray(state[:3 * scene.n]), scene.params(), forces)
        power[s] = forces @ state[3 * scene.n:]
    rate = (T[2:] - T[:-2]) / (2 * dt)
    # the central difference is off by dt^2 T'''/6; T''' from the third differences of T itself
    third = np.max(np.abs(np.diff(T, 3))) / dt**3
    np.testing.assert_allclose(rate, power[1:-1], rtol=0, atol=1.5 * dt**2 * third / 6 + 1e-9)
    assert np.max(np.abs(T - T[0])) > 1e-3 * T[0]  # the energy does change
    np.testing.assert_allclose(T[0], scene.initial.kinetic_energy, rtol=1e-15)


def test_exact_gives_only_what_is_conserved():
    central = particles(5, seed=0, t_end=1.0).exact([0.0, 1.0])
    assert set(central) == {"momentum", "angular_momentum", "energy"}
    assert central["momentum"].shape == (2, 3) and central["energy"].shape == (2,)
    noncentral = particles(5, seed=0, forces="noncentral", t_end=1.0).exact([0.0, 1.0])
    assert set(noncentral) == {"momentum"}


# ----- the random start --------------------------------------------------------------------------------

def test_start_is_drawn_from_the_seed():
    a, b, c = (particles(6, seed=s, t_end=1.0).initial for s in (11, 11, 12))
    np.testing.assert_array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    assert np.all((a.masses >= 0.5 / 6) & (a.masses <= 1.5 / 6))
    assert np.all(np.abs(a.positions) <= 0.5)


# ----- bad input and what is not provided --------------------------------------------------------------------

@pytest.mark.parametrize("changes, words", [
    (dict(forces="magnetic"), "forces"),
    (dict(n=1), "at least 2"),
    (dict(n=2.5), "whole number"),
    (dict(n=True), "whole number"),
    (dict(seed=-1), "seed"),
    (dict(strength=0.0), "strength"),
    (dict(softening=np.nan), "finite"),
    (dict(softening=-0.1), "softening"),
    (dict(t_end=-1.0), "t_end"),
])
def test_bad_input(changes, words):
    args = dict(n=4, seed=0, t_end=1.0)
    args.update(changes)
    with pytest.raises(ValueError, match=words):
        particles(args.pop("n"), **args)


def test_no_layout_for_other_simulators():
    scene = particles(3, seed=0, t_end=1.0)
    with pytest.raises(NotImplementedError, match="pair forces between free points"):
        scene.layout  # noqa: B018
