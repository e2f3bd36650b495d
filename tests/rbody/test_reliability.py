"""Issue 12: no silent wrong answer, work estimated before it starts, clear messages.

Each test here failed before its fix (the value or the message it checks was wrong or missing)."""

from __future__ import annotations

import numpy as np
import pytest

from rbody import Inertia, simulate
from rbody.errors import SimulationError
from rbody.motion import quat_to_matrix
from rbody.scenes import compound_pendulum, pi_collisions, rocket, swinging_rod


# ----- mass properties: scale before squaring ---------------------------------------------------------

@pytest.mark.parametrize("axis", [[1e300, 1e300, 0.0], [1e-200, 1e-200, 0.0], [3e-310, 3e-310, 0.0]])
def test_rod_axis_of_any_size_gives_the_same_tensor(axis):
    want = Inertia.rod(1.0, 1.0, axis=[1.0, 1.0, 0.0]).tensor
    got = Inertia.rod(1.0, 1.0, axis=axis).tensor
    np.testing.assert_allclose(got, want, rtol=0, atol=4e-16)
    assert got[0, 1] == pytest.approx(-1 / 24)  # products of inertia carry the minus sign


def test_point_masses_far_from_the_origin_keep_their_moments():
    # Two unit masses 2 m apart at x = 1e16: I_yy = I_zz = 2 (m d^2/4 each), whatever the offset.
    inertia = Inertia.point_masses([1.0, 1.0], [[1e16, 0, 0], [1e16 + 2, 0, 0]])
    np.testing.assert_allclose(np.diag(inertia.tensor), [0.0, 2.0, 2.0], rtol=1e-15, atol=0)
    assert abs(inertia.com[0] - (1e16 + 1)) <= 2.0  # the nearest float to 1e16 + 1


def test_point_masses_whose_moments_overflow_are_refused():
    with pytest.raises(ValueError, match="overflow"):
        Inertia.point_masses([1.0, 1.0], [[-1e200, 0, 0], [1e200, 0, 0]])


def test_tensor_beyond_float64_sums_says_why():
    with pytest.raises(ValueError, match=r"largest entry 1e\+308.*overflow"):
        Inertia(1.0, np.zeros(3), 1e308 * np.eye(3))


# ----- the pendulum's limits ----------------------------------------------------------------------------

T = np.linspace(0.0, 3.0, 7)


@pytest.mark.parametrize("theta0", [0.0, 2 * np.pi, -4 * np.pi])
def test_pendulum_at_rest_at_the_bottom_stays_there(theta0):
    out = swinging_rod(1.0, theta0=theta0, t_end=3.0).exact(T)
    np.testing.assert_array_equal(out["theta"], np.full(T.size, theta0))
    np.testing.assert_array_equal(out["omega"], np.zeros(T.size))


def test_tiny_swing_is_continuous_with_the_elliptic_solution():
    # theta0 = 1e-9: k^2 = 2.5e-19, elliptic; 1e-11: harmonic. Both scale with the amplitude.
    a = swinging_rod(1.0, theta0=1e-9, t_end=3.0).exact(T)["theta"]
    b = swinging_rod(1.0, theta0=1e-11, t_end=3.0).exact(T)["theta"] * 100
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-24)
    assert np.all(np.isfinite(swinging_rod(1.0, theta0=1e-200, t_end=3.0).exact(T)["theta"]))


def test_no_gravity_is_a_uniform_turn_matching_the_run():
    scene = swinging_rod(1.0, theta0=0.5, omega0=1.5, gravity=0.0, t_end=2.0)
    exact = scene.exact(T)
    np.testing.assert_allclose(exact["theta"], 0.5 + 1.5 * T, rtol=1e-15)
    np.testing.assert_array_equal(exact["omega"], np.full(T.size, 1.5))
    run = simulate(scene, dt=0.01, method="rk4")
    np.testing.assert_allclose(run["theta"], scene.exact(run.t)["theta"], rtol=1e-13)
    assert scene.period == pytest.approx(2 * np.pi / 1.5)
    body = Inertia.solid_sphere(1.0, 0.1)
    out = compound_pendulum(body, pivot=[0, 0, 0.5], theta0=0.3, gravity=0.0, t_end=1.0).exact(T)
    np.testing.assert_array_equal(out["theta"], np.full(T.size, 0.3))


# ----- messages -----------------------------------------------------------------------------------------

def test_one_zero_quaternion_among_many_is_named_briefly():
    q = np.tile([0.5, 0.5, 0.5, 0.5], (200_000, 1))
    q[123_456] = 0.0
    with pytest.raises(ValueError) as error:
        quat_to_matrix(q)
    message = str(error.value)
    assert len(message) < 300
    assert "(123456,)" in message and "1 of 200000" in message


def test_non_finite_values_in_a_large_array_are_named_briefly():
    from rbody.checks import finite_array

    values = np.zeros((100_000, 3))
    values[777, 2] = np.nan
    with pytest.raises(ValueError) as error:
        finite_array(values, "positions")
    assert len(str(error.value)) < 300 and "(777, 2)" in str(error.value)


# ----- work estimated before it starts ------------------------------------------------------------------

ROD = swinging_rod(1.0, theta0=1.0, t_end=1.0)


@pytest.mark.parametrize("dt", [1e-300, 5e-324])
def test_a_step_too_small_is_refused_as_too_many_steps(dt):
    with pytest.raises(ValueError, match="too many steps") as error:
        simulate(ROD, dt=dt)
    assert "margin below the top" not in str(error.value) and len(str(error.value)) < 600


def test_save_every_beyond_the_run_is_an_error_not_a_round_up():
    with pytest.raises(ValueError, match=r"save_every=1000000000000: beyond the run of 1000 steps"):
        simulate(ROD, dt=1e-3, save_every=10**12)
    assert simulate(ROD, dt=1e-3, save_every=1000).t[-1] == pytest.approx(1.0)  # the whole run is allowed


def test_a_batch_beyond_the_memory_is_refused_with_the_estimate(monkeypatch):
    import importlib

    module = importlib.import_module("rbody.simulation")  # the module, not the function of that name
    monkeypatch.setattr(module, "available_memory", lambda: 10**9)  # 1 GB free
    batch = swinging_rod(np.ones(1000), theta0=1.0, t_end=1.0)      # 1001 x 1000 x 2 x 8 B = 16 MB
    assert simulate(batch, dt=1e-3).t.size == 1001
    monkeypatch.setattr(module, "available_memory", lambda: 10**7)  # 10 MB free
    with pytest.raises(ValueError, match=r"GB at the peak \(saved states 0.016 GB.*allow_large=True"):
        simulate(batch, dt=1e-3)
    assert simulate(batch, dt=1e-3, allow_large=True).t.size == 1001


def test_estimate_counts_steps_samples_and_bytes():
    from rbody.simulation import estimate_work

    work = estimate_work(swinging_rod(np.ones(4), theta0=1.0, t_end=1.0), 1e-3, 1.0, 10)
    assert {k: work[k] for k in ("steps", "batch", "samples", "state_bytes", "impacts")} == {
        "steps": 1000.0, "batch": 4.0, "samples": 101.0, "state_bytes": 8.0 * 101 * 4 * 2, "impacts": 0.0}
    # the peak adds the observables formed from the states and the workspaces (tests/rbody/test_memory.py)
    assert work["bytes"] == (work["state_bytes"] + work["observable_bytes"] + work["build_bytes"] + work["work_bytes"]
                             + work["constraint_bytes"])
    assert work["constraint_bytes"] == 0.0  # no constraint layer


@pytest.mark.parametrize("digits", [10, 11])
def test_pi_factory_sets_t_end_without_running_the_impacts_and_simulate_refuses(digits):
    import time

    start = time.perf_counter()
    scene = pi_collisions(digits)
    assert time.perf_counter() - start < 5.0       # the run of 3e10 impacts takes ~15 min
    with pytest.raises(ValueError, match=r"about 3.14e\+1[01] impacts"):
        simulate(scene, dt=scene.t_end / 10)


@pytest.mark.parametrize("convention", ["galperin", "chapter"])
@pytest.mark.parametrize("digits", [0, 1, 2, 3])
def test_closed_form_last_impact_matches_the_run(digits, convention):
    scene = pi_collisions(digits, convention=convention, speed=0.7, spacing=1.3)
    counts = scene.counts()
    assert counts["done"] and counts["total"] == scene.exact_counts["total"]
    assert scene.last_impact_time == pytest.approx(counts["t_last"], rel=1e-11)
    assert scene.t_end == pytest.approx(1.1 * counts["t_last"], rel=1e-11)


# ----- a burn shorter than the step ------------------------------------------------------------------

def test_burn_shorter_than_the_step_is_refused_not_a_wrong_speed():
    scene = rocket(100.0, burn_rate=1e6, exhaust_speed=50.0, dry_mass=40.0, t_end=1.0)
    for method in ("euler", "rk4"):
        with pytest.raises(SimulationError, match=r"jumps at t = 6e-05 s.*dt <= 6e-06"):
            simulate(scene, dt=1e-3, method=method)
    # Below the step it asks for, rk4 converges on the exact final speed u log(m0/dry) = 45.81 m/s.
    exact = 50.0 * np.log(100 / 40)
    errors = [abs(simulate(scene, dt=dt, t_end=1e-4, method="rk4")["speed"][-1] - exact) for dt in (6e-6, 6e-7)]
    assert errors[1] < 1e-3 * errors[0] and errors[1] < 1e-8 * exact  # fourth order: 1e-4 per tenfold


# ----- meshes: overlapping parts and self-intersection ------------------------------------------------

def _box_with_corner_tetrahedron():
    import trimesh

    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))            # 6 m^3
    corner = np.array([-0.5, -1.0, -1.5])
    tet = trimesh.Trimesh(corner + np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0], [0, 0, 0.5]]),
                          [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=False)  # 1/48 m^3, inside
    assert tet.volume > 0
    return trimesh.util.concatenate([box, tet])


def test_part_inside_another_sharing_one_vertex_is_refused():
    # Before: the shared vertex joined the two into one part, and the mass came out 6.0208 instead of 6.
    with pytest.raises(ValueError, match=r"part 1 of 2 .*overlapping solids count their mass twice"):
        Inertia.from_mesh(_box_with_corner_tetrahedron(), density=1.0)


@pytest.mark.parametrize("moved_to", [[-0.9, -1.8, 2.9], [-1.5, 1.0, 1.5]])
def test_box_folded_through_itself_is_refused(moved_to):
    import trimesh

    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    vertices = box.vertices.copy()
    vertices[int(np.argmax(vertices.sum(axis=1)))] = moved_to       # the corner (+, +, +) pushed through
    folded = trimesh.Trimesh(vertices, box.faces, process=False)
    assert folded.volume > 0                                         # closed, wound, with a volume: plausible
    with pytest.raises(ValueError, match=r"surface intersects itself: faces \d+ and \d+ cross"):
        Inertia.from_mesh(folded, density=1.0)


def test_bodies_touching_at_a_corner_or_a_face_are_still_accepted():
    import trimesh

    a = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    b = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    b.apply_translation((1.0, 1.0, 1.0))                               # meets a at one corner only
    both = Inertia.from_mesh(trimesh.util.concatenate([a, b]), density=1.0)
    want = Inertia.box(1.0, (1, 1, 1)) + Inertia.box(1.0, (1, 1, 1)).translated((1, 1, 1))
    assert both.mass == pytest.approx(2.0, rel=1e-14)
    np.testing.assert_allclose(both.tensor, want.tensor, rtol=1e-13)


def test_a_mesh_too_large_to_check_is_refused_not_left_unchecked():
    import trimesh

    with pytest.raises(ValueError, match="cannot check in reasonable time"):
        Inertia.from_mesh(trimesh.creation.cylinder(radius=1.0, height=2.0, sections=1500), mass=1.0)


@pytest.mark.parametrize("gravity", [np.array(()), np.array([9.81, 1.0]), [9.81], np.zeros((1, 1))])
def test_array_gravity_is_a_value_error_naming_it(gravity):
    from rbody import Body, Inertia, Joint, Layout, Scene

    layout = Layout((Body("rod", Inertia(1.0, (0, 0, -0.5), np.diag([0.1, 0.1, 0.01]))),),
                    (Joint("pivot", "hinge", "rod", axis=(0, 1, 0)),))
    with pytest.raises(ValueError, match=r"gravity=.*expected one number"):
        Scene.from_layout(layout, t_end=1.0, gravity=gravity)
    assert Scene.from_layout(layout, t_end=1.0, gravity=np.float64(9.81)).gravity == 9.81


def test_stability_rate_of_a_large_batch_is_each_elements():
    """A batch of 20000 double pendulums (a tree) at random angles: the rate of each equals the rate of that
    element run alone (the batch Jacobian is one compiled loop, not a Python loop over the batch)."""
    from rbody import Body, Inertia, Joint, Layout, Scene, stability

    rod = Inertia(1.0, (0, 0, -0.5), np.diag([1 / 12, 1 / 12, 1e-4]))
    layout = Layout((Body("a", rod), Body("b", rod, parent="a", pos=(0, 0, -1.0))),
                    (Joint("ja", "hinge", "a", axis=(0, 1, 0)), Joint("jb", "hinge", "b", axis=(0, 1, 0))))
    qpos0 = np.random.default_rng(3).uniform(-2, 2, (20000, 2))
    batch = Scene.from_layout(layout, t_end=1.0, qpos0=qpos0)
    rates = stability.fastest_rate(batch, "rk4")
    assert rates.shape == (20000,) and np.all(rates > 0)
    for b in (0, 777, 19999):
        alone = Scene.from_layout(layout, t_end=1.0, qpos0=qpos0[b])
        assert rates[b] == pytest.approx(float(stability.fastest_rate(alone, "rk4")[0]), rel=1e-12)


@pytest.mark.parametrize("value", [0.0, -0.0, 1.5, -2.0, 3, -3, np.float64(0.25), 1e308, 10**400, float("nan"),
                                   float("inf"), True, np.float32(2.0), np.int64(7), "1.5", 1j])
def test_one_number_is_checked_as_an_array_of_it_is(value):
    """The checks' fast path for one Python or numpy number (rbody.checks._plain_number: a model of many bodies
    checks hundreds of thousands as it loads) accepts, returns and refuses exactly what the array path does."""
    from rbody import checks

    def outcome(check, *args, **kwargs):
        try:
            result = check(value, "x", *args, **kwargs)
        except ValueError as error:
            return "refused", str(error)
        return type(result), np.asarray(result).tolist()

    def by_array(check, *args, **kwargs):  # the same check with the fast path off
        original = checks._plain_number
        checks._plain_number = lambda _value: None
        try:
            return outcome(check, *args, **kwargs)
        finally:
            checks._plain_number = original

    for check, args, kwargs in ((checks.finite_array, (), {}), (checks.finite_array, (), {"shape": ()}),
                                (checks.finite_array, (), {"shape": (1,)}), (checks.positive, (), {}),
                                (checks.nonnegative, (), {}), (checks.in_interval, (-2.0, 1.5), {}),
                                (checks.in_interval, (-2.0, 1.5), {"closed": True})):
        assert outcome(check, *args, **kwargs) == by_array(check, *args, **kwargs), (check.__name__, args, kwargs)
