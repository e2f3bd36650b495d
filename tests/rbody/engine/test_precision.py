"""Issue 23: what float64 cannot carry is refused with that reason (hinge angles too large to carry a step); what it
can carry runs (coordinates far from the origin: each tree is computed about its own origin); a stability verdict is
never "use dt <= 0 s"."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbody import Body, Inertia, Joint, Layout, Scene, SimulationError, simulate

ROD = Inertia.rod(1.0, 1.0, "z").translated([0.0, 0.0, -0.5])


def pendulum_at(x: float, qpos0: float = 0.3, t_end: float = 1.0) -> Scene:
    layout = Layout(bodies=(Body("arm", ROD, pos=(x, 0.0, 0.0)),),
                    joints=(Joint("pivot", "hinge", "arm", axis=(0.0, 1.0, 0.0), qpos0=qpos0),))
    return Scene.from_layout(layout, t_end=t_end)


def test_a_pendulum_a_million_metres_away_runs_as_it_does_at_the_origin():
    """Before: refused as "the mass matrix is singular" (the engine formed inertias about the world origin). Each tree
    is now computed about its own origin: the run equals the one at the origin (tests/rbody/engine/
    test_far_from_origin.py checks more)."""
    near, far = pendulum_at(0.0), pendulum_at(1e6)
    a, b = simulate(near, dt=1e-3, method="rk4"), simulate(far, dt=1e-3, method="rk4")
    np.testing.assert_array_equal(b["qpos"], a["qpos"])


def free_body(moments: float, pos=(0.0, 0.0, 0.0), qvel0=(0.0,) * 6, gravity: float = 9.81) -> Scene:
    body = Body("b", Inertia(1.0, np.zeros(3), moments * np.diag([1.0, 2.0, 2.5])), pos=pos)
    return Scene.from_layout(Layout(bodies=(body,), joints=(Joint("f", "free", "b", qvel0=qvel0),)), t_end=1.0,
                             gravity=gravity)


@pytest.mark.parametrize("pos, qvel0, gravity", [((0, 0, 0), (0,) * 6, 9.81), ((0, 0, 1), (0,) * 6, 9.81),
                                                 ((1, 2, 3), (0, 0, 0, 1, 2, 3), 9.81), ((0, 0, 0), (0,) * 6, 0.0)])
def test_a_free_body_with_inertia_1e_12_runs_as_mujoco_runs_it(pos, qvel0, gravity):
    """Before issue 23: refused with "use dt <= 0 s" (a Jacobian not finite), or a non-finite state at 0.45 s as it
    fell away from the origin. Its free fall is exact (z = z0 - g t^2 / 2 at rk4's order 4, a polynomial of degree
    2), and its spin keeps the length of its angular momentum."""
    run = simulate(free_body(1e-12, pos, qvel0, gravity), dt=1e-3, method="rk4")
    t = run.t
    np.testing.assert_allclose(run["b.com"][:, 2], pos[2] - 0.5 * gravity * t**2, rtol=0, atol=1e-12)
    moments = 1e-12 * np.array([1.0, 2.0, 2.5])
    quat, omega = run["b.quat"], run["b.omega"]
    from rbody.motion import quat_to_matrix
    body_omega = np.einsum("tji,tj->ti", np.array([quat_to_matrix(q) for q in quat]), omega)
    momentum = np.linalg.norm(moments * body_omega, axis=1)
    np.testing.assert_allclose(momentum, momentum[0], rtol=1e-9)


def test_a_hinge_angle_of_1e15_is_refused_with_its_spacing():
    """Before: ran, and ended 0.74 m from the run started at the same angle mod 2 pi."""
    with pytest.raises(ValueError, match=r"angle 1e\+15 rad is carried by float64 only to its spacing 0.125 rad"):
        pendulum_at(0.0, qpos0=1e15)


def test_a_run_whose_steps_a_large_angle_cannot_carry_is_refused_before_any_step():
    scene = pendulum_at(0.0, qpos0=1e8)  # spacing 1.5e-8 rad: fine for a scene
    with pytest.raises(SimulationError, match=r"carried by float64 only to 1.49e-08 rad, .* of the .* rad a step"):
        simulate(scene, dt=1e-3, method="rk4")


def test_a_large_angle_that_float64_carries_runs_as_its_reduced_angle():
    turns = 2 * math.pi * 15_000  # 9.4e4 rad: spacing 1.5e-11
    a = simulate(pendulum_at(0.0, qpos0=0.3 + turns), dt=1e-3, method="rk4")
    b = simulate(pendulum_at(0.0, qpos0=0.3), dt=1e-3, method="rk4")
    np.testing.assert_allclose(a["arm.com"], b["arm.com"], rtol=0, atol=1e-9)
