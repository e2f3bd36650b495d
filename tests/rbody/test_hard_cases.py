"""rbody on the hard cases of issue 6 (numerical stability), one fast test per behaviour.

The cross-simulator suite is validation/hard/ (tests/validation/test_hard.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import rbody
from rbody import Inertia, SimulationError, simulate, stability
from rbody.scenes import compound_pendulum, free_rotation, pendulum_chain, pi_collisions, rolling, swinging_rod

EPS = float(np.finfo(np.float64).eps)
G = 9.81


def rod_w0(length: float = 1.0) -> float:
    """w0 = sqrt(M g d / I) = sqrt(3 g / (2 L)) for the rod about its end [rad/s]."""
    return math.sqrt(1.5 * G / length)


def mp_theta(theta0: float, t: np.ndarray, length: float = 1.0, dps: int = 50) -> tuple[np.ndarray, float]:
    """theta(t) and the period of the rod released at rest from theta0, in mpmath (the float inputs exactly):
    sin(theta/2) = k sn(w0 t + K | k^2), cos(theta/2) = dn(...), period 4 K / w0."""
    import mpmath

    with mpmath.workdps(dps):
        th, g, L = mpmath.mpf(theta0), mpmath.mpf(G), mpmath.mpf(length)
        w0 = mpmath.sqrt(g * (L / 2) / (L * L / 3))
        m = mpmath.sin(th / 2) ** 2
        K, k = mpmath.ellipk(m), mpmath.sqrt(m)
        theta = [float(2 * mpmath.atan2(k * mpmath.ellipfun("sn", w0 * mpmath.mpf(float(s)) + K, m=m),
                                        mpmath.ellipfun("dn", w0 * mpmath.mpf(float(s)) + K, m=m))) for s in t]
        return np.array(theta), float(4 * K / w0)


# ----- 1. pi collisions ----------------------------------------------------------------------------------

def _phase_error(scene) -> tuple[float, float]:
    """Error [rad] of the direction of the scaled final velocities (sqrt(m) v, sqrt(M) u) against the unfolded
    billiard in mpmath, and the margin alpha dist(pi/alpha, Z) by which it may err before the count changes."""
    import mpmath

    run = simulate(scene, dt=scene.t_end)
    exact = scene.exact(run.t[-1:])
    roots = np.sqrt(np.array(scene.masses))
    got, want = roots * run["velocities"][-1], roots * exact["velocities"][-1]
    phase = abs(math.atan2(got[0], got[1]) - math.atan2(want[0], want[1]))
    with mpmath.workdps(scene.digits + 30):
        alpha = mpmath.atan(1 / mpmath.mpf(10) ** scene.digits)
        ratio = mpmath.pi / alpha
        margin = float(alpha * min(ratio - mpmath.floor(ratio), mpmath.ceil(ratio) - ratio))
    return phase, margin


@pytest.mark.parametrize("digits", [6, 7])
def test_pi_count_exact_and_its_phase_a_rounding_walk(digits):
    """The count is floor(pi 10^N), and the final direction of the velocities is off by no more than a random
    walk of one rounding per impact, sqrt(impacts) eps: float64 holds the count while that stays below the margin."""
    scene = pi_collisions(digits)
    assert scene.count() == scene.expected_collisions == int(str(314159265358)[:digits + 1])
    phase, margin = _phase_error(scene)
    assert phase <= math.sqrt(scene.count()) * EPS
    assert phase < margin / 100


@pytest.mark.slow
def test_pi_count_digits_8():
    scene = pi_collisions(8)
    assert scene.count() == 314159265
    phase, margin = _phase_error(scene)
    assert phase <= math.sqrt(scene.count()) * EPS < margin


# ----- 2. the swinging rod near the top -------------------------------------------------------------------

GAPS = (1e-3, 1e-6, 1e-9)


@pytest.mark.parametrize("gap", GAPS)
def test_near_top_period_against_mpmath(gap):
    """4 K(k^2)/w0 from ellipkm1(cos^2(theta0/2)): exact to round-off even where k^2 rounds to 1."""
    scene = swinging_rod(1.0, theta0=math.pi - gap, t_end=1.0)
    _theta, period = mp_theta(math.pi - gap, np.zeros(1))
    assert abs(scene.period - period) <= 4 * EPS * period


NEAR_TOP_THETA = 1e-11  # [rad]: measured 1.2e-12 at pi - 1e-9 once u0 is formed from (sn0, cn0, dn0)


def _near_top_theta_error(gap: float) -> float:
    scene = swinging_rod(1.0, theta0=math.pi - gap, t_end=1.0)
    t = np.linspace(0.0, 3 * scene.period, 121)
    reference, _period = mp_theta(math.pi - gap, t)
    return float(np.max(np.abs(scene.exact(t)["theta"] - reference)))


def test_near_top_theta_against_mpmath_at_1e_3():
    assert _near_top_theta_error(1e-3) <= NEAR_TOP_THETA


@pytest.mark.parametrize("gap", [1e-6, 1e-9])
def test_near_top_theta_against_mpmath_close_to_the_top(gap):
    assert _near_top_theta_error(gap) <= NEAR_TOP_THETA


def _near_top_run(method: str, gap: float, periods: int, h: float = 0.05):
    probe = swinging_rod(1.0, theta0=math.pi - gap, t_end=1.0)
    scene = swinging_rod(1.0, theta0=math.pi - gap, t_end=periods * probe.period)
    return scene, simulate(scene, dt=h / rod_w0(), method=method, save_every=4)


@pytest.mark.parametrize("method", ["symplectic_euler", "verlet", "yoshida6", "gauss6"])
def test_near_top_symplectic_energy_stays_bounded(method):
    """pi - 1e-3, 100 periods at dt w0 = 0.05: the energy error of the whole run is no larger than twice that of
    its first quarter (bounded, a modified energy is conserved; a drift would give 4 times), and the swing stays
    a swing."""
    scene, run = _near_top_run(method, 1e-3, 100)
    error = np.abs(run["energy"] - run["energy"][0])
    allowance = 8 * EPS * math.sqrt(error.size * 4) * abs(run["energy"][0])  # the rounding's random walk
    assert np.max(error) <= 2 * np.max(error[:error.size // 4]) + allowance
    assert np.max(np.abs(run["theta"])) < math.pi


def test_near_top_rk4_energy_drifts():
    """rk4 (|R(i h w)| < 1) loses energy steadily: the error at the end is many times that after a tenth of the
    run, and at the same phase (each upward pass through the bottom) the energy falls from every period to the
    tenth after it."""
    scene, run = _near_top_run("rk4", 1e-3, 100)
    error = np.abs(run["energy"] - run["energy"][0])
    assert np.max(error[-error.size // 10:]) > 5 * np.max(error[:error.size // 10])
    theta = run["theta"]
    bottom = np.flatnonzero((theta[:-1] < 0) & (theta[1:] >= 0))
    assert bottom.size >= 90
    energy = run["energy"][bottom]
    assert np.all(energy[10:] < energy[:-10])


def test_resolution_problem_of_the_near_top_swing():
    """1 - k^2 = cos^2(theta0/2) is carried by the state only to ~eps: pi - 1e-9 (2.5e-19) cannot be run at all,
    pi - 1e-6 (2.5e-13) for a few hundred steps, pi - 1e-3 for 10^4 periods."""
    w0 = rod_w0()
    dt = 0.05 / w0
    assert stability.resolution_problem(swinging_rod(1.0, theta0=math.pi - 1e-9, t_end=1.0)) is not None
    near = swinging_rod(1.0, theta0=math.pi - 1e-6, t_end=1.0)
    assert stability.resolution_problem(near, dt, 10 * dt) is None
    problem = stability.resolution_problem(near, dt, 1e4 * near.period)
    assert problem is not None and "1 - k^2" in problem and "2.5e-13" in problem
    far = swinging_rod(1.0, theta0=math.pi - 1e-3, t_end=1.0)
    assert stability.resolution_problem(far, dt, 1e4 * far.period) is None


@pytest.mark.parametrize("method", ["verlet", "rk4"])
def test_simulate_refuses_a_swing_float64_cannot_carry(method):
    scene = swinging_rod(1.0, theta0=math.pi - 1e-9, t_end=100.0)
    with pytest.raises(SimulationError, match="1 - k\\^2"):
        simulate(scene, dt=0.05 / rod_w0(), method=method)


# ----- 3. free rotation near the intermediate axis --------------------------------------------------------

def _racket(t_end: float = 100.0):
    return free_rotation(Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])), omega0=(0.05, 10.0, 0.05), t_end=t_end)


def _flip_times(run) -> np.ndarray:
    """Times at which omega_2 crosses zero downwards: the cubic Hermite interpolant through the samples with
    the slopes of Euler's equations, omega_2' = (I3 - I1) omega_3 omega_1 / I2, solved by Newton's method."""
    w = run["omega_body"]
    w2, slope = w[:, 1], (3.0 - 1.0) * w[:, 2] * w[:, 0] / 2.0
    i = np.flatnonzero((w2[:-1] > 0) & (w2[1:] <= 0))
    h = run.t[i + 1] - run.t[i]
    q0, q1, d0, d1 = w2[i], w2[i + 1], slope[i] * h, slope[i + 1] * h
    s = q0 / (q0 - q1)
    for _ in range(8):
        p = ((2 * s**3 - 3 * s**2 + 1) * q0 + (s**3 - 2 * s**2 + s) * d0 + (3 * s**2 - 2 * s**3) * q1
             + (s**3 - s**2) * d1)
        dp = (6 * s**2 - 6 * s) * q0 + (3 * s**2 - 4 * s + 1) * d0 + (6 * s - 6 * s**2) * q1 + (3 * s**2 - 2 * s) * d1
        s = s - p / dp
    return run.t[i] + s * h


@pytest.mark.parametrize("method", ["splitting", "yoshida6"])
def test_intermediate_axis_exact_rotations_keep_L(method):
    """About 23 flips in 100 s: the exact sub-rotations keep |L| (and L_world) to round-off."""
    scene = _racket()
    run = simulate(scene, dt=1e-3, method=method, save_every=10)
    momentum = run["L_world"]
    assert np.max(np.abs(momentum - momentum[0])) <= 1e-12 * np.linalg.norm(momentum[0])
    assert _flip_times(run).size >= 20


@pytest.mark.parametrize("method, energy", [("yoshida6", 1e-11), ("gauss6", 1e-12), ("rk4", 1e-9)])
def test_intermediate_axis_flip_period_and_energy(method, energy):
    """The flips come every 4 K(m)/|lambda| (the exact elliptic period) to 1e-9 on average, and the energy holds
    to the method's error at dt = 1e-3 (measured: yoshida6 3e-13, gauss6 4e-14, rk4 1.5e-11 over 100 s)."""
    scene = _racket()
    run = simulate(scene, dt=1e-3, method=method)
    flips = _flip_times(run)
    assert flips.size >= 20
    assert (flips[-1] - flips[0]) / (flips.size - 1) == pytest.approx(scene.period, rel=1e-9)
    assert np.max(np.abs(run["energy"] / run["energy"][0] - 1)) <= energy


# ----- 4. extreme shapes --------------------------------------------------------------------------------

NEEDLE = Inertia.solid_cylinder(1.0, 1e-4, 1.0, "z")           # moments 5e-9 and 0.0833: ratio 6e-8
THIN_DISC = Inertia.solid_cylinder(1.0, 0.5, 1e-4, "z")        # A + B - C = M h^2 / 6 = 1.7e-9


@pytest.mark.parametrize("body", [NEEDLE, THIN_DISC], ids=["needle", "thin disc"])
@pytest.mark.parametrize("method", ["splitting", "yoshida6", "gauss6", "rk4"])
def test_extreme_bodies_in_free_rotation_are_finite_and_right(body, method):
    """Tumbling and spinning: at dt = 1e-3 where that is inside the method's limit, else at a quarter of the
    limit (the needle's splitting: its sub-rotations move L onto the 5e-9 moment, limit ~5e-4 s); within
    1e-8 (1e-2 for the second-order splitting at a quarter of its limit: 0.0165 (dt w sqrt(I3/I1))^2 per 2 s)."""
    scene = free_rotation(body, omega0=(1.0, 0.1, 10.0), t_end=2.0)
    limit = stability.stability_limit(scene, method)
    dt = 1e-3 if 1e-3 <= limit else limit / 4
    run = simulate(scene, dt=dt, method=method, save_every=max(1, round(1e-3 / dt)))
    exact = scene.exact(run.t)
    assert all(np.all(np.isfinite(run[name])) for name in run.observables)
    tolerance = 1e-2 if method == "splitting" else 1e-8
    assert np.max(np.abs(run["omega_body"] - exact["omega_body"])) <= tolerance * np.max(np.abs(exact["omega_body"]))


def test_needle_splitting_limit_is_where_its_error_grows():
    """The splitting's error on a tumbling needle is 0.0165 (I3/I1) (dt |omega|)^2 over 2 s (measured): at its
    estimated limit that is ~1 % of omega, at 1e-3 s (beyond it) 20 %; rbody.engine.stability refuses 1e-3 s."""
    scene = free_rotation(NEEDLE, omega0=(1.0, 0.1, 0.0), t_end=2.0)
    limit = stability.stability_limit(scene, "splitting")
    assert limit < 1e-3
    with pytest.raises(SimulationError, match="limit"):
        stability.check_step(scene, "splitting", 1e-3)
    errors = []
    for dt in (limit / 4, 1e-3):
        run = raw_run(scene, "splitting", dt)
        t = np.arange(run["omega_body"].shape[0]) * dt
        errors.append(np.max(np.abs(run["omega_body"][:, 0] - scene.exact(t)["omega_body"])))
    assert errors[0] < 1e-2 < errors[1]


@pytest.mark.parametrize("body", [NEEDLE, THIN_DISC, Inertia.rod(1.0, 1.0, "z")], ids=["needle", "disc", "ideal rod"])
def test_extreme_bodies_as_pendulums(body):
    """Hung from the end (the disc from its rim) about the body y axis: I = I_yy + M d^2."""
    pivot = (0.5, 0.0, 0.0) if body is THIN_DISC else (0.0, 0.0, 0.5)
    scene = compound_pendulum(body, pivot=pivot, axis="y", theta0=1.0, t_end=2.0)
    run = simulate(scene, dt=1e-3, method="yoshida6")
    assert np.max(np.abs(run["theta"] - scene.exact(run.t)["theta"])) <= 1e-12
    d = 0.5
    assert scene.equivalent_length == pytest.approx((body.tensor[1, 1] + d * d) / d, rel=1e-15)


def test_ideal_rod_free_rotation_refused_and_export_needs_min_inertia():
    rod = Inertia.rod(1.0, 1.0, "z")
    with pytest.raises(ValueError, match="principal moment"):
        free_rotation(rod, omega0=(1.0, 0.0, 0.0), t_end=1.0)
    pendulum = compound_pendulum(rod, pivot=(0.0, 0.0, 0.5), axis="y", theta0=1.0, t_end=1.0)
    with pytest.raises(ValueError, match="min_inertia"):
        rbody.to_mjcf(pendulum)
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(pendulum, min_inertia=1e-12))
    np.testing.assert_allclose(np.sort(model.body_inertia[1]), [1e-12, 1 / 12, 1 / 12], rtol=1e-12)


@pytest.mark.parametrize("body", [NEEDLE, THIN_DISC], ids=["needle", "thin disc"])
def test_extreme_bodies_export_compiles_with_their_moments(body):
    mujoco = pytest.importorskip("mujoco")
    scene = free_rotation(body, omega0=(1.0, 0.1, 10.0), t_end=1.0)
    model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))
    np.testing.assert_allclose(np.sort(model.body_inertia[1]), np.linalg.eigvalsh(body.tensor), rtol=1e-12)


# ----- 5. rolling at the friction limit -------------------------------------------------------------------

@pytest.mark.parametrize("body", ["disc", "solid_sphere", "hollow_cylinder"])
@pytest.mark.parametrize("factor, rolls", [(1 - 1e-6, False), (1.0, True), (1 + 1e-6, True)])
def test_rolling_at_the_friction_limit(body, factor, rolls):
    """friction = mu_min x (1 -+ 1e-6): classified right, and the run is the closed form of its case to
    round-off (constant accelerations: verlet is exact); the slip below the limit is ~1e-6 and exact too."""
    mu_min = rolling(body, radius=0.1, incline=0.5).mu_min
    scene = rolling(body, radius=0.1, incline=0.5, friction=mu_min * factor, t_end=1.0)
    assert bool(scene.rolls) is rolls
    run = simulate(scene, dt=1e-3, method="verlet")
    exact = scene.exact(run.t)
    for name in ("distance", "speed", "spin"):
        assert np.max(np.abs(run[name] - exact[name])) <= 1e-13 * np.max(np.abs(exact[name]))
    assert np.max(np.abs(run["slip"] - exact["slip"])) <= 1e-13 * np.max(np.abs(exact["speed"]))
    if not rolls:
        assert 1e-7 < exact["slip"][-1] < 1e-5  # the slip that tells the cases apart
    else:
        assert np.all(exact["slip"] == 0.0)


# ----- 6. too large a step ---------------------------------------------------------------------------------

def raw_run(scene, method: str, dt: float, t_end: float | None = None) -> dict:
    """The method's compiled loop on the scene's native model, without simulate's checks: (T, B, n) states and
    the observables, for tests that must step beyond a limit on purpose. Raises SimulationError on a failed step."""

    from rbody.engine import runner
    model = scene.native()
    steps = runner.step_count(scene.t_end if t_end is None else t_end, dt, 1)
    out = np.empty((steps + 1,) + model.y0.shape)
    failed = runner._integrate(model, method, dt, steps, 1, out)
    if np.any(failed >= 0):
        raise SimulationError(f"{method} failed at step {int(np.max(failed))}")
    return model.observe(np.arange(steps + 1) * dt, out)


def _small_swing(t_end: float):
    return swinging_rod(1.0, theta0=1e-3, t_end=t_end)


@pytest.mark.parametrize("method", ["verlet", "rk4", "yoshida6"])
def test_stability_interval_is_where_the_linear_swing_grows(method):
    """A swing of 1e-3 rad is a harmonic oscillator: it stays bounded at 0.98 beta / w0 and grows at
    1.01 beta / w0 (yoshida6: the first unstable window starts at 2.269)."""
    beta = stability.stability_interval(method)
    w0 = rod_w0()
    inside = raw_run(_small_swing(4000 * 0.98 * beta / w0), method, 0.98 * beta / w0)
    assert np.max(np.abs(inside["theta"])) < 2e-3
    outside = raw_run(_small_swing(4000 * 1.01 * beta / w0), method, 1.01 * beta / w0)
    assert np.max(np.abs(outside["theta"])) > 1e-2


def test_stability_limits_of_the_rod_and_the_racket():
    rod = swinging_rod(1.0, theta0=1.0, t_end=20.0)
    w0 = rod_w0()
    assert stability.stability_limit(rod, "verlet") == pytest.approx(2 / w0, rel=1e-14)
    assert stability.stability_limit(rod, "rk4") == pytest.approx(2 * math.sqrt(2) / w0, rel=1e-14)
    assert stability.stability_limit(rod, "euler") == pytest.approx(2 * math.log(2) / (w0**2 * 20.0), rel=1e-14)
    assert stability.stability_limit(rod, "reference") == math.inf
    assert stability.stability_limit(rolling(radius=0.1, incline=0.5), "rk4") == math.inf
    # near the intermediate axis the rate is at least the growth rate w2 sqrt((I2 - I1)(I3 - I2)/(I1 I3))
    racket = _racket(20.0)
    assert float(stability.fastest_rate(racket)[0]) >= 10.0 * math.sqrt(1 / 3) * (1 - 1e-12)


def test_gauss6_runs_inside_its_estimate():
    rod = swinging_rod(1.0, theta0=1.0, t_end=20.0)
    limit = stability.stability_limit(rod, "gauss6")
    run = simulate(rod, dt=0.95 * limit, method="gauss6")
    assert np.all(np.isfinite(run["theta"]))


STEP_CASES = [(scene_name, method, factor)
              for scene_name, methods in (("rod", ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6")),
                                          ("racket", ("euler", "rk4", "gauss6", "splitting", "yoshida6")))
              for method in methods for factor in (2.0, 10.0)]


def _step_scene(name: str):
    return swinging_rod(1.0, theta0=1.0, t_end=20.0) if name == "rod" else _racket(20.0)


@pytest.mark.parametrize("scene_name, method, factor", STEP_CASES)
def test_too_large_a_step_never_returns_non_finite_values(scene_name, method, factor):
    scene = _step_scene(scene_name)
    dt = factor * stability.stability_limit(scene, method)
    try:
        run = simulate(scene, dt=dt, method=method)
    except SimulationError:
        return
    assert all(np.all(np.isfinite(run[name])) for name in run.observables)


@pytest.mark.parametrize("scene_name, method, factor", STEP_CASES)
def test_too_large_a_step_is_refused_naming_the_limit(scene_name, method, factor):
    scene = _step_scene(scene_name)
    limit = stability.stability_limit(scene, method)
    with pytest.raises(SimulationError, match=f"{limit:.6g}"):
        simulate(scene, dt=factor * limit, method=method)


def test_needle_splitting_beyond_its_limit_is_refused():
    with pytest.raises(SimulationError, match="limit"):
        simulate(free_rotation(NEEDLE, omega0=(1.0, 0.1, 0.0), t_end=2.0), dt=1e-3, method="splitting")


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_overflowing_state_is_a_simulation_error():
    with pytest.raises(SimulationError):
        simulate(_racket(20.0), dt=2.0, method="euler")


def test_check_step_names_the_limit():
    rod = swinging_rod(1.0, theta0=1.0, t_end=20.0)
    limit = stability.stability_limit(rod, "verlet")
    stability.check_step(rod, "verlet", 0.99 * limit)
    with pytest.raises(SimulationError, match=f"limit {limit:.6g} s"):
        stability.check_step(rod, "verlet", 1.01 * limit)
    with pytest.raises(SimulationError, match="no stability interval"):
        stability.check_step(rod, "euler", 0.1)


# ----- 7. meshes at bad scales ------------------------------------------------------------------------------

def _box(extents, offset=(0.0, 0.0, 0.0)):
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(offset)
    return mesh


def _relative_tensor_error(got: Inertia, want: Inertia) -> float:
    return float(np.linalg.norm(got.tensor - want.tensor) / np.linalg.norm(want.tensor))


@pytest.mark.parametrize("scale, offset", [(1.0, 1e6), (1e-3, 0.0), (1e3, 0.0), (1.0, -1e6)])
def test_mesh_at_bad_scales(scale, offset):
    """Dyadic box corners: the geometry is exact, so the tensor must be to 1e-9 (it is to round-off)."""
    extents = scale * np.array([1.0, 0.5, 0.25])
    shift = np.array([1.0, -1.0, 1.0]) * offset
    got = Inertia.from_mesh(_box(extents, shift), mass=1.0)
    want = Inertia.box(1.0, extents).translated(shift)
    assert _relative_tensor_error(got, want) <= 1e-9
    assert np.linalg.norm(got.com - want.com) <= 1e-9 * scale


@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_sliver_mesh(offset):
    sliver = np.array([1.0, 2.0**-20, 2.0**-20])
    got = Inertia.from_mesh(_box(sliver, (offset, 0.0, 0.0)), mass=1.0)
    want = Inertia.box(1.0, sliver).translated((offset, 0.0, 0.0))
    assert _relative_tensor_error(got, want) <= 1e-9
    # the small moment itself: a diagonal entry here, summed without cancellation
    assert got.tensor[0, 0] == pytest.approx(want.tensor[0, 0], rel=1e-9)


def _duplicated(mesh):
    """The same box with every face given its own three vertices (36 vertices for 12 faces)."""
    trimesh = pytest.importorskip("trimesh")
    corners = mesh.vertices[mesh.faces].reshape(-1, 3)
    return trimesh.Trimesh(vertices=corners, faces=np.arange(len(corners)).reshape(-1, 3), process=False)


def _with_degenerate_faces(mesh):
    """One edge split at its midpoint m, the zero-area faces (a, m, b), (b, m, a) and a face with a repeated
    index added: the solid is unchanged."""
    trimesh = pytest.importorskip("trimesh")
    vertices, faces = mesh.vertices.copy(), [list(f) for f in mesh.faces]
    a, b, c = faces[0]
    other = next(k for k, f in enumerate(faces[1:], 1) if {a, b} <= set(f))
    d = next(v for v in faces[other] if v not in (a, b))
    m = len(vertices)
    vertices = np.vstack([vertices, (vertices[a] + vertices[b]) / 2])
    faces[0], faces[other] = [a, m, c], [b, m, d]
    faces += [[m, b, c], [m, a, d], [a, m, b], [b, m, a], [a, a, b]]
    return trimesh.Trimesh(vertices=vertices, faces=np.array(faces), process=False)


def test_mesh_with_duplicate_vertices_and_degenerate_faces():
    extents = np.array([1.0, 0.5, 0.25])
    box = _box(extents)
    want = Inertia.box(1.0, extents)
    for mesh in (_duplicated(box), _with_degenerate_faces(box), _duplicated(_with_degenerate_faces(box))):
        assert _relative_tensor_error(Inertia.from_mesh(mesh, mass=1.0), want) <= 1e-9


def test_broken_meshes_raise_clear_errors():
    trimesh = pytest.importorskip("trimesh")
    box = _box((1.0, 0.5, 0.25))
    with pytest.raises(ValueError, match="watertight"):
        Inertia.from_mesh(trimesh.Trimesh(vertices=box.vertices, faces=box.faces[1:], process=False), mass=1.0)
    inverted = box.copy()
    inverted.invert()
    with pytest.raises(ValueError, match="inverted"):
        Inertia.from_mesh(inverted, mass=1.0)


# ----- 9. time reversal --------------------------------------------------------------------------------------

ROUND_OFF = 1e-12


@pytest.mark.parametrize("method", ["verlet", "yoshida6", "gauss6"])
def test_rod_time_reversal(method):
    steps, dt = 1000, 1e-2
    forward = simulate(swinging_rod(1.0, theta0=1.0, omega0=0.5, t_end=steps * dt), dt=dt, method=method)
    back = simulate(swinging_rod(1.0, theta0=float(forward["theta"][-1]), omega0=-float(forward["omega"][-1]),
                                 t_end=steps * dt), dt=dt, method=method)
    assert abs(back["theta"][-1] - 1.0) <= ROUND_OFF and abs(back["omega"][-1] + 0.5) <= ROUND_OFF


def test_chain_time_reversal_gauss6():
    steps, dt = 500, 1e-3
    theta0 = np.linspace(0.3, 0.6, 4)
    forward = simulate(pendulum_chain(4, theta0=theta0, t_end=steps * dt), dt=dt, method="gauss6")
    back = simulate(pendulum_chain(4, theta0=forward["theta"][-1], omega0=-forward["omega"][-1], t_end=steps * dt),
                    dt=dt, method="gauss6")
    assert np.max(np.abs(back["theta"][-1] - theta0)) <= ROUND_OFF
    assert np.max(np.abs(back["omega"][-1])) <= ROUND_OFF


@pytest.mark.parametrize("method", ["splitting", "yoshida6", "gauss6"])
def test_free_rotation_time_reversal(method):
    """Forward from the identity; then the body turned to its final pose (its inertia rotated) spun with
    -omega_world for as many steps: back at the identity with -omega0, to round-off."""
    from rbody.motion import quat_multiply, quat_to_matrix

    steps, dt = 1000, 1e-2
    body = Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]))
    omega0 = np.array([0.3, 0.2, 3.0])
    forward = simulate(free_rotation(body, omega0=omega0, t_end=steps * dt), dt=dt, method=method)
    q_end = forward["quaternion"][-1] / np.linalg.norm(forward["quaternion"][-1])
    rotation = quat_to_matrix(q_end)
    back = simulate(free_rotation(body.rotated(rotation), omega0=-(rotation @ forward["omega_body"][-1]),
                                  t_end=steps * dt), dt=dt, method=method)
    q_back = back["quaternion"][-1] / np.linalg.norm(back["quaternion"][-1])
    total = quat_multiply(q_back, q_end)
    assert 2 * math.atan2(np.linalg.norm(total[1:]), abs(total[0])) <= ROUND_OFF * 10
    spin = quat_to_matrix(q_back) @ back["omega_body"][-1]
    assert np.max(np.abs(spin + omega0)) <= ROUND_OFF * 10 * np.linalg.norm(omega0)
