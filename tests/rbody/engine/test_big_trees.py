"""Issue 23: the stability estimate of a big tree costs a few dozen evaluations of its dynamics, whatever its size
(Arnoldi's iteration on Jacobian-vector products), and agrees with the dense Jacobian's spectral radius."""

from __future__ import annotations

import importlib
import tracemalloc

import numpy as np
import pytest

from rbody import Body, Inertia, Joint, Layout, Scene, simulate
from rbody.engine import integrators

stability = importlib.import_module("rbody.engine.stability")


def ball_tree(bodies: int, seed: int = 1, kind: str = "ball") -> Scene:
    """Bodies on ball (or hinge) joints, each hung from a random earlier one (benchmarks/stability_estimate.py)."""
    rng = np.random.default_rng(seed)
    parts, joints = [], []
    for k in range(bodies):
        parent = "world" if k == 0 else f"b{int(rng.integers(0, k))}"
        offset = (rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), -0.3) if k else (0.0, 0.0, 0.0)
        inertia = Inertia(rng.uniform(0.5, 2.0), (0.0, 0.0, -0.15), np.diag(rng.uniform(0.03, 0.05, 3)))
        parts.append(Body(f"b{k}", inertia, parent=parent, pos=offset))
        axis = tuple(rng.normal(size=3)) if kind == "hinge" else (0.0, 0.0, 1.0)
        joints.append(Joint(f"j{k}", kind, f"b{k}", axis=axis))
    return Scene.from_layout(Layout(bodies=tuple(parts), joints=tuple(joints)), t_end=1.0)


def dense_rate(model, y: np.ndarray) -> float:
    n = y.size
    jacobian = np.empty((1, n, n))
    stability._jacobians(integrators.pointer_function(model.rhs), np.ascontiguousarray(y[None]),
                         np.ascontiguousarray(model.params[:1]), stability.JACOBIAN_STEP, jacobian)
    return float(np.max(np.abs(np.linalg.eigvals(jacobian[0]))))


@pytest.mark.parametrize("bodies, kind, moving", [(12, "ball", False), (40, "hinge", True), (25, "ball", True)])
def test_the_krylov_rate_equals_the_dense_spectral_radius(bodies, kind, moving):
    """At rest and at a random moving state (real and complex eigenvalues): within 0.2 % of the dense Jacobian's
    spectral radius, the estimate before issue 23."""
    scene = ball_tree(bodies, seed=bodies, kind=kind)
    model = scene.native_model
    y = np.array(model.y0[0])
    assert y.size > stability.DENSE_STATE_LIMIT  # the Krylov path
    if moving:
        nq, nv = scene.multibody.nq, scene.multibody.nv
        y[nq:nq + nv] = np.random.default_rng(7).normal(0.0, 2.0, nv)
    krylov = stability.krylov_rate(model.rhs, y, np.asarray(model.params[0]))
    assert krylov == pytest.approx(dense_rate(model, y), rel=2e-3)


def test_a_thousand_body_tree_costs_a_few_dozen_evaluations_and_little_memory(monkeypatch):
    """1,000 bodies on ball joints (a state of 10,000 numbers): the dense estimate took 20,000 evaluations, 41 s
    and 2.6 GB; now at most 400 evaluations and 20 MB (benchmarks/stability_estimate.py prints the seconds)."""
    scene = ball_tree(1000)
    model = scene.native_model
    calls = []
    original = stability._jvp
    monkeypatch.setattr(stability, "_jvp", lambda *a: calls.append(2) or original(*a))
    tracemalloc.start()
    try:
        rate = float(stability.fastest_rate(scene, "rk4")[0])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert model.y0.shape[1] == 10_000
    assert 0 < rate < np.inf
    assert sum(calls) <= 400 and peak < 20e6, (sum(calls), peak)


def test_a_big_tree_runs_a_few_steps():
    run = simulate(ball_tree(300), dt=1e-3, t_end=5e-3, method="rk4")
    assert run["qpos"].shape == (6, 1200) and np.all(np.isfinite(run["qpos"]))


def test_kernels_whose_workspace_is_on_the_heap_keep_it_while_they_work():
    """1,000 hinges: a workspace of about 1 MB, beyond the stack's (multibody.STACK_FLOATS) and malloc's mmap threshold,
    allocated by the kernel itself and read through raw pointers. Before, numba freed it after the pointer was
    taken (memory.keep_alive): building the tree's Multibody (its pivot check) and tree_rhs crashed the process.
    Each kernel is checked against another that shares its passes: tree_rhs's accelerations against
    forward_dynamics, bit for bit (the same compiled passes); tree_accel against tree_rhs at rest; each lane of
    tree_rhs_lanes against tree_rhs."""
    from rbody.engine import multibody as mb

    scene = ball_tree(1000, kind="hinge")
    model = scene.multibody
    p = np.array(model.params)
    assert mb.workspace_size(p) > mb.STACK_FLOATS and mb.workspace_size(p) * 8 > 128 * 1024  # glibc's first threshold
    assert mb.runs_in_lanes(model)
    rng = np.random.default_rng(3)
    lanes = mb.LANES
    y = np.zeros((lanes, model.nq + model.nv))
    y[:, :model.nq] = rng.uniform(-0.3, 0.3, (lanes, model.nq))
    y[:, model.nq:] = rng.uniform(-1.0, 1.0, (lanes, model.nv))
    rates = np.empty_like(y)
    for lane in range(lanes):
        mb.tree_rhs(np.array(y[lane]), p, rates[lane])
    assert np.all(np.isfinite(rates))
    np.testing.assert_array_equal(rates[:, model.nq:], model.forward_dynamics(y[:, :model.nq], y[:, model.nq:]))
    np.testing.assert_array_equal(rates[:, :model.nq], y[:, model.nq:])
    at_rest = np.empty(model.nv)
    mb.tree_accel(np.array(y[0, :model.nq]), p, at_rest)
    still = np.array(y[0])
    still[model.nq:] = 0.0
    expected = np.empty_like(still)
    mb.tree_rhs(still, p, expected)
    np.testing.assert_array_equal(at_rest, expected[model.nq:])
    out = np.full(y.size, np.nan)
    mb.tree_rhs_lanes(np.ascontiguousarray(y.T).reshape(-1), p, out)
    np.testing.assert_array_equal(out.reshape(-1, lanes).T, rates)
