"""Models of many contact candidates before their run: the stability check reads the motion in the starting mode
without the contacts' candidates (rbody.scene.TreeScene._starting_motion, ConstraintTable.without_contacts): every
run starts with its contacts apart, so the rate is the one the whole constraint layer's right-hand side gives, at
the cost of the tree's own (a layer of 400 spheres spent 560 s and 9.5 GB in a check that read its 80,200
candidates); the memory estimate counts the rows of every candidate, and a run they would not fit is refused before
it starts."""

from __future__ import annotations

import numpy as np
import pytest

import rbody
import rbody.engine.constraints.stepping
from rbody.engine.constraints.dynamics import constrained_rhs
from rbody.engine.constraints.jacobians import row_count, unit_count
from rbody.engine.contacts.broadphase import pair_count
from rbody.engine.stability import fastest_rate, jacobian_rate

STIFFNESS = 400.0  # N m / rad: a spring whose mode sets the rate, w^2 = k / I (the arm horizontal: no gravity term)


def arm_xml(limited: bool) -> str:
    """A sprung hinge arm whose tip sphere can touch a floor, beside a free sphere resting on it: contacts, and
    (limited) the hinge's two stops before them."""
    limit = 'limited="true" range="-60 60"' if limited else ""
    return f"""<mujoco><worldbody><geom type="plane" size="5 5 0.1"/>
      <body name="arm" pos="0 0 0.5"><joint name="h" type="hinge" axis="0 1 0" stiffness="{STIFFNESS}"
          springref="0" {limit}/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="1"/>
        <geom type="sphere" pos="0.3 0 0" size="0.05" mass="0.1"/></body>
      <body name="ball" pos="1 0 0.1"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>
    </worldbody></mujoco>"""


def layer_xml(side: int) -> str:
    bodies = "".join(f'<body pos="{0.3 * (i % side)} {0.3 * (i // side)} 0.1"><freejoint/>'
                     f'<geom type="sphere" size="0.1" mass="1"/></body>' for i in range(side * side))
    return f'<mujoco><worldbody><geom type="plane" size="10 10 0.1"/>{bodies}</worldbody></mujoco>'


def whole_layer_rate(scene) -> float:
    """The rate read the way the check read it before: constrained_rhs over every unit, contacts included."""
    native = scene.native_model
    return float(jacobian_rate(native.rhs, native.y0, native.params)[0])


@pytest.mark.parametrize("limited", [True, False], ids=["limit-contacts", "contacts-only"])
def test_the_rate_is_the_whole_constraint_layers(limited):
    scene = rbody.from_mjcf(arm_xml(limited), t_end=1.0)
    table = scene.native_model.constraints
    assert (table.contact0 > 0) == limited and table.contact0 < len(table.units)
    rate = float(fastest_rate(scene, "moreau")[0])
    whole = whole_layer_rate(scene)
    model = scene.multibody
    inertia = model.mass_matrix(model.qpos0)[0, 0]  # the hinge's dof: the first
    assert rate == pytest.approx(whole, rel=1e-7)
    assert rate == pytest.approx(np.sqrt(STIFFNESS / inertia), rel=1e-6)  # the spring's mode


def test_the_rows_read_leave_out_every_contact():
    scene = rbody.from_mjcf(arm_xml(True), t_end=1.0)
    native = scene.native_model
    table = native.constraints
    source = scene._starting_motion(native)
    p, full = source.params[0], native.params[0]
    assert (unit_count(p), pair_count(p)) == (table.contact0, 0) and pair_count(full) > 0
    assert row_count(p) == sum(unit.rows for unit in table.units[:table.contact0]) < row_count(full)
    y = native.y0[0].copy()
    y[scene.multibody.nq] += 0.1  # the hinge turning
    kept, whole = np.empty_like(y), np.empty_like(y)
    constrained_rhs(y, p, kept)
    constrained_rhs(y, full, whole)
    np.testing.assert_allclose(kept, whole, rtol=0, atol=1e-12 * np.max(np.abs(whole)))


def test_a_contact_held_at_the_start_is_read_with_the_others():
    scene = rbody.from_mjcf(arm_xml(True), t_end=1.0)
    native = scene.native_model
    table = native.constraints
    params = native.params.copy()
    params[:, table.mode_slice().start + table.contact0] = 1.0
    held = dataclasses_replace(native, params=params)
    assert scene._starting_motion(held) is held


def test_a_layer_of_spheres_reads_the_free_tree():
    scene = rbody.from_mjcf(layer_xml(10), t_end=1.0)  # 100 spheres, 5,050 pairs: 15,150 candidate rows
    native = scene.native_model
    source = scene._starting_motion(native)
    assert source.constraints is None and source.rhs is not constrained_rhs
    assert source.y0.shape[1] == native.y0.shape[1] - 1  # the dissipated energy left out
    small = rbody.from_mjcf(layer_xml(2), t_end=1.0)
    assert float(fastest_rate(small, "moreau")[0]) == pytest.approx(whole_layer_rate(small), rel=1e-6, abs=1e-9)


def test_the_estimate_counts_every_candidates_rows_and_refuses_before_the_run(monkeypatch):
    from rbody import simulation
    from rbody.simulation import estimate_work

    scene = rbody.from_mjcf(layer_xml(10), t_end=0.05)
    table, nv = scene.native_model.constraints, scene.multibody.nv
    work = estimate_work(scene, 1e-2, 0.05, 1)
    assert work["constraint_bytes"] == 8.0 * (2 * nv * nv + 2 * table.rows * nv)  # 15,150 rows of 600 dofs: 151 MB
    assert work["bytes"] > work["constraint_bytes"] > 0.99 * 8.0 * 2 * table.rows * nv
    monkeypatch.setattr(simulation, "available_memory", lambda: 10**8)  # 100 MB left
    steps = []
    monkeypatch.setattr(rbody.engine.constraints.stepping, "moreau_loop", lambda *args: steps.append(args))
    with pytest.raises(ValueError, match=r"constraint rows, contact candidates included 0.151 GB"):
        rbody.simulate(scene, dt=1e-2, method="moreau")
    assert not steps  # refused before any step


def dataclasses_replace(obj, **fields):
    import dataclasses

    return dataclasses.replace(obj, **fields)


def arms_xml() -> str:
    """Three sprung, damped hinge arms with different stiffnesses (nothing couples them) and two free spheres on a
    floor."""
    arms = "".join(
        f'<body name="arm{k}" pos="{k} 0 1"><joint type="hinge" axis="0 1 0" stiffness="{stiffness}" damping="{damping}"/>'
        f'<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="{mass}" contype="0" conaffinity="0"/></body>'
        for k, (stiffness, damping, mass) in enumerate([(40.0, 0.5, 1.0), (900.0, 2.0, 0.5), (5.0, 0.0, 2.0)]))
    spheres = "".join(f'<body pos="{k} 2 0.1"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>'
                      for k in range(2))
    return f'<mujoco><worldbody><geom type="plane" size="5 5 0.1"/>{arms}{spheres}</worldbody></mujoco>'


@pytest.mark.parametrize("method", ["mujoco_euler", "implicitfast", "implicit"])
def test_mujocos_step_rate_by_groups_is_the_whole_trees(method, monkeypatch):
    """The step rate of MuJoCo's integrators (rbody.engine.mujoco_stability.step_rate) from each group of dofs that
    nothing couples equals the rate of the whole tree linearised at once (relative 1e-6: the same bisection to its
    2^-30); here every dof is a group of its own."""
    from rbody.engine import mujoco_stability

    scene = rbody.from_mjcf(arms_xml(), t_end=1.0)
    native = scene.native_model
    by_groups = float(scene.rates_for(native)(method)[0])
    seen = []
    original = mujoco_stability.coupled_groups

    def one_group(jq, jv, mass, derivative):
        seen.append([g.tolist() for g in original(jq, jv, mass, derivative)])
        return [np.arange(jq.shape[0])]

    monkeypatch.setattr(mujoco_stability, "coupled_groups", one_group)
    whole = float(scene.rates_for(native)(method)[0])
    assert seen[0] == [[d] for d in range(15)]  # each dof its own (a sphere's M is diagonal, its Jacobians 0)
    assert by_groups > 0.0 and by_groups == pytest.approx(whole, rel=1e-6)


def test_a_layer_of_spheres_prepares_for_mujocos_integrators_group_by_group():
    """100 free spheres under MuJoCo's Euler: each group of dofs linearised on its own (no spring: rate 0), where the
    whole tree's 1,200 x 1,200 step matrix was bisected 70 times (400 spheres: 111 s); a block-diagonal M of 100
    blocks of 6 makes 100 groups."""
    from rbody.engine import mujoco_stability

    scene = rbody.from_mjcf(layer_xml(10), t_end=0.05)
    run = rbody.prepare(scene, dt=1e-2, method="mujoco_euler")
    assert run.dt == 1e-2
    jq = np.zeros((600, 600))
    mass = np.kron(np.eye(100), np.ones((6, 6)))
    assert len(mujoco_stability.coupled_groups(jq, jq, mass, jq)) == 100
