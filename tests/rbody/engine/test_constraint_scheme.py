"""The constraint layer run through simulate: which methods run a constrained tree, what a run reports, batches."""

from __future__ import annotations

import numpy as np
import pytest

from rbody import Body, Equality, Inertia, Joint, Layout, MethodNotApplicable, Scene, simulate

G = 9.81


def rod(mass: float = 1.0, length: float = 1.0) -> Inertia:
    """A thin rod of `length` hanging along -z from its end at the body origin."""
    moment = mass * length**2 / 12
    return Inertia(mass, (0.0, 0.0, -length / 2), np.diag([moment, moment, 1e-6 * moment]))


def limited_pendulum(theta0=1.0, low=-0.5, high=2.0, restitution=0.0, friction=0.0, t_end=3.0, **scene):
    joint = Joint("h", "hinge", "rod", axis=(0, 1, 0), qpos0=theta0, range=(low, high), restitution=restitution,
                  frictionloss=friction)
    return Scene.from_layout(Layout(bodies=(Body("rod", rod()),), joints=(joint,)), t_end=t_end, **scene)


def test_a_constrained_tree_runs_rk4_between_events_or_a_time_stepping_and_nothing_else():
    """rk4 between events by default; moreau, and MuJoCo's integrators as the time-stepping's free motion."""
    scene = limited_pendulum()
    assert scene.methods == ("rk4", "moreau", "mujoco_euler", "implicitfast", "implicit")
    with pytest.raises(MethodNotApplicable, match="constraint layer runs rk4, moreau"):
        simulate(scene, dt=1e-2, method="verlet")
    with pytest.raises(MethodNotApplicable, match="constrained tree"):
        simulate(limited_pendulum(), dt=1e-2, method="gauss6")
    free = Scene.from_layout(Layout(bodies=(Body("rod", rod()),), joints=(Joint("h", "hinge", "rod", axis=(0, 1, 0)),)),
                             t_end=1.0)
    assert "moreau" not in free.methods
    with pytest.raises(MethodNotApplicable, match="moreau"):
        simulate(free, dt=1e-2, method="moreau")


def test_a_run_reports_its_events_scheme_and_the_constraint_observables():
    run = simulate(limited_pendulum(restitution=1.0), dt=1e-2)
    assert run.meta["method"] == "rk4" and run.meta["scheme"].startswith("event-driven")
    assert run.meta["events"] == run.meta["impacts"] == len(run.events["time"]) == 3
    assert list(run.events["what"]) == ["impact"] * 3 and set(run.events["constraints"]) == {"h.lower"}
    assert run.meta["constraint_rows"] == [("limit", "h.lower", 0), ("limit", "h.upper", 0)]
    assert run.meta["limits"] == ["h.lower", "h.upper"] and run.meta["frictions"] == []
    T = run.t.size
    assert run["constraint_force"].shape == (T, 2) and run["active_limits"].shape == (T, 2)
    assert run["sticking"].shape == (T, 0) and run["dissipated"].shape == (T,)
    assert np.all(run["qpos"][:, 0] >= -0.5 - 1e-15)  # never past its stop beyond round-off
    steps = simulate(limited_pendulum(restitution=1.0), dt=1e-2, method="moreau")
    assert steps.meta["scheme"].startswith("time-stepping") and steps.meta["events"] == 0


def test_a_batch_runs_each_element_as_alone():
    scene = limited_pendulum()
    from rbody.scene import TreeScene
    import dataclasses

    batch = dataclasses.replace(scene, qpos0=np.array([[1.0], [0.3]]), qvel0=np.zeros((2, 1)))
    assert isinstance(batch, TreeScene) and batch.batch_shape == (2,)
    together = simulate(batch, dt=1e-2)
    for b in range(2):
        alone = simulate(batch.item(b), dt=1e-2)
        np.testing.assert_array_equal(together["qpos"][:, b], alone["qpos"])
        np.testing.assert_array_equal(together["constraint_force"][:, b], alone["constraint_force"])
    assert together.meta["events"] == 1  # only the first swings to its stop (0.3 rad stays within it)
    assert list(together.events["element"]) == [0]


def test_the_time_steppings_constraint_observables_are_read_when_asked_for():
    """A moreau run hands back its states; its forces, errors, held limits and sticking frictions are read from the
    impulses it kept on first access, each batch element's from its own run, as that element run alone gives them."""
    import dataclasses

    scene = limited_pendulum(low=0.2, friction=3.0, t_end=2.0)
    batch = dataclasses.replace(scene, qpos0=np.array([[1.0], [0.5]]), qvel0=np.zeros((2, 1)))
    together = simulate(batch, dt=1e-2, method="moreau")
    lazy = ("constraint_force", "constraint_error", "active_limits", "sticking")
    assert not any(together.data.is_computed(name) for name in lazy)
    assert together.data.is_computed("qpos") and together.data.is_computed("dissipated")
    sticking = together["sticking"]
    assert not together.data.is_computed("active_limits")  # each is read on its own
    for b in range(2):
        alone = simulate(batch.item(b), dt=1e-2, method="moreau")
        for name in lazy:
            np.testing.assert_array_equal(together[name][:, b], alone[name])
    # gravity's torque m g (L/2) sin(theta): 4.1 N m at 1.0 rad, beyond the dry friction's 3 N m, which then
    # stops the rod short of its stop; 2.35 N m at 0.5 rad, within it: the second rod never moves
    assert not sticking[1, 0, 0] and sticking[-1, 0, 0] and np.all(sticking[:, 1, 0])
    assert np.all(together["qpos"][:, 1, 0] == 0.5) and not together["active_limits"].any()
    assert together["qpos"][-1, 0, 0] > 0.2 and np.all(np.diff(together["qpos"][-20:, 0, 0]) == 0.0)


def test_a_time_stepped_trajectory_keeps_its_impulses_not_its_runs(monkeypatch):
    """The lazy observables read each element's kept impulses; the element's run, with its copy of the parameter
    row (megabytes for a robot's file), is let go once its element is done, even while the trajectory lives."""
    import gc
    import weakref

    from rbody.engine.constraints import runner, stepping

    made = []

    class Watched(stepping.MoreauRun):
        def __init__(self, *arguments, **keywords):
            super().__init__(*arguments, **keywords)
            made.append(weakref.ref(self))

    monkeypatch.setattr(runner, "MoreauRun", Watched)
    import dataclasses

    scene = limited_pendulum(low=0.2, friction=3.0, t_end=0.5)
    batch = dataclasses.replace(scene, qpos0=np.array([[1.0], [0.5]]), qvel0=np.zeros((2, 1)))
    run = simulate(batch, dt=1e-2, method="moreau")
    gc.collect()
    assert len(made) == 2 and all(ref() is None for ref in made)
    assert run["sticking"].shape == (run.t.size, 2, 1) and run["constraint_error"].shape == (run.t.size, 2, 3)


def test_a_loop_closed_by_a_connect_runs_with_a_redundant_row():
    """A planar four-bar in 3-D: its connect's third row (along the hinges' axes) is redundant (J's row is zero);
    the run goes on and that row's force is zero."""
    L, d = 1.0, 0.8
    bar = Inertia(0.5, (d / 2, 0, 0), np.diag([1e-6, 0.5 * d**2 / 12, 0.5 * d**2 / 12]))
    bodies = (Body("crank", rod()), Body("coupler", bar, parent="crank", pos=(0, 0, -L)),
              Body("rocker", rod(), pos=(d, 0, 0)))
    joints = (Joint("a", "hinge", "crank", axis=(0, 1, 0), qpos0=0.4),
              Joint("b", "hinge", "coupler", axis=(0, 1, 0), qpos0=-0.4),
              Joint("c", "hinge", "rocker", axis=(0, 1, 0), qpos0=0.4))
    loop = Equality("loop", "connect", body1="coupler", body2="rocker", anchor=(d, 0, 0))
    scene = Scene.from_layout(Layout(bodies=bodies, joints=joints, equalities=(loop,)), t_end=1.0)
    run = simulate(scene, dt=1e-2)
    assert np.abs(run["constraint_error"]).max() <= 1e-14
    assert np.abs(run["constraint_force"][:, 1]).max() <= 1e-12  # the redundant row carries nothing
    np.testing.assert_allclose(run["qpos"][:, 0], run["qpos"][:, 2], rtol=0, atol=1e-12)  # a parallelogram
