"""The built-in families on the general engine: each scene's own Layout run natively by rbody's multibody
engine (engine_model) against the family's hand-written kernel (hand_model, the oracle) to round-off at the
same dt, and against the exact solution (the rod's elliptic functions, the chain's energy and normal modes,
free rotation's Jacobi-elliptic motion); the observed order of rk4 through the engine; and the switch
(FAST_PATH, HAND_KERNEL_MAX_LINKS) that decides which of the two native() runs."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from rbody import Inertia, Scene, simulate
from rbody.engine import integrators
from rbody.motion import quat_to_matrix
from rbody.scenes import compound_pendulum, free_rotation, pendulum_chain, swinging_rod, two_body

# the modules (rbody.scenes exports factory functions of the same names)
pendulum_module, chain_module, rotation_module = (importlib.import_module(f"rbody.scenes.{name}")
                                                  for name in ("pendulum", "chain", "free_rotation"))

EPS = np.finfo(float).eps


def run(model, method: str, dt: float, steps: int) -> dict[str, np.ndarray]:
    """The observables of `steps` steps of `method` on a native model, every step saved: (steps + 1, B, ...)."""
    out = np.empty((steps + 1,) + model.y0.shape)
    y0, params = np.ascontiguousarray(model.y0), np.ascontiguousarray(model.params)
    if method == "rk4":
        failed = integrators.run_rk4(model.rhs, y0, params, dt, steps, 1, out, finish=model.finish)
    elif method == "euler":
        failed = integrators.run_euler(model.rhs, y0, params, dt, steps, 1, out, finish=model.finish)
    elif method == "verlet":
        failed = integrators.run_composed_verlet(model.accel, np.ones(1), y0, params, dt, steps, 1, out)
    elif method in model.split:
        step, weights = model.split[method]
        failed = integrators.run_composed_flow(step, weights, y0, params, dt, steps, 1, out)
    else:
        raise ValueError(method)
    assert np.all(failed < 0)
    data = model.observe(np.arange(steps + 1) * dt, out)
    return {name: np.asarray(value() if callable(value) else value) for name, value in data.items()}


def largest_difference(a: dict, b: dict, names) -> float:
    return max(float(np.max(np.abs(a[name] - b[name]))) for name in names)


# ----- the swinging rod and the compound pendulum ------------------------------------------------------------

# A batch that varies the rod's physics too (length, mass), swinging, whirling and near the top.
ROD_BATCH = swinging_rod(np.array([[0.5], [2.0]]), np.array([[1.3], [0.4]]), theta0=np.array([0.1, 1.0, 3.1, -1.0]),
                         omega0=np.array([0.0, 1.0, 0.0, 9.0]), t_end=2.0)
# A disc pivoted off its centre, turned so that its body axes are not the world's, on a tilted body axis.
TILT = quat_to_matrix(np.array([0.9, 0.2, -0.3, 0.1]) / np.linalg.norm([0.9, 0.2, -0.3, 0.1]))
DISC = compound_pendulum(Inertia.disc(2.0, 0.3, "y").rotated(TILT).translated([0.05, 0.1, -0.02]),
                         pivot=(0.3, 0.1, -0.02), axis=TILT @ np.array([0.0, 1.0, 0.0]),
                         theta0=np.array([0.5, 2.0]), omega0=np.array([0.0, -1.0]), t_end=2.0)


@pytest.mark.parametrize("scene", [ROD_BATCH, DISC], ids=["rod batch", "tilted disc"])
@pytest.mark.parametrize("method", ["rk4", "verlet", "euler"])
def test_pendulum_engine_equals_the_hand_kernel(scene, method):
    """Same method, same dt: the engine's hinge (qpos, qvel) is the hand kernel's (theta, omega) to round-off."""
    engine = run(scene.engine_model(), method, 1e-2, 200)
    hand = run(scene.hand_model(), method, 1e-2, 200)
    assert engine["theta"].shape == hand["theta"].shape == (201, int(np.prod(scene.batch_shape)))
    assert largest_difference(engine, hand, ("theta", "omega", "energy")) < 1e-12


@pytest.mark.parametrize("scene", [ROD_BATCH, DISC], ids=["rod batch", "tilted disc"])
def test_pendulum_engine_agrees_with_the_elliptic_solution(scene):
    engine = run(scene.engine_model(), "rk4", 1e-3, 2000)
    exact = scene.exact(np.arange(2001) * 1e-3)
    shape = engine["theta"].shape
    assert np.max(np.abs(engine["theta"] - exact["theta"].reshape(shape))) < 1e-9
    assert np.max(np.abs(engine["energy"] - exact["energy"].reshape(shape))) < 1e-9


def test_rk4_through_the_engine_is_fourth_order():
    scene = swinging_rod(1.0, theta0=1.0, t_end=2.0)
    model = scene.engine_model()
    exact_end = scene.exact([2.0])["theta"][0]
    steps = np.array([50, 100, 200, 400])
    errors = [abs(run(model, "rk4", 2.0 / n, int(n))["theta"][-1, 0] - exact_end) for n in steps]
    slope = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert slope == pytest.approx(4.0, abs=0.2)


def test_fast_path_chooses_the_pendulum_kernel(monkeypatch):
    scene = swinging_rod(1.0, theta0=1.0, t_end=1.0)
    hand, engine = scene.hand_model(), scene.engine_model()
    assert hand.rhs is pendulum_module.pendulum_rhs and engine.rhs is not hand.rhs
    for fast, expected in ((True, hand), (False, engine)):
        monkeypatch.setattr(pendulum_module, "FAST_PATH", fast)
        fresh = swinging_rod(1.0, theta0=1.0, t_end=1.0)  # native_model is built once per scene
        assert fresh.native_model.rhs is expected.rhs
        np.testing.assert_array_equal(fresh.native_model.params, expected.params)
        # and simulate runs that kernel
        for method in ("rk4", "verlet"):
            through = simulate(fresh, dt=1e-2, method=method)
            alone = run(expected, method, 1e-2, 100)
            np.testing.assert_array_equal(through["theta"], alone["theta"][:, 0])


def test_a_wrong_state_mapping_is_caught():
    """The comparison above can fail: theta read from the engine's qvel instead of its qpos (a planted bug)."""
    model = ROD_BATCH.engine_model()
    wrong = model.__class__(**{**model.__dict__, "observe": lambda t, y: {"theta": y[..., 1], "omega": y[..., 0],
                                                                          "energy": y[..., 0]}})
    assert largest_difference(run(wrong, "rk4", 1e-2, 50), run(ROD_BATCH.hand_model(), "rk4", 1e-2, 50),
                              ("theta",)) > 1e-2


# ----- the pendulum chain ------------------------------------------------------------------------------------

CHAIN = pendulum_chain([1.0, 0.7, 1.3], masses=[1.0, 2.0, 0.5], theta0=np.array([[0.3, -0.5, 1.0], [2.0, 1.0, 0.1]]),
                       omega0=np.array([0.1, 0.2, -0.3]), t_end=2.0)


@pytest.mark.parametrize("method", ["rk4", "euler"])
def test_chain_engine_equals_the_hand_kernel(method):
    """The engine's hinges hold angles relative to the parent rod; summed, they are the hand kernel's absolute
    angles, to round-off."""
    engine = run(CHAIN.engine_model(), method, 1e-2, 200)
    hand = run(CHAIN.hand_model(), method, 1e-2, 200)
    assert engine["theta"].shape == (201, 2, 3)
    assert largest_difference(engine, hand, ("theta", "omega", "energy")) < 1e-11


def test_chain_relative_angles_are_not_the_absolute_ones():
    """The mapping matters: the engine's raw qpos (relative angles) differ from the absolute ones, so the test
    above would fail without the cumulative sum."""
    model = CHAIN.engine_model()
    out = np.empty((2,) + model.y0.shape)
    integrators.run_rk4(model.rhs, model.y0, model.params, 1e-2, 1, 1, out, finish=model.finish)
    absolute = run(CHAIN.hand_model(), "rk4", 1e-2, 1)["theta"]
    assert np.max(np.abs(out[..., :3] - absolute)) > 0.1
    np.testing.assert_allclose(np.cumsum(out[..., :3], axis=-1), absolute, rtol=0, atol=1e-14)


def test_chain_engine_gauss6_keeps_energy_and_meets_the_reference(monkeypatch):
    """gauss6 through the engine is symplectic (over 60 s the energy error stays at the level of the first
    6 s) and at dt = 1e-3 meets the hand kernel's DOP853 reference (rtol 1e-13) to a few 1e-13."""
    monkeypatch.setattr(chain_module, "HAND_KERNEL_MAX_LINKS", 0)  # every chain on the engine
    scene = pendulum_chain(2, theta0=[1.0, 2.0], t_end=60.0)
    assert scene.native_model.rhs is not chain_module.chain_rhs
    trajectory = simulate(scene, dt=1e-2, method="gauss6")
    error = np.abs(trajectory["energy"] - trajectory["energy"][0])
    assert error.max() < 1.5 * error[: error.size // 10].max()
    scene = pendulum_chain([1.0, 0.7], masses=[1.0, 2.0], theta0=[1.0, 2.0], omega0=[0.0, -1.0], t_end=3.0)
    assert scene.native_model.rhs is not chain_module.chain_rhs
    reference = simulate(scene, dt=1e-3, method="reference")  # DOP853 through the engine
    monkeypatch.setattr(chain_module, "HAND_KERNEL_MAX_LINKS", chain_module.MAX_LINKS)
    hand_reference = simulate(pendulum_chain([1.0, 0.7], masses=[1.0, 2.0], theta0=[1.0, 2.0], omega0=[0.0, -1.0],
                                             t_end=3.0), dt=1e-3, method="reference")
    engine = simulate(scene, dt=1e-3, method="gauss6")
    assert np.max(np.abs(engine["theta"] - hand_reference["theta"])) < 2e-12
    assert np.max(np.abs(reference["theta"] - hand_reference["theta"])) < 2e-12


@pytest.mark.parametrize("mode", [0, 1])
def test_chain_engine_swings_in_a_normal_mode(mode, monkeypatch):
    """Released at rest in a normal mode (K v = w^2 M0 v, the scene's normal_modes) with amplitude eps, the
    chain swings as eps v cos(w t) up to O(eps^2) relative: through the engine too."""
    monkeypatch.setattr(chain_module, "HAND_KERNEL_MAX_LINKS", 0)
    lengths, masses, eps = (1.0, 0.5), (2.0, 1.0), 1e-4
    w, shapes = pendulum_chain(lengths, masses=masses, theta0=[0.0, 0.0], t_end=1.0).normal_modes()
    v = shapes[:, mode] / np.abs(shapes[:, mode]).max()
    scene = pendulum_chain(lengths, masses=masses, theta0=eps * v, t_end=10.0)
    trajectory = simulate(scene, dt=1e-3, method="gauss6")
    assert np.max(np.abs(trajectory["theta"] / eps - np.outer(np.cos(w[mode] * trajectory.t), v))) < 1e-6


def test_rk4_on_the_chain_engine_is_fourth_order():
    """Largest error over 2 s (every 0.1 s) against the hand kernel's DOP853 reference at rtol 1e-13; at a
    moderate amplitude, where the error is in its asymptotic regime from 100 steps (at theta0 = (1, -0.5) the
    ratios are still 36, 52, 42 at 100 to 800 steps)."""
    scene = pendulum_chain([1.0, 0.5], masses=[2.0, 1.0], theta0=[0.5, 0.3], t_end=2.0)
    truth = simulate(scene, dt=0.1, method="reference")["theta"]  # hand kernel, DOP853 at rtol 1e-13
    model = scene.engine_model()
    steps = np.array([100, 200, 400])
    errors = [np.max(np.abs(run(model, "rk4", 2.0 / n, int(n))["theta"][:: n // 20, 0] - truth)) for n in steps]
    slope = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert slope == pytest.approx(4.0, abs=0.3)


def test_the_chain_switch_chooses_by_the_number_of_rods(monkeypatch):
    limit = chain_module.HAND_KERNEL_MAX_LINKS
    assert 0 <= limit <= chain_module.MAX_LINKS
    for n in sorted({1, max(limit, 1), min(limit + 1, chain_module.MAX_LINKS), chain_module.MAX_LINKS}):
        scene = pendulum_chain(n, theta0=np.full(n, 0.2), t_end=1.0)
        assert (scene.native_model.rhs is chain_module.chain_rhs) == (n <= limit), n
    for value, hand_kernel in ((0, False), (chain_module.MAX_LINKS, True)):
        monkeypatch.setattr(chain_module, "HAND_KERNEL_MAX_LINKS", value)
        two = pendulum_chain(2, theta0=[0.2, 0.3], t_end=1.0)
        assert (two.native_model.rhs is chain_module.chain_rhs) == hand_kernel
        assert two.native_model.y0.shape == (1, 4)
        trajectory, hand = simulate(two, dt=1e-2, method="rk4"), run(two.hand_model(), "rk4", 1e-2, 100)
        assert trajectory["theta"].shape == (101, 2)
        difference = np.max(np.abs(trajectory["theta"] - hand["theta"][:, 0]))
        assert difference == 0 if hand_kernel else 0 < difference < 1e-12


# ----- free rotation -----------------------------------------------------------------------------------------

# Principal axes not the Inertia's, and the centre of mass away from the body origin.
BODY = Inertia(2.0, np.array([0.1, -0.2, 0.3]), np.diag([1.0, 2.0, 3.0])).rotated(TILT)
SPIN = free_rotation(BODY, omega0=np.array([TILT @ [1.0, 0.5, 2.0], TILT @ [2.0, 0.5, 0.3]]), t_end=2.0)


def test_free_rotation_engine_equals_the_hand_kernel_under_rk4():
    """Euler's equations are the same to round-off; the orientation is integrated differently (the engine turns
    its quaternion by exp of a rotation vector, Runge-Kutta-Munthe-Kaas; the hand kernel integrates
    q' = q (0, w)/2 as a vector): both 4th order, so they agree to the methods' error, not to round-off."""
    engine = run(SPIN.engine_model(), "rk4", 1e-2, 200)
    hand = run(SPIN.hand_model(), "rk4", 1e-2, 200)
    exact = SPIN.exact(np.arange(201) * 1e-2)
    assert largest_difference(engine, hand, ("omega_body", "energy")) < 1e-13
    for name in ("quaternion", "L_world"):
        assert np.max(np.abs(engine[name] - exact[name])) < 2e-8
        assert np.max(np.abs(hand[name] - exact[name])) < 2e-8
    # the engine's quaternion stays unit by construction; the hand kernel's drifts
    assert np.max(np.abs(np.linalg.norm(engine["quaternion"], axis=-1) - 1)) < 8 * EPS
    assert np.max(np.abs(np.linalg.norm(hand["quaternion"], axis=-1) - 1)) > 1e-12


@pytest.mark.parametrize("method", ["splitting", "yoshida6"])
def test_free_rotation_engine_runs_the_family_splitting(method):
    """On the engine's state, splitting and yoshida6 are the family's own flows: equal to the hand kernel's to
    round-off (the state is mapped to the principal frame and back in every flow: a few ulp each, which the
    tumbling carries along), the centre of mass at rest."""
    model = SPIN.engine_model()
    step, weights = model.split[method]
    engine = run(model, method, 1e-2, 200)
    hand = run(SPIN.hand_model(), method, 1e-2, 200)
    scale = max(float(np.max(np.abs(hand[name]))) for name in SPIN.observables)
    flows = 200 * weights.size
    assert largest_difference(engine, hand, SPIN.observables) < 20 * EPS * flows * scale
    out = np.empty((201,) + model.y0.shape)
    integrators.run_composed_flow(step, weights, model.y0, model.params, 1e-2, 200, 1, out)
    centre = out[..., 0:3] + np.einsum("...ab,b->...a", quat_to_matrix(out[..., 3:7]), BODY.com)
    assert np.max(np.abs(centre - BODY.com)) < 20 * EPS * flows * np.linalg.norm(BODY.com)


def test_free_rotation_engine_agrees_with_the_jacobi_elliptic_solution():
    engine = run(SPIN.engine_model(), "rk4", 1e-3, 2000)
    exact = SPIN.exact(np.arange(2001) * 1e-3)
    assert largest_difference(engine, exact, SPIN.observables) < 1e-11


def test_rk4_on_the_free_rotation_engine_is_fourth_order():
    model = SPIN.engine_model()
    exact = SPIN.exact([2.0])
    steps = np.array([40, 80, 160])
    errors = [largest_difference({k: v[-1] for k, v in run(model, "rk4", 2.0 / n, int(n)).items()},
                                 {k: v[0] for k, v in exact.items()}, ("omega_body", "quaternion")) for n in steps]
    slope = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert slope == pytest.approx(4.0, abs=0.3)


def test_fast_path_chooses_the_free_rotation_kernel(monkeypatch):
    for fast in (True, False):
        monkeypatch.setattr(rotation_module, "FAST_PATH", fast)
        scene = free_rotation(BODY, omega0=TILT @ [1.0, 0.5, 2.0], t_end=1.0)
        model = scene.native_model
        assert (model.rhs is rotation_module.free_rotation_rhs) == fast
        assert model.y0.shape == ((1, 7) if fast else (1, 16))  # (q, w) or the engine's (qpos, qvel, phi)
        for method in ("rk4", "splitting"):
            trajectory = simulate(scene, dt=1e-2, method=method)
            exact = scene.exact(trajectory.t)
            assert largest_difference(trajectory, exact, ("omega_body", "energy")) < 2e-4, (fast, method)


# ----- the two-body problem -----------------------------------------------------------------------------------

def test_two_body_stays_on_its_kernel_for_the_engine_holds_no_pair_force():
    """The decision documented in rbody.scenes.two_body: the engine, given the scene's Layout, moves both bodies
    uniformly (no attraction), so the scene's own kernel, which follows the Kepler orbit, is its native model.
    Should the engine gain pair forces, this fails and the decision is to be revisited."""
    two_body_module = importlib.import_module("rbody.scenes.two_body")
    scene = two_body(1.0, 0.5, separation=1.0, relative_velocity=1.2, t_end=2.0)
    assert not two_body_module.ENGINE_PATH and scene.native_model.rhs is two_body_module.two_body_rhs
    free = simulate(Scene.from_layout(scene.layout, t_end=2.0, gravity=0.0), dt=1e-2, method="rk4")
    np.testing.assert_allclose(free["qpos"], free["qpos"][0] + np.outer(free.t, free["qvel"][0]), rtol=0, atol=1e-12)
    own = simulate(scene, dt=1e-2, method="rk4")
    exact = scene.exact(own.t)
    assert np.max(np.abs(own["r1"] - exact["r1"])) < 1e-6
    body1 = np.stack([free["qpos"][:, 0], np.zeros(free.t.size), free["qpos"][:, 1]], axis=-1)  # x, z slides
    np.testing.assert_allclose(body1[0], exact["r1"][0], rtol=0, atol=1e-15)
    assert np.max(np.abs(body1 - exact["r1"])) > 0.1


# ----- every method of every family, through simulate, on both paths ----------------------------------------

def both_paths(monkeypatch, module, constant: str, make, method: str, dt: float):
    """simulate(make(), dt, method) with the family's switch set to the engine, then to the hand kernel."""
    runs = []
    for value in (False, True) if constant == "FAST_PATH" else (0, chain_module.MAX_LINKS):
        monkeypatch.setattr(module, constant, value)
        scene = make()  # a new scene: native_model is built once per scene
        runs.append(simulate(scene, dt=dt, method=method))
    return runs[0], runs[1]


# the same dt, the same method: equal to round-off, except the adaptive reference (DOP853 at rtol 1e-13 picks its
# own steps from values that differ in their last bits: 2.5e-12 measured on the chain)
SAME_BOUND = {"reference": 1e-10}


@pytest.mark.parametrize("method", pendulum_module.PENDULUM_METHODS)
def test_every_pendulum_method_runs_on_the_engine(method, monkeypatch):
    engine, hand = both_paths(monkeypatch, pendulum_module, "FAST_PATH",
                              lambda: swinging_rod(1.0, theta0=2.0, omega0=0.5, t_end=2.0), method, 1e-2)
    assert largest_difference(engine, hand, ("theta", "omega", "energy")) < SAME_BOUND.get(method, 1e-12)


@pytest.mark.parametrize("method", chain_module.CHAIN_METHODS)
def test_every_chain_method_runs_on_the_engine(method, monkeypatch):
    engine, hand = both_paths(monkeypatch, chain_module, "HAND_KERNEL_MAX_LINKS",
                              lambda: pendulum_chain([1.0, 0.5, 0.8], theta0=[0.5, -0.3, 1.0], t_end=1.0), method, 5e-3)
    assert largest_difference(engine, hand, ("theta", "omega", "energy")) < SAME_BOUND.get(method, 1e-12)


@pytest.mark.parametrize("method", rotation_module.FREE_ROTATION_METHODS)
def test_every_free_rotation_method_runs_on_the_engine(method, monkeypatch):
    """omega_body and energy to round-off under every method; the orientation too under the family's own flows
    (splitting, yoshida6), and within the methods' error of the exact one under the others (module docstring)."""
    engine, hand = both_paths(monkeypatch, rotation_module, "FAST_PATH",
                              lambda: free_rotation(BODY, omega0=TILT @ [1.0, 0.5, 2.0], t_end=1.0), method, 1e-2)
    own_flows = method in ("splitting", "yoshida6")
    names = SPIN.observables if own_flows else ("omega_body", "energy")
    # the flows map the state to the principal frame and back: a few ulp per flow (the splitting test above),
    # 100 steps of up to 7 flows on observables of size ~10
    bound = 20 * EPS * 100 * 7 * 10 if own_flows else SAME_BOUND.get(method, 1e-12)
    assert largest_difference(engine, hand, names) < bound
    exact = SPIN.item(0).exact(engine.t)
    bound = {"euler": 0.1, "splitting": 2e-4, "rk4": 1e-8}.get(method, 1e-10)  # each method's error at dt = 1e-2
    assert largest_difference(engine, exact, SPIN.observables) < bound
