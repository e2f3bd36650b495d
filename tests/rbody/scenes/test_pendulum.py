"""The swinging rod and the compound pendulum (the chapter, section 5: E = 1/2 I theta'^2 - M g (L/2) cos theta,
equivalent simple pendulum l = 2I/(L M) = 2L/3), against their exact elliptic-function solution.

The exact solution itself is checked against what it must satisfy (energy, the period, the
small-angle limit, scipy's ellipk) and against an independent tight integration (DOP853, rtol 1e-13)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ellipk

import rbody
from rbody import Inertia, simulate
from rbody.scenes import compound_pendulum, swinging_rod

G = 9.81
THETA0S = (0.1, 1.0, 2.5, 3.1)


def rod_w0(length: float) -> float:
    """w0 = sqrt(M g (L/2) / (M L^2/3)) = sqrt(3 g / 2L) [rad/s]."""
    return np.sqrt(1.5 * G / length)


def linger(theta0: float) -> float:
    """1/cos(theta0/2) = (1 - k^2)^(-1/2) from rest: how much longer than at small amplitude the motion
    stays near the top, where errors in the state grow (50 at theta0 = 3.1)."""
    return 1.0 / np.cos(theta0 / 2)


def closed_period(theta0: float, w0: float) -> float:
    """4 K(sin^2(theta0/2)) / w0 [s], released from rest (scipy's ellipk, not the scene's code path)."""
    return 4 * ellipk(np.sin(theta0 / 2) ** 2) / w0


# ----- the exact solution -----------------------------------------------------------------------------


@pytest.mark.parametrize("theta0", THETA0S)
def test_period_is_the_complete_elliptic_integral(theta0):
    scene = swinging_rod(0.8, theta0=theta0, t_end=1.0)
    assert scene.period == pytest.approx(closed_period(theta0, rod_w0(0.8)), rel=1e-14)


def test_small_amplitude_period_series():
    # T = 2 pi / w0 (1 + theta0^2/16 + 11 theta0^4/3072 + ...): the next term is O(theta0^6)
    theta0 = 0.05
    scene = swinging_rod(1.0, theta0=theta0, t_end=1.0)
    series = 2 * np.pi / rod_w0(1.0) * (1 + theta0**2 / 16 + 11 * theta0**4 / 3072)
    assert scene.period == pytest.approx(series, rel=1e-9)
    at_rest = swinging_rod(1.0, theta0=0.0, t_end=1.0)
    assert at_rest.period == pytest.approx(2 * np.pi / rod_w0(1.0), rel=1e-15)


@pytest.mark.parametrize("theta0, omega0", [(0.1, 0.0), (1.0, 0.0), (2.5, 0.0), (3.1, 0.0), (1.0, -3.0),
                                            (1.0, 12.0), (-5.0, -12.0), (2.0 * np.pi + 0.5, 1.0)])
def test_exact_conserves_energy_and_starts_at_the_initial_state(theta0, omega0):
    scene = swinging_rod(1.0, theta0=theta0, omega0=omega0, t_end=1.0)
    t = np.linspace(0.0, 20.0, 4001)
    exact = scene.exact(t)
    energy = scene.energy_of(exact["theta"], exact["omega"])
    scale = scene.energy_of(0.0, 0.0)  # -M g d: the energy scale
    assert np.max(np.abs(energy - energy[0])) < 1e-13 * abs(scale)
    assert exact["theta"][0] == pytest.approx(theta0, abs=1e-14)
    assert exact["omega"][0] == pytest.approx(omega0, abs=1e-13)


@pytest.mark.parametrize("theta0, omega0", [(1.0, 0.0), (3.1, 0.0), (1.0, 3.0), (1.0, 12.0), (-5.0, -12.0)])
def test_exact_returns_after_one_period(theta0, omega0):
    """Swinging: back to (theta0, omega0); whirling: one more turn, theta0 +- 2 pi."""
    scene = swinging_rod(1.0, theta0=theta0, omega0=omega0, t_end=1.0)
    exact = scene.exact([scene.period])
    turn = 0.0 if scene.modulus < 1 else 2 * np.pi * np.sign(omega0)
    # theta0 = 3.1: 1 - k^2 = 4e-4, so an error eps in the time of the return moves theta by eps w0 t.
    assert exact["theta"][0] == pytest.approx(theta0 + turn, abs=1e-13 * scene.period * rod_w0(1.0) * 10)
    assert exact["omega"][0] == pytest.approx(omega0, abs=1e-12 * rod_w0(1.0) * 10)


@pytest.mark.parametrize("theta0, omega0", [(0.1, 0.0), (1.0, 0.0), (2.5, 0.0), (3.1, 0.0), (1.0, -3.0),
                                            (1.0, 12.0), (-5.0, -12.0)])
def test_exact_against_tight_reference(theta0, omega0):
    """The closed form against scipy's DOP853 at rtol 1e-13 over several periods or turns. The reference
    holds a relative error of a few 1e-13 over the run, amplified by how long the motion lingers near
    the top, (1 - k^2)^(-1/2) = 1/cos(theta0/2) from rest (50 at theta0 = 3.1), once on the way up and
    once on the way down."""
    scene = swinging_rod(1.0, theta0=theta0, omega0=omega0, t_end=6.0)
    reference = simulate(scene, dt=0.01, method="reference")
    exact = scene.exact(reference.t)
    twice = max(1.0 / abs(1 - scene.modulus), 1.0)  # the amplification, up and down: 1/|1 - k^2|
    size = 1 + np.max(np.abs(exact["theta"]))
    assert np.max(np.abs(reference["theta"] - exact["theta"])) < 5e-13 * size * twice
    assert np.max(np.abs(reference["omega"] - exact["omega"])) < 5e-13 * size * twice * np.max(np.abs(exact["omega"]))


def test_separatrix_and_near_top():
    """k = 1 exactly (theta0 = 0, omega0 = 2 w0 in floats) and k^2 = 1 - 2.5e-7: both still finite and
    against the reference over the first approach to the top, where the reference is well conditioned."""
    length = 0.7  # gives 1 - k^2 == 0.0 exactly for theta0 = 1 below
    w0 = rod_w0(length)
    scene = swinging_rod(length, theta0=1.0, omega0=2 * w0 * np.cos(0.5), t_end=2.0)
    assert scene.period == np.inf
    reference = simulate(scene, dt=0.01, method="reference")
    exact = scene.exact(reference.t)
    assert np.max(np.abs(reference["theta"] - exact["theta"])) < 1e-11
    assert exact["theta"][-1] < np.pi  # creeps up towards the top, never over it

    near = swinging_rod(1.0, theta0=np.pi - 1e-3, t_end=1.0)
    quarter = near.period / 4
    near = swinging_rod(1.0, theta0=np.pi - 1e-3, t_end=quarter)
    reference = simulate(near, dt=quarter / 500, method="reference")
    exact = near.exact(reference.t)
    assert np.max(np.abs(reference["theta"] - exact["theta"])) < 2e-12
    assert exact["theta"][-1] == pytest.approx(0.0, abs=1e-12)  # at the bottom after a quarter period
    assert near.exact([near.period * 4])["theta"][0] == pytest.approx(np.pi - 1e-3, abs=1e-12)


@pytest.mark.parametrize("gap", [1e-2, 1e-6])
def test_exact_near_the_top_against_mpmath(gap):
    """Released at rest pi - gap below the top: the closed form at 60 digits (mpmath's sn, cn, dn) against
    rbody's double-precision one. A phase error of eps in u moves theta by ~eps/gap where the motion
    creeps past the top, so 1e-15/gap is as close as any double-precision evaluation can come."""
    mp = pytest.importorskip("mpmath")
    with mp.workdps(60):
        theta0 = float(mp.pi - mp.mpf(gap))
        scene = swinging_rod(1.0, theta0=theta0, t_end=1.0)
        t = np.linspace(0.0, scene.period, 21)
        exact = scene.exact(t)
        w0 = mp.sqrt(mp.mpf(1.5) * mp.mpf(G))
        k = mp.sin(mp.mpf(theta0) / 2)
        quarter = mp.ellipk(k**2)
        for i, time in enumerate(t):
            u = w0 * mp.mpf(time) + quarter  # starts at the turning point, u0 = K
            sn, cn, dn = (mp.ellipfun(name, u, m=k**2) for name in ("sn", "cn", "dn"))
            assert abs(float(2 * mp.atan2(k * sn, dn)) - exact["theta"][i]) < 1e-15 / gap
            assert abs(float(2 * k * w0 * cn) - exact["omega"][i]) < 1e-15 / gap * float(w0)


# ----- simulated against exact --------------------------------------------------------------------------


@pytest.mark.parametrize("theta0", THETA0S)
def test_swinging_rod_against_exact(theta0):
    scene = swinging_rod(1.0, 2.0, theta0=theta0, t_end=5.0)
    run = simulate(scene, dt=1e-3, method="gauss6")
    exact = scene.exact(run.t)
    # gauss6 at dt = 1e-3: truncation (w0 dt)^7 ~ 1e-17 per step, so round-off over 5000 steps,
    # amplified by the time spent near the top, 1/cos(theta0/2)
    assert np.max(np.abs(run["theta"] - exact["theta"])) < 1e-13 * linger(theta0)
    assert np.max(np.abs(run["omega"] - exact["omega"])) < 1e-13 * linger(theta0) * rod_w0(1.0)


def test_whirling_rod_against_exact():
    scene = swinging_rod(1.0, theta0=0.3, omega0=10.0, t_end=5.0)
    assert scene.modulus > 1
    run = simulate(scene, dt=1e-3, method="gauss6")
    exact = scene.exact(run.t)
    assert run["theta"][-1] > 6 * np.pi  # several full turns
    assert np.max(np.abs(run["theta"] - exact["theta"])) < 1e-12
    assert np.max(np.abs(run["omega"] - exact["omega"])) < 2e-12


@pytest.mark.parametrize("theta0", THETA0S)
def test_returns_to_theta0_after_one_period(theta0):
    period = swinging_rod(1.0, theta0=theta0, t_end=1.0).period
    scene = swinging_rod(1.0, theta0=theta0, t_end=period)
    run = simulate(scene, dt=period / 4000, method="gauss6")
    assert run.t[-1] == pytest.approx(period, rel=1e-14)
    assert run["theta"][-1] == pytest.approx(theta0, abs=1e-13 * linger(theta0))
    assert run["omega"][-1] == pytest.approx(0.0, abs=1e-13 * linger(theta0) * rod_w0(1.0))
    # and at half a period it is at the other side, at rest
    half = np.argmin(np.abs(run.t - period / 2))
    assert run["theta"][half] == pytest.approx(-theta0, abs=1e-13 * linger(theta0))


def test_equivalent_length_of_the_rod():
    """The chapter: the rod moves as a simple pendulum of length l = 2I/(L M) = 2L/3."""
    length, mass = 1.2, 0.7
    rod = swinging_rod(length, mass, theta0=2.0, t_end=3.0)
    assert rod.equivalent_length == pytest.approx(2 * length / 3, rel=1e-15)
    bob = Inertia.point_masses([mass], [[0.0, 0.0, -2 * length / 3]])
    simple = compound_pendulum(bob, pivot=(0.0, 0.0, 0.0), theta0=2.0, t_end=3.0)
    t = np.linspace(0.0, 3.0, 301)
    np.testing.assert_allclose(rod.exact(t)["theta"], simple.exact(t)["theta"], rtol=0, atol=1e-13)
    run_rod = simulate(rod, dt=1e-3, method="rk4")
    run_simple = simulate(simple, dt=1e-3, method="rk4")
    np.testing.assert_allclose(run_rod["theta"], run_simple["theta"], rtol=0, atol=1e-13)


def test_disc_pivoted_at_its_rim():
    """A disc of radius a hung from a point of its rim: I = M a^2/2 + M a^2 = 3/2 M a^2, d = a,
    so w0^2 = g/(3a/2)."""
    mass, radius, theta0 = 2.5, 0.3, 1.0
    disc = Inertia.disc(mass, radius, axis="y")  # swings in its own plane
    pivot = (0.0, 0.0, radius)
    assert disc.moment("y", through=pivot) == pytest.approx(1.5 * mass * radius**2, rel=1e-15)
    scene = compound_pendulum(disc, pivot=pivot, axis="y", theta0=theta0, t_end=4.0)
    assert scene.equivalent_length == pytest.approx(1.5 * radius, rel=1e-15)
    w0 = np.sqrt(G / (1.5 * radius))
    assert scene.period == pytest.approx(closed_period(theta0, w0), rel=1e-14)
    run = simulate(scene, dt=1e-3, method="gauss6")
    exact = scene.exact(run.t)
    assert np.max(np.abs(run["theta"] - exact["theta"])) < 1e-13
    assert np.max(np.abs(run["omega"] - exact["omega"])) < 1e-13 * w0


@pytest.mark.parametrize("theta0", THETA0S)
def test_compound_pendulum_against_exact(theta0):
    """A box hung from a corner-side point off both symmetry planes: only d and I about the axis matter."""
    box = Inertia.box(1.5, (0.2, 0.1, 0.6))
    pivot = (0.05, 0.0, 0.25)
    scene = compound_pendulum(box, pivot=pivot, axis="y", theta0=theta0, t_end=3.0)
    d = np.hypot(0.05, 0.25)
    moment = 1.5 * (0.2**2 + 0.6**2) / 12 + 1.5 * d**2
    w0 = np.sqrt(1.5 * G * d / moment)
    assert scene.period == pytest.approx(closed_period(theta0, w0), rel=1e-14)
    run = simulate(scene, dt=1e-3, method="gauss6")
    exact = scene.exact(run.t)
    assert np.max(np.abs(run["theta"] - exact["theta"])) < 1e-13 * linger(theta0)


# ----- the methods ---------------------------------------------------------------------------------------

ORDER_SWEEPS = {  # dt halved three times, errors well above round-off and in the asymptotic range
    "euler": (1e-3, 5e-4, 2.5e-4, 1.25e-4),
    "symplectic_euler": (1e-3, 5e-4, 2.5e-4, 1.25e-4),
    "verlet": (1e-2, 5e-3, 2.5e-3, 1.25e-3),
    "rk4": (2e-2, 1e-2, 5e-3, 2.5e-3),
    "yoshida6": (0.1, 0.05, 0.025, 0.0125),
    "gauss6": (0.2, 0.1, 0.05, 0.025),
}


@pytest.mark.parametrize("method", sorted(ORDER_SWEEPS))
def test_observed_order_of_accuracy(method):
    scene = swinging_rod(1.0, theta0=1.0, t_end=2.0)
    exact_end = scene.exact([2.0])["theta"][0]
    errors = []
    for dt in ORDER_SWEEPS[method]:
        run = simulate(scene, dt=dt, method=method)
        assert run.t[-1] == pytest.approx(2.0, rel=1e-13)
        errors.append(abs(run["theta"][-1] - exact_end))
    slope = np.polyfit(np.log(ORDER_SWEEPS[method]), np.log(errors), 1)[0]
    assert slope == pytest.approx(rbody.METHOD_ORDER[method], abs=0.3)


def test_symplectic_methods_keep_energy_bounded_euler_grows_it():
    scene = swinging_rod(1.0, theta0=1.0, t_end=200.0)  # ~115 periods
    periods = 200.0 / scene.period
    e0 = scene.energy_of(1.0, 0.0)
    for method in ("symplectic_euler", "verlet", "yoshida6", "gauss6"):
        run = simulate(scene, dt=1e-2 if method != "symplectic_euler" else 1e-3, method=method, save_every=1)
        drift = np.abs(run["energy"] - e0)
        # the error oscillates with the motion: no growth from the first 10% of the run to all of it
        assert drift.max() < 1.5 * drift[: drift.size // 10].max(), method
    assert periods > 100
    # euler: 60 s (about 34 periods) keeps dt within its limit, a doubling of the amplitude over the run
    run = simulate(swinging_rod(1.0, theta0=1.0, t_end=60.0), dt=1e-3, method="euler")
    gained = run["energy"] - e0
    assert gained[-1] > 5 * np.abs(gained[: gained.size // 10]).max()
    assert np.all(np.diff(gained[:: gained.size // 20]) > 0)  # grows period after period


def _round_trip(method: str, dt: float = 1e-2) -> tuple[float, float]:
    """Forward 3 s from (1, 0.5), reverse the velocity, 3 s back: the final (theta, omega)."""
    forward = simulate(swinging_rod(1.0, theta0=1.0, omega0=0.5, t_end=3.0), dt=dt, method=method)
    back = simulate(swinging_rod(1.0, theta0=forward["theta"][-1], omega0=-forward["omega"][-1], t_end=3.0),
                    dt=dt, method=method)
    return back["theta"][-1], back["omega"][-1]


@pytest.mark.parametrize("method", ["verlet", "yoshida6", "gauss6"])
def test_time_reversibility(method):
    """Symmetric methods: forward N steps, reverse the velocity, N steps back -> the start, to round-off."""
    theta, omega = _round_trip(method)
    assert theta == pytest.approx(1.0, abs=2e-14)
    assert omega == pytest.approx(-0.5, abs=2e-14)


def test_rk4_is_not_time_reversible():
    """The same round trip with rk4 misses by its truncation error: the test above can fail."""
    theta, _omega = _round_trip("rk4")
    assert abs(theta - 1.0) > 1e-9


@pytest.mark.parametrize("method", ["euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6"])
def test_batch_equals_single_runs(method):
    theta0 = np.array([[0.1, 1.0, 2.5], [3.1, -1.0, 0.5]])
    omega0 = np.array([0.0, 1.0, 8.0])  # broadcasts along the rows
    lengths = np.array([[0.5], [2.0]])
    batch = simulate(swinging_rod(lengths, 1.3, theta0=theta0, omega0=omega0, t_end=2.0), dt=1e-2, method=method)
    assert batch["theta"].shape == (201, 2, 3)
    for i in range(2):
        for j in range(3):
            single = simulate(swinging_rod(lengths[i, 0], 1.3, theta0=theta0[i, j], omega0=omega0[j], t_end=2.0),
                              dt=1e-2, method=method)
            for name in ("theta", "omega", "energy"):
                np.testing.assert_array_equal(batch[name][:, i, j], single[name])


def test_batched_exact_and_period_match_single():
    theta0 = np.array([0.1, 1.0, 3.1])
    batch = swinging_rod(1.0, theta0=theta0, omega0=[0.0, 2.0, 0.0], t_end=1.0)
    t = np.linspace(0.0, 3.0, 31)
    exact = batch.exact(t)
    for j in range(3):
        single = batch.item(j)
        assert single.period == batch.period[j]
        np.testing.assert_array_equal(exact["theta"][:, j], single.exact(t)["theta"])


# ----- bad input -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, words", [
    (dict(length=0.0), "length"),
    (dict(length=-1.0), "length"),
    (dict(length=1.0, mass=0.0), "mass"),
    (dict(length=1.0, mass=-2.0), "mass"),
    (dict(length=1.0, theta0=np.nan), "theta0"),
    (dict(length=1.0, omega0=np.inf), "omega0"),
    (dict(length=[1.0, 2.0], theta0=[0.1, 0.2, 0.3]), "broadcast"),
])
def test_bad_rod_input(kwargs, words):
    arguments = dict(theta0=1.0, t_end=1.0) | kwargs
    length = arguments.pop("length")
    with pytest.raises(ValueError, match=words):
        swinging_rod(length, **arguments)


def test_pivot_through_the_centre_of_mass_is_rejected():
    with pytest.raises(ValueError, match="centre of mass"):
        compound_pendulum(Inertia.disc(1.0, 0.2, axis="y"), pivot=(0.0, 0.0, 0.0), theta0=1.0, t_end=1.0)
    # a pivot on the line through the centre of mass along the axis is the same hinge line
    with pytest.raises(ValueError, match="centre of mass"):
        compound_pendulum(Inertia.disc(1.0, 0.2, axis="y"), pivot=(0.0, 0.5, 0.0), theta0=1.0, t_end=1.0)


def test_bad_compound_input():
    with pytest.raises(ValueError, match="Inertia"):
        compound_pendulum("disc", pivot=(0.0, 0.0, 0.1), theta0=1.0, t_end=1.0)
    with pytest.raises(ValueError, match="pivot"):
        compound_pendulum(Inertia.disc(1.0, 0.2, axis="y"), pivot=(0.0, 0.1), theta0=1.0, t_end=1.0)
    with pytest.raises(ValueError, match="t_end"):
        compound_pendulum(Inertia.disc(1.0, 0.2, axis="y"), pivot=(0.0, 0.0, 0.1), theta0=1.0, t_end=0.0)
