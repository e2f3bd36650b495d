"""The chapter's two-body problem (section 5.1.5) against Kepler's solution.

x1 = R + (m2/M) r, x2 = R - (m1/M) r, R' constant, mu r'' = F12 with mu = m1 m2/M: for gravity
r'' = -G M r/|r|^3, a Kepler orbit of period 2 pi sqrt(a^3/(G M)) when bound.
"""

from __future__ import annotations

import numpy as np
import pytest

import rbody
from rbody.scenes import two_body
from rbody.scenes.two_body import solve_kepler_elliptic, solve_kepler_hyperbolic

M1, M2 = 1.0, 0.5
K = M1 + M2          # G (m1 + m2) with G = 1


def _ellipse(**changes):
    """r0 = 1 along x, r0' = 1 along z: a = 1/(2 - 1/K) = 0.75, e = 1/3."""
    args = dict(separation=1.0, relative_velocity=1.0, t_end=10.0)
    args.update(changes)
    return two_body(args.pop("m1", M1), args.pop("m2", M2), **args)


def _max_error(scene, dt, method, name="r1"):
    run = rbody.simulate(scene, dt=dt, method=method)
    return float(np.max(np.abs(run[name] - scene.exact(run.t)[name])))


# ----- Kepler's equation ----------------------------------------------------------------------------

def test_kepler_elliptic_to_round_off():
    e = np.array([0.0, 0.1, 0.5, 0.9, 0.99, 0.999999])
    M = np.linspace(-40.0, 40.0, 2001)[:, None]
    E = solve_kepler_elliptic(M, e)
    residual = E - e * np.sin(E) - M
    assert np.max(np.abs(residual)) <= 4 * np.finfo(float).eps * 40.0
    assert np.all(np.diff(E, axis=0) > 0)  # E increases with M: no branch jumps


def test_kepler_hyperbolic_to_round_off():
    e = np.array([1.000001, 1.01, 1.5, 3.0, 50.0])
    M = np.concatenate([-np.logspace(3, -8, 300), [0.0], np.logspace(-8, 3, 300)])[:, None]
    H = solve_kepler_hyperbolic(M, e)
    residual = e * np.sinh(H) - H - M
    assert np.max(np.abs(residual) / (np.abs(M) + e * np.abs(np.sinh(H)) + 1e-300)) <= 8 * np.finfo(float).eps


# ----- exact motion --------------------------------------------------------------------------------------

def test_circular_orbit():
    """|r0'| = sqrt(K/|r0|): r(t) = |r0| (cos wt, 0, sin wt), w = sqrt(K/|r0|^3)."""
    r = 2.0
    scene = _ellipse(separation=r, relative_velocity=np.sqrt(K / r))
    w = np.sqrt(K / r**3)
    t = np.linspace(0, 20, 41)
    exact = scene.exact(t)
    circle = r * np.stack([np.cos(w * t), np.zeros_like(t), np.sin(w * t)], axis=1)
    np.testing.assert_allclose(exact["r1"], M2 / K * circle, rtol=0, atol=1e-13 * r)
    np.testing.assert_allclose(exact["r2"], -M1 / K * circle, rtol=0, atol=1e-13 * r)
    np.testing.assert_allclose(exact["separation"], r, rtol=1e-14)
    assert scene.period == pytest.approx(2 * np.pi / w, rel=1e-14)


def test_ellipse_period_and_return():
    scene = _ellipse()
    a = 1 / (2 / 1.0 - 1.0**2 / K)            # vis-viva
    assert scene.semi_major_axis == pytest.approx(a, rel=1e-15)
    assert scene.eccentricity == pytest.approx(1 / 3, rel=1e-14)
    period = 2 * np.pi * np.sqrt(a**3 / K)
    assert scene.period == pytest.approx(period, rel=1e-14)
    back = scene.exact([0.0, period, 3 * period])
    for name in ("r1", "r2"):
        np.testing.assert_allclose(back[name][1:], back[name][[0, 0]], rtol=0, atol=1e-13)
    # r0 is across r0' and slower than circular: apocentre a (1 + e) = 1 at t = 0, pericentre
    # a (1 - e) half a period later
    assert scene.exact([period / 2])["separation"][0] == pytest.approx(a * (1 - 1 / 3), rel=1e-14)


# ellipses from near apocentre and near pericentre, hyperbolas; pericentre distances >= 0.18
@pytest.mark.parametrize("speed, tilt", [(0.8, 0.0), (1.0, 0.3), (1.6, 0.3), (2.5, 0.0), (2.5, 0.7)])
def test_exact_orbit_solves_newton(speed, tilt):
    """r'' = -K r/|r|^3 (five-point second difference, h = 1e-4: truncation ~ (h/tau)^4 with
    tau = q^(3/2)/sqrt(K) >= 0.06 s at the pericentre q, round-off ~ 1e-16 |r|/h^2) and r' matches the
    first difference of r."""
    v = speed * np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    scene = _ellipse(separation=np.array([1.0, 0.0, 0.3]), relative_velocity=v)
    t = np.linspace(0.3, 9.7, 13)
    h = 1e-4
    r = lambda s: scene.relative_orbit(s)[0][:, 0]  # noqa: E731
    second = (-r(t - 2 * h) + 16 * r(t - h) - 30 * r(t) + 16 * r(t + h) - r(t + 2 * h)) / (12 * h**2)
    position, rate = scene.relative_orbit(t)
    position, rate = position[:, 0], rate[:, 0]
    distance = np.linalg.norm(position, axis=1, keepdims=True)
    gravity = -K * position / distance**3
    round_off = 64 / 12 * np.finfo(float).eps * np.max(distance) / h**2   # the stencil's weights times eps |r|
    np.testing.assert_allclose(second, gravity, rtol=0, atol=1e-6 * np.max(np.abs(gravity)) + 2 * round_off)
    first = (r(t - 2 * h) - 8 * r(t - h) + 8 * r(t + h) - r(t + 2 * h)) / (12 * h)
    np.testing.assert_allclose(first, rate, rtol=0, atol=1e-8 * (1 + np.max(np.abs(rate))))
    np.testing.assert_allclose(scene.relative_orbit([0.0])[0][0, 0], [1.0, 0.0, 0.3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(scene.relative_orbit([0.0])[1][0, 0], v, rtol=0, atol=1e-14)


def test_exact_orbit_near_a_close_pericentre_matches_a_tight_reference():
    """e = 0.968, pericentre 0.018: the exact orbit against DOP853 at rtol 1e-13 (the reference method),
    over three pericentre passages."""
    scene = _ellipse(separation=np.array([1.0, 0.0, 0.3]),
                     relative_velocity=0.4 * np.array([np.sin(0.7), 0.0, np.cos(0.7)]))
    assert 0.96 < scene.eccentricity < 0.97
    assert _max_error(scene, 0.01, "reference", "r1") < 1e-9


@pytest.mark.parametrize("speed", [0.5, 1.0, 2.2])
def test_exact_energy_and_angular_momentum_are_constant(speed):
    """Observables formed from the exact x1, x2, v1, v2 keep E and L about the centre of mass."""
    scene = _ellipse(relative_velocity=speed, com_velocity=(0.3, 0.0, -0.2))
    t = np.linspace(0, 10, 21)
    r, v = scene.relative_orbit(t)
    V = np.array([0.3, 0.0, -0.2])
    x1, x2 = t[:, None, None] * V + M2 / K * r, t[:, None, None] * V - M1 / K * r
    v1, v2 = V + M2 / K * v, V - M1 / K * v
    observed = scene.observe_states(x1, x2, v1, v2)
    mu = M1 * M2 / K
    energy = 0.5 * K * V @ V + 0.5 * mu * speed**2 - M1 * M2 / 1.0
    np.testing.assert_allclose(observed["energy"], energy, rtol=1e-13)
    np.testing.assert_allclose(observed["angular_momentum"][:, 0], np.broadcast_to([0.0, -mu * speed, 0.0], (21, 3)),
                               rtol=0, atol=1e-13)
    exact = scene.exact(t)
    np.testing.assert_allclose(exact["r1"], x1[:, 0], rtol=0, atol=1e-15 * 10)
    np.testing.assert_allclose(exact["energy"], energy, rtol=1e-15)


def test_centre_of_mass_moves_uniformly_and_r_is_one_body():
    """M R = m1 x1 + m2 x2 = M V t; two pairs with the same m1 + m2 share r(t) (mu only rescales)."""
    V = np.array([0.5, 0.0, 0.25])
    t = np.linspace(0, 10, 11)
    a = _ellipse(com_velocity=V).exact(t)
    np.testing.assert_allclose((M1 * a["r1"] + M2 * a["r2"]) / K, t[:, None] * V, rtol=0, atol=1e-14)
    b = _ellipse(m1=0.25, m2=1.25, com_velocity=V).exact(t)
    np.testing.assert_allclose(a["r1"] - a["r2"], b["r1"] - b["r2"], rtol=0, atol=1e-14)
    assert _ellipse().reduced_mass == pytest.approx(M1 * M2 / K, rel=1e-15)


def test_heavy_partner_stays_nearly_fixed():
    """The chapter: m2 >> m1 makes mu ~ m1 and the heavy body almost still (|x2| = m1/M |r|)."""
    scene = two_body(1.0, 1e6, separation=1.0, relative_velocity=1000.0, t_end=1.0)
    exact = scene.exact(np.linspace(0, 1e-3, 5))
    assert np.max(np.linalg.norm(exact["r2"], axis=-1)) <= 1e-6 * np.max(exact["separation"]) * (1 + 1e-12)


def test_hyperbola_is_unbound():
    scene = _ellipse(relative_velocity=2.5)
    assert scene.eccentricity > 1 and scene.semi_major_axis < 0 and scene.period == np.inf
    separation = scene.exact(np.linspace(0, 100, 11))["separation"]
    assert np.all(np.diff(separation) > 0)
    # far away the relative speed tends to sqrt(2 E / mu) = sqrt(v0^2 - 2K/r0)
    _r, v = scene.relative_orbit([1e7])
    assert np.linalg.norm(v) == pytest.approx(np.sqrt(2.5**2 - 2 * K), rel=1e-6)


# ----- native runs ------------------------------------------------------------------------------------

@pytest.mark.parametrize("method, order, dt", [
    ("symplectic_euler", 1, 4e-3), ("verlet", 2, 1e-2), ("rk4", 4, 2e-2), ("yoshida6", 6, 4e-2), ("gauss6", 6, 0.1),
])
def test_method_order(method, order, dt):
    scene = _ellipse(t_end=5.0)
    ratio = _max_error(scene, dt, method) / _max_error(scene, dt / 2, method)
    assert 2**order * 0.75 < ratio < 2**order * 1.3


@pytest.mark.parametrize("method", ["euler", "verlet", "rk4", "gauss6"])
def test_momentum_is_conserved_to_round_off(method):
    """The pair force is formed once and applied with both signs; P = M V stays whatever dt."""
    scene = _ellipse(com_velocity=(0.2, 0.0, 0.1), t_end=10.0)
    run = rbody.simulate(scene, dt=0.05, method=method)
    x1, x2 = run["r1"], run["r2"]
    R = (M1 * x1 + M2 * x2) / K
    steps = run.t.size
    np.testing.assert_allclose(R, run.t[:, None] * np.array([0.2, 0.0, 0.1]), rtol=0,
                               atol=steps * 4 * np.finfo(float).eps * 10)


def test_verlet_keeps_angular_momentum_and_bounds_the_energy_error():
    """Verlet is symplectic: L about the centre of mass to round-off; the energy error stays O(dt^2)
    over many periods instead of drifting."""
    scene = _ellipse(t_end=30 * 3.35)
    run = rbody.simulate(scene, dt=1e-2, method="verlet")
    L = run["angular_momentum"]
    np.testing.assert_allclose(L, np.broadcast_to(L[0], L.shape), rtol=0, atol=1e-13)
    energy_error = np.abs(run["energy"] - run["energy"][0])
    first, last = energy_error[: run.t.size // 30].max(), energy_error[-run.t.size // 30:].max()
    assert last < 1.5 * first
    assert run["energy"][0] == pytest.approx(scene.exact([0.0])["energy"][0], rel=1e-15)


def test_hyperbolic_flyby_rk4():
    scene = _ellipse(relative_velocity=2.0, t_end=10.0)
    assert _max_error(scene, 1e-3, "rk4") < 1e-11


def test_batch_over_G():
    scene = _ellipse(G=np.array([0.5, 1.0, 1.5]), t_end=4.0)
    assert scene.batch_shape == (3,)
    run = rbody.simulate(scene, dt=2e-3, method="rk4")
    assert run["r1"].shape == (run.t.size, 3, 3) and run["separation"].shape == (run.t.size, 3)
    exact = scene.exact(run.t)
    np.testing.assert_allclose(run["r1"], exact["r1"], rtol=0, atol=1e-7)
    assert np.all(np.diff(scene.period) < 0)  # stronger gravity, shorter period
    one = scene.item(2)
    np.testing.assert_allclose(one.exact(run.t)["r1"], exact["r1"][:, 2], rtol=0, atol=1e-15)


# ----- bad input ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("changes, words", [
    (dict(separation=0.0), "non-zero"),
    (dict(separation=(0.0, 0.0, 0.0)), "non-zero"),
    (dict(separation=(1.0, 0.5, 0.0)), "x-z plane"),
    (dict(relative_velocity=(0.0, 1.0, 0.0)), "x-z plane"),
    (dict(separation=(1.0, 2.0)), "shape"),
    (dict(relative_velocity=0.0), "radial"),
    (dict(relative_velocity=(2.0, 0.0, 0.0)), "radial"),
    (dict(relative_velocity=np.sqrt(2 * K)), "parabolic"),
    (dict(m1=-1.0), "m1"),
    (dict(m2=0.0), "m2"),
    (dict(G=np.nan), "finite"),
    (dict(separation=np.inf), "finite"),
])
def test_bad_input(changes, words):
    with pytest.raises(ValueError, match=words):
        _ellipse(**changes)


# ----- what other simulators build -------------------------------------------------------------------

def test_layout_and_pair_force():
    scene = _ellipse(com_velocity=(0.1, 0.0, 0.0))
    layout = scene.layout
    assert [b.name for b in layout.bodies] == ["body1", "body2"]
    assert [(j.name, j.axis) for j in layout.joints] == [
        ("body1_x", (1.0, 0.0, 0.0)), ("body1_z", (0.0, 0.0, 1.0)),
        ("body2_x", (1.0, 0.0, 0.0)), ("body2_z", (0.0, 0.0, 1.0))]
    joints = {j.name: j for j in layout.joints}
    assert joints["body1_x"].qpos0 == pytest.approx(M2 / K) and joints["body2_x"].qpos0 == pytest.approx(-M1 / K)
    assert joints["body1_z"].qvel0 == pytest.approx(M2 / K) and joints["body1_x"].qvel0 == pytest.approx(0.1)
    # m1 x1'' = pair_force on the exact motion; the observables come back from joint histories
    t = np.linspace(0.5, 9.5, 7)
    exact = scene.exact(t)
    h = 1e-3
    x1 = lambda s: scene.exact(s)["r1"]  # noqa: E731
    second = (-x1(t - 2 * h) + 16 * x1(t - h) - 30 * x1(t) + 16 * x1(t + h) - x1(t + 2 * h)) / (12 * h**2)
    np.testing.assert_allclose(M1 * second, scene.pair_force(exact["r1"], exact["r2"]), rtol=0, atol=1e-6)
    _r, v = scene.relative_orbit(t)
    V = np.array([0.1, 0.0, 0.0])
    v1, v2 = V + M2 / K * v[:, 0], V - M1 / K * v[:, 0]
    histories = {f"body{i}_{axis}": (exact[f"r{i}"][:, k], v[:, k])
                 for i, v in ((1, v1), (2, v2)) for axis, k in (("x", 0), ("z", 2))}
    observed = scene.observe(t, {}, histories)
    for name in ("r1", "r2", "separation"):
        np.testing.assert_allclose(observed[name], exact[name], rtol=0, atol=1e-15)
    np.testing.assert_allclose(observed["energy"], exact["energy"], rtol=1e-14)
    np.testing.assert_allclose(observed["angular_momentum"], exact["angular_momentum"], rtol=0, atol=1e-14)
