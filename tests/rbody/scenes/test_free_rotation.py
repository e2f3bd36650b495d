"""Free rotation: the Jacobi-elliptic solution of Euler's equations against the equations themselves,
closed forms of special cases, and rbody's native methods (order, invariants, reversibility)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, example, given, settings, strategies as st

from rbody import Inertia, MethodNotApplicable, simulate
from rbody.engine import integrators, methods
from rbody.motion import quat_conjugate, quat_from_axis_angle, quat_multiply, quat_rotate, quat_to_matrix
from rbody.scene import BodyStates
from rbody.scenes import free_rotation
from rbody.scenes.free_rotation import MIN_BOX_FRACTION, FreeRotation

EPS = np.finfo(float).eps

# A body whose principal axes are not the Inertia's axes: moments (1, 2, 3) kg m^2 turned by TURN.
TURN = quat_to_matrix(np.array([0.9, 0.2, -0.3, 0.1]))
TILTED = Inertia(2.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])).rotated(TURN)
W_AXIS3 = TURN @ np.array([1.0, 0.5, 2.0])   # L^2 > 2T I2: the polhode encircles the largest axis
W_AXIS1 = TURN @ np.array([2.0, 0.5, 0.3])   # L^2 < 2T I2: it encircles the smallest axis


def diagonal(a: float, b: float, c: float, mass: float = 1.0) -> Inertia:
    return Inertia(mass, np.zeros(3), np.diag([a, b, c]))


def derivative(scene: FreeRotation, name: str, t: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """Five-point central difference of an exact observable (error ~ h^4 f^(5) / 30)."""
    values = [scene.exact(t + k * h)[name] for k in (-2, -1, 1, 2)]
    return (values[0] - 8 * values[1] + 8 * values[2] - values[3]) / (12 * h)


def euler_rhs(scene: FreeRotation, omega_body: np.ndarray) -> np.ndarray:
    """w' from I w' = (I w) x w in the Inertia's axes (Euler's equations, torque-free)."""
    tensor = scene._tensor()
    return np.linalg.solve(tensor, np.cross(omega_body @ tensor, omega_body)[..., None])[..., 0]


def assert_solves_the_equations(scene: FreeRotation, t: np.ndarray, tolerance: float = 1e-9) -> None:
    exact = scene.exact(t)
    omega, quaternion = exact["omega_body"], exact["quaternion"]
    scale = np.max(np.abs(omega)) + 1.0
    # Euler's equations
    np.testing.assert_allclose(derivative(scene, "omega_body", t), euler_rhs(scene, omega),
                               rtol=0, atol=tolerance * scale**2)
    # q' = 1/2 q (0, w_body)
    pure = np.concatenate([np.zeros(omega.shape[:-1] + (1,)), omega], axis=-1)
    np.testing.assert_allclose(derivative(scene, "quaternion", t), 0.5 * quat_multiply(quaternion, pure),
                               rtol=0, atol=tolerance * scale)
    # R (I w) is the fixed L_world, and |q| = 1
    np.testing.assert_allclose(quat_rotate(quaternion, omega @ scene._tensor()), exact["L_world"],
                               rtol=0, atol=1e-13 * scale * np.max(scene.principal_moments))
    np.testing.assert_allclose(np.linalg.norm(quaternion, axis=-1), 1.0, rtol=0, atol=4 * EPS)


def max_error(trajectory, exact, names=("omega_body", "quaternion")) -> float:
    return max(float(np.max(np.abs(trajectory[name] - exact[name]))) for name in names)


# ----- the exact solution ---------------------------------------------------------------------------------

@pytest.mark.parametrize("omega0, around_largest", [(W_AXIS3, True), (W_AXIS1, False), (-W_AXIS3, True),
                                                     (-W_AXIS1, False)], ids=["axis3", "axis1", "-axis3", "-axis1"])
def test_exact_solution_solves_euler_equations_in_both_regimes(omega0, around_largest):
    scene = free_rotation(TILTED, omega0=omega0, t_end=10.0)
    moments = scene.principal_moments
    w = TURN.T @ omega0
    assert (np.sum(moments**2 * w**2) > np.sum(moments * w**2) * moments[1]) == around_largest  # L^2 > 2T I2
    assert_solves_the_equations(scene, np.linspace(0.0, 10.0, 97))
    # starts where it was told to, with the identity orientation
    exact = scene.exact([0.0])
    np.testing.assert_allclose(exact["omega_body"][0], omega0, rtol=0, atol=4 * EPS * np.max(np.abs(omega0)))
    np.testing.assert_allclose(exact["quaternion"][0], [1.0, 0.0, 0.0, 0.0], rtol=0, atol=4 * EPS)


def test_exact_invariants_are_the_initial_ones():
    scene = free_rotation(TILTED, omega0=W_AXIS3, t_end=10.0)
    exact = scene.exact(np.linspace(0.0, 10.0, 11))
    tensor = TILTED.tensor
    np.testing.assert_allclose(exact["L_world"], np.broadcast_to(tensor @ W_AXIS3, (11, 3)), rtol=1e-14)
    np.testing.assert_allclose(exact["energy"], 0.5 * W_AXIS3 @ tensor @ W_AXIS3, rtol=1e-14)
    # and the energy of the exact omega at every time is the same
    omega = exact["omega_body"]
    np.testing.assert_allclose(0.5 * np.einsum("ta,ab,tb->t", omega, tensor, omega), exact["energy"], rtol=1e-13)


@pytest.mark.parametrize("omega0", [W_AXIS3, W_AXIS1])
def test_period_is_the_period_of_omega(omega0):
    scene = free_rotation(TILTED, omega0=omega0, t_end=10.0)
    period = scene.period
    t = np.linspace(0.0, period, 13)
    np.testing.assert_allclose(scene.exact(t + period)["omega_body"], scene.exact(t)["omega_body"], rtol=0, atol=1e-13)
    # and no shorter: half a period later w is not the same (the component along the encircled axis
    # keeps its sign, the other two change theirs)
    half = scene.exact(t + period / 2)["omega_body"] - scene.exact(t)["omega_body"]
    assert np.max(np.abs(half)) > 0.1


def test_exact_agrees_with_the_reference_integrator():
    scene = free_rotation(TILTED, omega0=W_AXIS1, t_end=3.0)
    trajectory = simulate(scene, dt=0.01, method="reference")
    exact = scene.exact(trajectory.t)
    assert max_error(trajectory, exact) < 1e-11


@settings(max_examples=25, deadline=None)
@given(moments=st.tuples(*[st.floats(0.2, 1.0)] * 3), omega=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
       turn=st.tuples(*[st.floats(-1.0, 1.0)] * 4))
# a symmetric top spun across its axis, tilted by 9e-12 rad: the body-frame precession rate lam ~ 9e-12 rad/s
# once made the quaternion's precession angle a difference of two O(1) integrals divided by lam (error 1e-5)
@example(moments=(1.0, 0.5, 0.5), omega=(1.0, 0.0, 0.0), turn=(1.0, 0.0, 4.409074841048432e-12, 0.0))
def test_random_bodies_solve_euler_equations(moments, omega, turn):
    a, b, c = sorted(moments)
    assume(a + b >= c and np.linalg.norm(turn) > 0.1)  # a body (triangle inequality); a rotation to draw
    inertia = diagonal(a, b, c).rotated(quat_to_matrix(np.array(turn) / np.linalg.norm(turn)))
    scene = free_rotation(inertia, omega0=omega, t_end=4.0)
    assert_solves_the_equations(scene, np.linspace(0.0, 4.0, 9), tolerance=1e-8)


def test_separatrix_is_the_sech_tanh_limit():
    # I = (3, 4, 6), w = (1, 0.7, 0.5): I1 w1^2 (I2 - I1) = 3 = I3 w3^2 (I3 - I2), so L^2 = 2T I2 exactly.
    inertia = diagonal(3.0, 4.0, 6.0)
    for omega0 in ([1.0, 0.7, 0.5], [-1.0, 0.7, 0.5], [1.0, -0.7, -0.5]):
        scene = free_rotation(inertia, omega0=omega0, t_end=10.0)
        assert scene.period == np.inf
        assert_solves_the_equations(scene, np.linspace(0.0, 10.0, 41))
        # w -> (0, +-A2, 0) along the intermediate axis, A2^2 = (2T I3 - L^2) / (I2 (I3 - I2))
        w = np.array(omega0)
        I = np.array([3.0, 4.0, 6.0])
        A2 = np.sqrt((np.sum(I * w**2) * I[2] - np.sum(I**2 * w**2)) / (I[1] * (I[2] - I[1])))
        late = scene.exact([60.0])["omega_body"][0]
        np.testing.assert_allclose(np.abs(late), [0.0, A2, 0.0], rtol=0, atol=1e-8)
        # it is the limit of the elliptic motion on either side
        for nudge in (1 + 1e-13, 1 - 1e-13):
            near = free_rotation(inertia, omega0=[omega0[0], omega0[1], omega0[2] * nudge], t_end=10.0)
            assert np.isfinite(near.period)
            t = np.linspace(0.0, 5.0, 11)
            np.testing.assert_allclose(near.exact(t)["omega_body"], scene.exact(t)["omega_body"], rtol=0, atol=1e-8)
            np.testing.assert_allclose(near.exact(t)["quaternion"], scene.exact(t)["quaternion"], rtol=0, atol=1e-8)


@pytest.mark.parametrize("body, axis", [
    (Inertia.solid_cylinder(1.5, 0.3, 1.0, axis=[1.0, 1.0, 0.0]), [1.0, 1.0, 0.0]),  # prolate
    (Inertia.disc(2.0, 0.5, axis=[0.0, 1.0, 1.0]), [0.0, 1.0, 1.0]),                  # oblate
])
def test_symmetric_body_precesses_uniformly(body, axis):
    n = np.array(axis) / np.linalg.norm(axis)
    along, across = body.moment(n), body.moment(np.cross(n, [1.0, 0.0, 0.0]))
    omega0 = np.array([0.7, -1.2, 2.0])
    scene = free_rotation(body, omega0=omega0, t_end=6.0)
    t = np.linspace(0.0, 6.0, 25)
    # Closed form: the body precesses about its axis at Omega = (I_along - I_across) w_n / I_across, and
    # R(t) = Rot(L, |L| t / I_across) Rot_body(n, -Omega t).
    w_n = omega0 @ n
    rate = (along - across) * w_n / across
    spin = quat_from_axis_angle(n, rate * t)
    omega = quat_rotate(spin, np.broadcast_to(omega0, (t.size, 3)))
    momentum = body.tensor @ omega0
    orientation = quat_multiply(quat_from_axis_angle(momentum, np.linalg.norm(momentum) * t / across),
                                quat_from_axis_angle(n, -rate * t))
    exact = scene.exact(t)
    np.testing.assert_allclose(exact["omega_body"], omega, rtol=0, atol=1e-13)
    np.testing.assert_allclose(exact["quaternion"], orientation, rtol=0, atol=1e-13)
    assert scene.period == pytest.approx(2 * np.pi / abs(rate), rel=1e-13)
    trajectory = simulate(scene, dt=0.01, method="gauss6")
    assert max_error(trajectory, scene.exact(trajectory.t)) < 1e-12


@pytest.mark.parametrize("inertia, omega0, period", [
    (diagonal(1.0, 2.0, 3.0), [0.0, 0.0, 2.0], 2 * np.pi / 2.0),  # small wobble: lam^2 = w^2 (I3-I1)(I3-I2)/(I1 I2)
    (diagonal(1.0, 2.0, 3.0), [-2.0, 0.0, 0.0], 2 * np.pi / (2.0 * np.sqrt(1.0 / 3.0))),  # (I2-I1)(I3-I1)/(I2 I3)
    (diagonal(1.0, 2.0, 3.0), [0.0, 2.0, 0.0], np.inf),   # unstable equilibrium on the intermediate axis
    (diagonal(1.0, 1.0, 1.5), [1.0, -2.0, 0.0], np.inf),  # in the plane of the two equal moments
    (diagonal(1.0, 1.0, 1.0), [1.0, -2.0, 0.5], np.inf),  # a sphere
    (diagonal(1.0, 2.0, 3.0), [0.0, 0.0, 0.0], np.inf),
])
def test_steady_spins_are_exactly_steady(inertia, omega0, period):
    scene = free_rotation(inertia, omega0=omega0, t_end=5.0)
    t = np.linspace(0.0, 5.0, 6)
    exact = scene.exact(t)
    np.testing.assert_array_equal(exact["omega_body"], np.broadcast_to(omega0, (6, 3)))
    turn = quat_from_axis_angle(omega0, np.linalg.norm(omega0) * t) if np.any(omega0) else np.tile([1.0, 0, 0, 0], (6, 1))
    np.testing.assert_allclose(exact["quaternion"], turn, rtol=0, atol=1e-15)
    assert scene.period == pytest.approx(period, rel=1e-14)


def test_batch_matches_its_items():
    omega0 = np.stack([W_AXIS3, W_AXIS1, -W_AXIS3, [0.0, 0.0, 1.0], [0.1, 2.0, 0.1], W_AXIS1 * 0.5])
    scene = free_rotation(TILTED, omega0=omega0.reshape(2, 3, 3), t_end=2.0)
    assert scene.batch_shape == (2, 3)
    assert scene.period.shape == (2, 3)
    t = np.linspace(0.0, 2.0, 5)
    exact = scene.exact(t)
    assert exact["omega_body"].shape == (5, 2, 3, 3) and exact["quaternion"].shape == (5, 2, 3, 4)
    assert exact["energy"].shape == (5, 2, 3)
    trajectory = simulate(scene, dt=0.01, method="rk4")
    assert trajectory["L_world"].shape == (trajectory.t.size, 2, 3, 3)
    for index in np.ndindex(2, 3):
        one = scene.item(index)
        assert one.batch_shape == () and one.period == scene.period[index]
        single = one.exact(t)
        for name in one.observables:
            np.testing.assert_array_equal(exact[name][(slice(None),) + index], single[name])
        alone = simulate(one, dt=0.01, method="rk4")
        # the same steps; only the order of the final change of axes (one matrix product) may differ
        np.testing.assert_allclose(alone["omega_body"], trajectory["omega_body"][(slice(None),) + index],
                                   rtol=0, atol=8 * EPS)


# ----- the native methods ----------------------------------------------------------------------------------

CASE = free_rotation(TILTED, omega0=W_AXIS3, t_end=2.0)  # the order test's case


@pytest.mark.parametrize("method, dt, order", [
    ("euler", 2.5e-3, 1), ("rk4", 0.05, 4), ("splitting", 0.05, 2), ("yoshida6", 0.1, 6), ("gauss6", 0.2, 6),
])
def test_observed_order_of_accuracy(method, dt, order):
    assert methods.METHOD_ORDER[method] == order
    errors = []
    for step in (dt, dt / 2):
        trajectory = simulate(CASE, dt=step, method=method)
        errors.append(max_error(trajectory, CASE.exact(trajectory.t)))
    observed = np.log2(errors[0] / errors[1])
    assert abs(observed - order) < 0.3, f"{method}: errors {errors}, observed order {observed:.2f}"


def test_small_steps_agree_with_the_exact_solution():
    for method, dt, bound in (("rk4", 1e-3, 1e-11), ("splitting", 1e-4, 1e-7), ("gauss6", 0.01, 1e-12)):
        trajectory = simulate(CASE, dt=dt, method=method)
        assert max_error(trajectory, CASE.exact(trajectory.t), CASE.observables) < bound, method


def test_splitting_keeps_angular_momentum_and_bounds_energy():
    scene = free_rotation(TILTED, omega0=W_AXIS3, t_end=1000.0)
    steps = 100_000
    for method, substeps in (("splitting", 5), ("yoshida6", 35)):
        trajectory = simulate(scene, dt=1e-2, method=method, save_every=100)
        L = trajectory["L_world"]
        drift = np.linalg.norm(L - L[0], axis=-1) / np.linalg.norm(L[0])
        # every exact rotation keeps L_world (the body turns one way, L_body the other): only round-off,
        # a few eps per sub-flow
        assert drift.max() < 4 * EPS * steps * substeps, method
        np.testing.assert_allclose(np.linalg.norm(trajectory["quaternion"], axis=-1), 1.0,
                                   rtol=0, atol=4 * EPS * np.sqrt(steps * substeps))
        if method == "splitting":  # (yoshida6's energy error at this dt is round-off, which wanders)
            energy = np.abs(trajectory["energy"] / trajectory["energy"][0] - 1)
            # symplectic: the energy error stays bounded, no drift over 100 000 steps
            assert energy.max() < 1.5 * energy[: energy.size // 10].max()
    # while rk4 lets L_world drift past that round-off bound
    trajectory = simulate(scene, dt=1e-2, method="rk4", save_every=100)
    L = trajectory["L_world"]
    assert np.max(np.linalg.norm(L - L[0], axis=-1) / np.linalg.norm(L[0])) > 4 * EPS * steps * 5


def test_euler_reports_the_quaternion_as_integrated():
    # y += dt f(y) with q' = 1/2 q (0, w): (0, w) q is orthogonal to q, so |q_{k+1}|^2 = |q_k|^2 (1 + dt^2 |w_k|^2 / 4).
    dt = 1e-2
    trajectory = simulate(CASE, dt=dt, method="euler")
    w2 = np.sum(trajectory["omega_body"] ** 2, axis=-1)
    expected = np.sqrt(np.concatenate([[1.0], np.cumprod(1 + dt**2 * w2[:-1] / 4)]))
    np.testing.assert_allclose(np.linalg.norm(trajectory["quaternion"], axis=-1), expected, rtol=1e-13)
    assert expected[-1] - 1 > 1e-3  # the drift is visible


@pytest.mark.parametrize("method", ["splitting", "yoshida6"])
def test_symmetric_methods_are_time_reversible(method):
    model = CASE.native()
    step, weights = model.split[method]
    y0, params = np.ascontiguousarray(model.y0), np.ascontiguousarray(model.params)
    nsteps = 2000
    out = np.empty((2,) + y0.shape)
    integrators.run_composed_flow(step, weights, y0, params, 0.01, nsteps, nsteps, out)
    turned = out[-1].copy()
    turned[:, 4:] *= -1  # w -> -w reverses the motion
    assert np.max(np.abs(turned - y0)) > 0.1  # it went somewhere
    integrators.run_composed_flow(step, weights, turned, params, 0.01, nsteps, nsteps, out)
    back = out[-1].copy()
    back[:, 4:] *= -1
    # round-off only: a few units of the last bit of the state's size for each of the 2 nsteps x stages flows
    # (the forward and backward errors do not cancel: 4.5e-12 for splitting and 3.3e-11 for yoshida6)
    budget = 4 * EPS * np.abs(y0).max() * 2 * nsteps * len(weights)
    np.testing.assert_allclose(back, y0, rtol=0, atol=budget)


def test_tennis_racket_flips_with_the_exact_period():
    # Spin mostly about the intermediate axis: w2 reverses again and again, every scene.period.
    scene = free_rotation(diagonal(1.0, 2.0, 3.0), omega0=[0.02, 3.0, 0.02], t_end=60.0)
    period = scene.period
    assert 10.0 < period < 25.0
    dt = 1e-3
    trajectory = simulate(scene, dt=dt, method="rk4")
    w2 = trajectory["omega_body"][:, 1]
    assert w2.min() < -2.99 and w2.max() > 2.99  # a full flip, not a wobble
    falling = np.flatnonzero((w2[:-1] > 0) & (w2[1:] <= 0))
    rising = np.flatnonzero((w2[:-1] < 0) & (w2[1:] >= 0))

    def crossings(i):  # linear interpolation: w2'' = 0 where w2 = 0 (sn'' = 0 at sn = 0)
        return trajectory.t[i] + dt * w2[i] / (w2[i] - w2[i + 1])

    down, up = crossings(falling), crossings(rising)
    assert down.size >= 3 and up.size >= 2
    np.testing.assert_allclose(np.diff(down), period, rtol=1e-7)
    np.testing.assert_allclose(np.diff(up), period, rtol=1e-7)
    # and when: the exact solution crosses at the same times
    exact_w2 = scene.exact(down)["omega_body"][:, 1]
    np.testing.assert_allclose(exact_w2, 0.0, rtol=0, atol=1e-6)


def test_no_verlet_for_free_rotation():
    for method in ("verlet", "symplectic_euler"):
        with pytest.raises(MethodNotApplicable, match="splitting"):
            simulate(CASE, dt=0.01, method=method)


# ----- what other simulators are given ---------------------------------------------------------------------

def test_layout_box_has_the_principal_moments_and_the_centre_stays_put():
    body = Inertia(2.0, np.zeros(3), np.diag([1.0, 2.0, 2.5])).rotated(TURN).translated([0.1, -0.2, 0.3])
    scene = free_rotation(body, omega0=W_AXIS3, t_end=1.0)
    assert scene.gravity == 0.0
    layout = scene.layout
    (shape,) = layout.bodies[0].shapes
    assert shape.kind == "box"
    box = Inertia.box(body.mass, 2 * np.array(shape.size)).rotated(np.array(shape.quat))
    np.testing.assert_allclose(box.tensor, body.tensor, rtol=0, atol=1e-14)
    np.testing.assert_allclose(shape.pos, body.com)
    (joint,) = layout.joints
    velocity, omega = (np.array(v) for v in joint.qvel0)
    np.testing.assert_allclose(omega, W_AXIS3)
    # the body-frame origin moves so that the centre of mass is at rest: v + w x com = 0
    np.testing.assert_allclose(velocity + np.cross(omega, body.com), 0.0, rtol=0, atol=1e-15)
    # a lamina (I1 + I2 = I3, as TILTED) has no thickness: its box gets the thinnest side allowed
    (lamina,) = free_rotation(TILTED, omega0=W_AXIS3, t_end=1.0).layout.bodies[0].shapes
    assert min(lamina.size) == pytest.approx(MIN_BOX_FRACTION * max(lamina.size), rel=1e-12)


def test_observe_recovers_the_observables_from_world_states():
    scene = free_rotation(TILTED, omega0=W_AXIS1, t_end=3.0)
    t = np.linspace(0.0, 3.0, 31)
    exact = scene.exact(t)
    quat = exact["quaternion"]
    states = BodyStates(com=np.zeros((31, 3)), quat=quat, velocity=np.zeros((31, 3)),
                        omega=quat_rotate(quat, exact["omega_body"]))
    observed = scene.observe(t, {"body": states}, {})
    for name in scene.observables:
        np.testing.assert_allclose(observed[name], exact[name], rtol=0, atol=1e-13)
    # the native model reports the same frame: its first sample is the initial state
    native = simulate(scene, dt=0.01, method="splitting", t_end=0.01)
    for name in scene.observables:
        np.testing.assert_allclose(native[name][0], exact[name][0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(quat_multiply(native["quaternion"][0], quat_conjugate(quat[0])), [1, 0, 0, 0],
                               rtol=0, atol=1e-15)


# ----- bad input -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    (dict(inertia="box", omega0=[1, 2, 3]), "Inertia"),
    (dict(inertia=Inertia.rod(1.0, 2.0), omega0=[1, 2, 3]), "principal moment > 0"),
    (dict(inertia=Inertia.point_masses([1.0], [[0, 0, 0]]), omega0=[1, 2, 3]), "principal moment > 0"),
    (dict(inertia=TILTED, omega0=[1, 2]), "shape"),
    (dict(inertia=TILTED, omega0=1.0), "shape"),
    (dict(inertia=TILTED, omega0=[1, np.nan, 3]), "finite"),
    (dict(inertia=TILTED, omega0=[1, 2, 3], t_end=0.0), "t_end"),
])
def test_bad_input_is_refused(kwargs, match):
    kwargs.setdefault("t_end", 1.0)
    with pytest.raises(ValueError, match=match):
        free_rotation(**kwargs)


def test_gravity_is_refused_and_batch_items_checked():
    with pytest.raises(ValueError, match="gravity"):
        FreeRotation(name="free_rotation", t_end=1.0, gravity=9.81, inertia=TILTED, omega0=[1, 2, 3])
    with pytest.raises(TypeError):
        free_rotation(TILTED, omega0=[1, 2, 3], t_end=1.0, gravity=9.81)  # the factory takes none
    batch = free_rotation(TILTED, omega0=np.ones((4, 3)), t_end=1.0)
    with pytest.raises(ValueError, match="index"):
        batch.item(slice(0, 2))
    with pytest.raises(ValueError, match="batch"):
        batch.layout  # noqa: B018
