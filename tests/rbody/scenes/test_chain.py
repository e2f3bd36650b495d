"""The pendulum chain (double rod pendulum and longer chains): no closed form for the motion, so it is
checked by its conservation of energy, against a tight reference (DOP853, rtol 1e-13), against the
closed-form normal modes of small oscillation, and against the swinging rod for one link."""

from __future__ import annotations

import numpy as np
import pytest

from rbody import MethodNotApplicable, simulate
from rbody.scenes import pendulum_chain, swinging_rod

G = 9.81


def double_rod_m0_k(l1: float, l2: float, m1: float, m2: float) -> tuple[np.ndarray, np.ndarray]:
    """Linearised double rod pendulum, from T = 1/2 sum (m v_c^2 + m l^2/12 w^2) and V = sum m g z_c:
    M0 = [[(m1/3 + m2) l1^2, m2 l1 l2/2], [m2 l1 l2/2, m2 l2^2/3]], K = g diag((m1/2 + m2) l1, m2 l2/2)."""
    m0 = np.array([[(m1 / 3 + m2) * l1**2, m2 * l1 * l2 / 2], [m2 * l1 * l2 / 2, m2 * l2**2 / 3]])
    k = G * np.diag([(m1 / 2 + m2) * l1, m2 * l2 / 2])
    return m0, k


def double_rod_frequencies(l1: float, l2: float, m1: float, m2: float) -> np.ndarray:
    """Roots of det(K - w^2 M0) = 0: a w^4 - b w^2 + c = 0 (ascending w [rad/s])."""
    m0, k = double_rod_m0_k(l1, l2, m1, m2)
    a = m0[0, 0] * m0[1, 1] - m0[0, 1] ** 2
    b = m0[0, 0] * k[1, 1] + m0[1, 1] * k[0, 0]
    c = k[0, 0] * k[1, 1]
    root = np.sqrt(b * b - 4 * a * c)
    return np.sqrt(np.array([(b - root) / (2 * a), (b + root) / (2 * a)]))


# ----- energy and the reference -------------------------------------------------------------------------


@pytest.mark.parametrize("method, order", [("gauss6", 6), ("rk4", 4)])
def test_double_pendulum_energy_error_falls_with_the_order(method, order):
    """Large-amplitude (chaotic) double pendulum: max |E - E0| over 5 s falls as dt^order."""
    scene = pendulum_chain([1.0, 0.7], masses=[1.0, 2.0], theta0=[1.0, 2.0], omega0=[0.0, -1.0], t_end=5.0)
    dts = (2e-2, 1e-2, 5e-3) if method == "gauss6" else (1e-2, 5e-3, 2.5e-3)
    errors = []
    for dt in dts:
        run = simulate(scene, dt=dt, method=method)
        errors.append(np.max(np.abs(run["energy"] - run["energy"][0])))
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert slope == pytest.approx(order, abs=0.5)
    assert errors[-1] < 1e-6 * abs(scene.energy_of(np.zeros(2), np.zeros(2)))


def test_gauss6_conserves_energy_without_drift():
    """gauss6 is symplectic: over 60 s the energy error stays at the level of the first 6 s."""
    scene = pendulum_chain(2, theta0=[1.0, 2.0], t_end=60.0)
    run = simulate(scene, dt=1e-2, method="gauss6")
    error = np.abs(run["energy"] - run["energy"][0])
    assert error.max() < 1.5 * error[: error.size // 10].max()


def test_gauss6_against_reference():
    """gauss6 at dt = 1e-3 (local error (w dt)^7 ~ 1e-16) and DOP853 at rtol 1e-13 agree over 3 s to a
    few 1e-13 (the reference's own tolerance, grown by the chaotic motion)."""
    scene = pendulum_chain([1.0, 0.7], masses=[1.0, 2.0], theta0=[1.0, 2.0], omega0=[0.0, -1.0], t_end=3.0)
    run = simulate(scene, dt=1e-3, method="gauss6")
    reference = simulate(scene, dt=1e-3, method="reference")
    assert np.max(np.abs(run["theta"] - reference["theta"])) < 2e-12
    assert np.max(np.abs(run["omega"] - reference["omega"])) < 2e-11
    # the reference itself keeps the energy (|E| ~ 30 J) to its tolerance
    assert np.max(np.abs(reference["energy"] - reference["energy"][0])) < 2e-11
    # rk4 at the same dt is visibly less accurate: the check above can fail
    rk4 = simulate(scene, dt=1e-3, method="rk4")
    assert np.max(np.abs(rk4["theta"] - reference["theta"])) > 1e-10


# ----- closed forms -------------------------------------------------------------------------------------


def test_equal_rods_normal_mode_frequencies():
    """Two equal rods (m, l): w^2 = (3 -+ 6/sqrt 7) g / l."""
    scene = pendulum_chain([0.8, 0.8], masses=[1.5, 1.5], theta0=[0.0, 0.0], t_end=1.0)
    frequencies, _shapes = scene.normal_modes()
    expected = np.sqrt((3 + np.array([-1, 1]) * 6 / np.sqrt(7)) * G / 0.8)
    np.testing.assert_allclose(frequencies, expected, rtol=1e-14)
    np.testing.assert_allclose(frequencies, double_rod_frequencies(0.8, 0.8, 1.5, 1.5), rtol=1e-14)


@pytest.mark.parametrize("lengths, masses", [((1.0, 0.5), (2.0, 1.0)), ((0.3, 1.2), (0.5, 3.0))])
def test_unequal_rods_normal_modes(lengths, masses):
    scene = pendulum_chain(lengths, masses=masses, theta0=[0.0, 0.0], t_end=1.0)
    frequencies, shapes = scene.normal_modes()
    np.testing.assert_allclose(frequencies, double_rod_frequencies(*lengths, *masses), rtol=1e-13)
    m0, k = double_rod_m0_k(*lengths, *masses)
    for w, v in zip(frequencies, shapes.T):
        np.testing.assert_allclose(k @ v, w**2 * m0 @ v, rtol=0, atol=1e-12 * np.abs(k).max())


@pytest.mark.parametrize("mode", [0, 1])
def test_small_oscillation_in_a_normal_mode(mode):
    """Released at rest in a normal mode with amplitude eps, the chain swings as eps v cos(w t): the
    nonlinear correction is O(eps^3), a phase error eps^2 w t."""
    lengths, masses, eps = (1.0, 0.5), (2.0, 1.0), 1e-4
    m0, k = double_rod_m0_k(*lengths, *masses)
    w = double_rod_frequencies(*lengths, *masses)[mode]
    v = np.array([m0[0, 1] * w**2, k[0, 0] - w**2 * m0[0, 0]])  # first row of (K - w^2 M0) v = 0
    v /= np.abs(v).max()
    scene = pendulum_chain(lengths, masses=masses, theta0=eps * v, t_end=10.0)
    run = simulate(scene, dt=1e-3, method="gauss6")
    predicted = np.outer(np.cos(w * run.t), v)
    assert np.max(np.abs(run["theta"] / eps - predicted)) < 1e-6


def test_one_link_is_the_swinging_rod():
    chain = pendulum_chain([1.5], masses=[2.0], theta0=[2.0], omega0=[0.5], t_end=5.0)
    rod = swinging_rod(1.5, 2.0, theta0=2.0, omega0=0.5, t_end=5.0)
    run = simulate(chain, dt=1e-3, method="gauss6")
    exact = rod.exact(run.t)
    assert run["theta"].shape == (run.t.size, 1)
    assert np.max(np.abs(run["theta"][:, 0] - exact["theta"])) < 1e-13
    assert np.max(np.abs(run["omega"][:, 0] - exact["omega"])) < 1e-12
    np.testing.assert_allclose(run["energy"], exact["energy"], rtol=0, atol=1e-12)
    assert chain.normal_modes()[0][0] == pytest.approx(np.sqrt(1.5 * G / 1.5), rel=1e-15)


def test_mass_matrix_of_two_rods_and_kinetic_energy():
    """M(theta) against the double-rod closed form, and 1/2 w^T M w against the sum over the rods of
    1/2 m v_c^2 + 1/2 (m l^2/12) w^2 (energy_of, computed from the velocities of the centres)."""
    l1, l2, m1, m2 = 1.0, 0.6, 1.2, 0.8
    scene = pendulum_chain([l1, l2], masses=[m1, m2], theta0=[0.0, 0.0], t_end=1.0)
    theta = np.array([0.4, -1.1])
    c = np.cos(theta[0] - theta[1])
    expected = np.array([[(m1 / 3 + m2) * l1**2, m2 * l1 * l2 / 2 * c], [m2 * l1 * l2 / 2 * c, m2 * l2**2 / 3]])
    np.testing.assert_allclose(scene.mass_matrix(theta), expected, rtol=1e-15)
    rng = np.random.default_rng(7)
    chain = pendulum_chain([1.0, 2.0, 0.5, 1.2], masses=[1.0, 3.0, 2.0, 0.5], theta0=np.zeros(4), t_end=1.0)
    theta, omega = rng.normal(size=(5, 4)), rng.normal(size=(5, 4))
    kinetic = chain.energy_of(theta, omega) - chain.energy_of(theta, np.zeros_like(omega))
    quadratic = 0.5 * np.einsum("bi,bij,bj->b", omega, chain.mass_matrix(theta), omega)
    np.testing.assert_allclose(kinetic, quadratic, rtol=1e-13)
    # hanging straight down at rest: V = -g sum_j m_j (depth of its centre)
    depth = np.array([0.5, 1.0 + 1.0, 3.0 + 0.25, 3.5 + 0.6])
    assert chain.energy_of(np.zeros(4), np.zeros(4)) == pytest.approx(-G * np.dot([1.0, 3.0, 2.0, 0.5], depth))


def test_longer_chain_conserves_energy():
    scene = pendulum_chain(8, theta0=np.linspace(0.2, 1.6, 8), t_end=2.0)
    run = simulate(scene, dt=1e-3, method="gauss6")
    assert np.max(np.abs(run["energy"] - run["energy"][0])) < 1e-11  # |E| ~ 200 J
    assert np.all(np.isfinite(run["theta"]))


def test_longest_chain_with_gauss6():
    """32 rods: the mass matrix solve is ill-conditioned (cond ~ 5e3 after 0.1 s), so gauss6's stage
    iteration bottoms out at a round-off far above 1e-16 and must still be accepted as converged."""
    scene = pendulum_chain(32, theta0=np.linspace(0.2, 1.0, 32), t_end=0.2)
    run = simulate(scene, dt=1e-3, method="gauss6")
    assert np.max(np.abs(run["energy"] - run["energy"][0])) < 1e-14 * abs(run["energy"][0])


# ----- batches, layout, observe -------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["euler", "rk4", "gauss6"])
def test_batch_equals_single_runs(method):
    theta0 = np.array([[[0.1, 0.2], [1.0, 2.0], [3.0, -1.0]], [[0.0, 0.5], [2.0, 2.0], [-0.3, 0.3]]])
    omega0 = np.array([0.5, -1.0])
    batch_scene = pendulum_chain([1.0, 0.5], masses=[1.0, 2.0], theta0=theta0, omega0=omega0, t_end=1.0)
    assert batch_scene.batch_shape == (2, 3)
    batch = simulate(batch_scene, dt=1e-2, method=method)
    assert batch["theta"].shape == (101, 2, 3, 2)
    assert batch["energy"].shape == (101, 2, 3)
    for index in np.ndindex(2, 3):
        single_scene = pendulum_chain([1.0, 0.5], masses=[1.0, 2.0], theta0=theta0[index], omega0=omega0, t_end=1.0)
        assert batch_scene.item(index) == single_scene
        single = simulate(single_scene, dt=1e-2, method=method)
        for name in ("theta", "omega", "energy"):
            np.testing.assert_array_equal(batch[name][(slice(None),) + index], single[name])


def test_layout_nests_the_links_with_relative_hinge_angles():
    scene = pendulum_chain([1.0, 0.5, 0.25], masses=[1.0, 2.0, 3.0], theta0=[0.3, 0.5, -0.2],
                           omega0=[1.0, 0.0, 2.0], t_end=1.0)
    layout = scene.layout
    assert [b.name for b in layout.bodies] == ["link_0", "link_1", "link_2"]
    assert [b.parent for b in layout.bodies] == ["world", "link_0", "link_1"]
    assert [b.pos for b in layout.bodies] == [(0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 0.0, -0.5)]
    for body, (length, mass) in zip(layout.bodies, [(1.0, 1.0), (0.5, 2.0), (0.25, 3.0)]):
        assert body.inertia.mass == mass
        np.testing.assert_array_equal(body.inertia.com, [0.0, 0.0, -length / 2])
        np.testing.assert_allclose(np.diag(body.inertia.tensor), [mass * length**2 / 12] * 2 + [0.0], rtol=1e-15)
        (shape,) = body.shapes
        assert shape.kind == "capsule" and shape.size == pytest.approx((0.01 * length, length / 2))
    np.testing.assert_allclose([j.qpos0 for j in layout.joints], [0.3, 0.2, -0.7], rtol=1e-15)
    np.testing.assert_allclose([j.qvel0 for j in layout.joints], [1.0, -1.0, 2.0], rtol=1e-15)
    assert all(j.kind == "hinge" and j.axis == (0.0, 1.0, 0.0) for j in layout.joints)


def test_observe_sums_the_relative_angles():
    scene = pendulum_chain([1.0, 0.5], masses=[1.0, 2.0], theta0=[0.3, 1.0], t_end=1.0)
    run = simulate(scene, dt=1e-2, method="rk4")
    relative, rates = np.diff(run["theta"], axis=1, prepend=0.0), np.diff(run["omega"], axis=1, prepend=0.0)
    joints = {f"hinge_{i}": (relative[:, i], rates[:, i]) for i in range(2)}
    observed = scene.observe(run.t, {}, joints)
    np.testing.assert_allclose(observed["theta"], run["theta"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(observed["omega"], run["omega"], rtol=0, atol=1e-14)
    np.testing.assert_allclose(observed["energy"], run["energy"], rtol=0, atol=1e-13)


def test_centres_of_mass_of_the_hanging_and_bent_chain():
    scene = pendulum_chain([1.0, 0.5], masses=[1.0, 1.0], theta0=[0.0, 0.0], t_end=1.0)
    np.testing.assert_allclose(scene.centres_of_mass([0.0, 0.0]), [[0, 0, -0.5], [0, 0, -1.25]], rtol=0, atol=1e-15)
    # theta = +pi/2 turns about +y: the rod points along -x
    np.testing.assert_allclose(scene.centres_of_mass([np.pi / 2, 0.0]), [[-0.5, 0, 0], [-1.0, 0, -0.25]],
                               rtol=0, atol=1e-15)


# ----- methods and bad input ----------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["verlet", "symplectic_euler", "yoshida6", "splitting"])
def test_explicit_symplectic_methods_do_not_apply(method):
    scene = pendulum_chain(2, theta0=[1.0, 2.0], t_end=1.0)
    with pytest.raises(MethodNotApplicable, match="gauss6"):
        simulate(scene, dt=1e-2, method=method)


def test_default_method_is_gauss6():
    run = simulate(pendulum_chain(2, theta0=[1.0, 2.0], t_end=0.1), dt=1e-2)
    assert run.meta["method"] == "gauss6"


def test_no_closed_form():
    with pytest.raises(NotImplementedError, match="reference"):
        pendulum_chain(2, theta0=[1.0, 2.0], t_end=1.0).exact([0.0])


@pytest.mark.parametrize("links, kwargs, words", [
    ([1.0, 0.0], {}, "lengths"),
    ([1.0, -1.0], {}, "lengths"),
    ([1.0, np.nan], {}, "links"),
    ([1.0, 1.0], dict(masses=[1.0, -1.0]), "masses"),
    ([1.0, 1.0], dict(masses=[1.0, 0.0]), "masses"),
    ([1.0, 1.0], dict(masses=[1.0]), "masses"),
    ([1.0, 1.0], dict(theta0=[0.1, 0.2, 0.3]), "theta0"),
    ([1.0, 1.0], dict(theta0=0.1), "theta0"),
    ([1.0, 1.0], dict(theta0=[0.1, np.nan]), "theta0"),
    ([1.0, 1.0], dict(omega0=[1.0, 2.0, 3.0]), "omega0"),
    ([1.0, 1.0], dict(theta0=np.zeros((3, 2)), omega0=np.zeros((2, 2))), "broadcast"),
    (0, {}, "at least one"),
    ([], {}, "1 to 32"),
    (33, {}, "1 to 32"),
    (True, {}, "links"),
    ("two", {}, "links"),
])
def test_bad_input(links, kwargs, words):
    arguments = dict(theta0=[0.1, 0.2], t_end=1.0) | kwargs
    with pytest.raises(ValueError, match=words):
        pendulum_chain(links, **arguments)
