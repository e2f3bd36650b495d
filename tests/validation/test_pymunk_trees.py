"""pymunk on planar trees: slides on moving bodies, a hinge then a slide, chains; what it refuses.

The trees here have no closed-form motion, so each run is judged by what holds exactly: the joint
coordinates pymunk's bodies are read back into equal the layout's initial ones at t = 0; the bodies'
centres of mass equal the forward kinematics of those coordinates at every step (the joints hold); the
energy is conserved by the physics, and pymunk's energy error is first order in dt (DESIGN.md: its
position-first update and PivotJoint lose or gain energy at a rate proportional to dt); the motion
converges at first order as dt is halved.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Scene
from rbody.motion import quat_to_matrix
from rbody.scenes import compound_pendulum, free_rotation, pendulum_chain
from validation import run, supports
from validation.comparison import divergence

pytestmark = pytest.mark.crosssim


@dataclass(frozen=True, kw_only=True, eq=False)
class PlanarTree(Scene):
    """A layout as a scene: observables are each joint's coordinate and rate ("<joint>.q", "<joint>.v"),
    each body's centre of mass and velocity, and the energy sum 1/2 m v^2 + 1/2 w^T I_world w + m g z."""

    tree: Any
    observables: ClassVar[tuple[str, ...]] = ("energy",)

    def _layout(self) -> Layout:
        return self.tree

    def observe(self, t, bodies, joints):
        out = {}
        for j in self.tree.joints:
            out[f"{j.name}.q"], out[f"{j.name}.v"] = np.asarray(joints[j.name][0]), np.asarray(joints[j.name][1])
        energy = np.zeros(len(t))
        for b in self.tree.bodies:
            s = bodies[b.name]
            rotation = quat_to_matrix(s.quat)
            inertia = np.einsum("tij,jk,tlk->til", rotation, b.inertia.tensor, rotation)
            energy += (0.5 * b.inertia.mass * np.sum(s.velocity**2, axis=-1)
                       + 0.5 * np.einsum("ti,tij,tj->t", s.omega, inertia, s.omega)
                       + b.inertia.mass * self.gravity * s.com[:, 2])
            out[f"{b.name}.com"], out[f"{b.name}.velocity"], out[f"{b.name}.quat"] = s.com, s.velocity, s.quat
        out["energy"] = energy
        return out


def _rod(mass: float, length: float) -> Inertia:
    """A thin cylinder hanging from its body origin along -z."""
    return Inertia.solid_cylinder(mass, 0.02, length, "z").translated([0.0, 0.0, -length / 2])


def cart_pole_bead(t_end: float = 1.0) -> PlanarTree:
    """A cart on a rail along x; a pole hinged to it; a bead sliding along the pole (a slide on a body that
    turns: a groove fixed in the pole and a gear that turns the bead with it)."""
    cart = Body("cart", Inertia.box(2.0, (0.2, 0.1, 0.05)))
    pole = Body("pole", _rod(1.0, 1.0), parent="cart")
    bead = Body("bead", Inertia.solid_sphere(0.3, 0.05), parent="pole", pos=(0.0, 0.0, -0.6))
    joints = (Joint("x", "slide", "cart", axis=(1, 0, 0), qvel0=0.3),
              Joint("hinge", "hinge", "pole", axis=(0, 1, 0), qpos0=0.8, qvel0=-0.5),
              Joint("along", "slide", "bead", axis=(0, 0, 1), qpos0=0.1, qvel0=0.2))
    return PlanarTree(name="cart_pole_bead", t_end=t_end, tree=Layout(bodies=(cart, pole, bead), joints=joints))


def cart_pole_sleeve_bead(t_end: float = 1.0) -> PlanarTree:
    """cart_pole_bead with a sleeve welded to the pole 0.3 m down (a body without a joint) and the bead sliding on
    the sleeve from 0.3 m below it: the same bead, on a parent that pymunk merges into the pole."""
    scene = cart_pole_bead(t_end)
    cart, pole, bead = scene.tree.bodies
    sleeve = Body("sleeve", Inertia.solid_cylinder(0.2, 0.03, 0.1, "z"), parent="pole", pos=(0.0, 0.0, -0.3))
    bead = dataclasses.replace(bead, parent="sleeve", pos=(0.0, 0.0, -0.3))
    return dataclasses.replace(scene, name="cart_pole_sleeve_bead",
                               tree=Layout(bodies=(cart, pole, sleeve, bead), joints=scene.tree.joints))


def telescope(t_end: float = 1.0) -> PlanarTree:
    """An arm hinged to the world at (0.1, 0, 0.2) that extends along itself (a hinge, then a slide: a
    groove fixed in the arm through the pivot), and a rod hinged at its end about -y."""
    arm = Body("arm", _rod(1.0, 1.0), pos=(0.1, 0.0, 0.2))
    tip = Body("tip", _rod(0.5, 0.5), parent="arm", pos=(0.0, 0.0, -1.0))
    joints = (Joint("swing", "hinge", "arm", axis=(0, 1, 0), qpos0=0.6, qvel0=0.4),
              Joint("extend", "slide", "arm", axis=(0, 0, -1), qpos0=0.2, qvel0=0.1),
              Joint("tip_hinge", "hinge", "tip", axis=(0, -1, 0), qpos0=-0.3))
    return PlanarTree(name="telescope", t_end=t_end, tree=Layout(bodies=(arm, tip), joints=joints))


def _initial(scene: PlanarTree, trajectory) -> None:
    for joint in scene.tree.joints:
        assert trajectory[f"{joint.name}.q"][0] == pytest.approx(joint.qpos0, abs=1e-12), joint.name
        assert trajectory[f"{joint.name}.v"][0] == pytest.approx(joint.qvel0, abs=1e-12), joint.name


@pytest.mark.parametrize("make", [cart_pole_bead, cart_pole_sleeve_bead, telescope])
def test_joint_coordinates_read_back_at_the_start(make):
    scene = make()
    assert supports(scene, "pymunk") == (True, "")
    _initial(scene, run(scene, "pymunk", dt=1e-3, t_end=0.01))


def _kinematic_gaps(dt: float, make=None) -> dict[str, float]:
    """Largest distance [m] (and speed [m/s]) between each body's com (velocity) as pymunk reports it and
    the forward kinematics of the joint coordinates read back from it:
    R_y(theta) (0, 0, z) = (z sin theta, 0, z cos theta)."""
    trajectory = run((make or cart_pole_bead)(), "pymunk", dt=dt)
    x, theta, s = trajectory["x.q"], trajectory["hinge.q"], trajectory["along.q"]
    xv, w, sv = trajectory["x.v"], trajectory["hinge.v"], trajectory["along.v"]
    zero, r = np.zeros_like(x), s - 0.6
    expected = {"cart.com": np.stack([x, zero, zero], axis=1),
                "pole.com": np.stack([x - 0.5 * np.sin(theta), zero, -0.5 * np.cos(theta)], axis=1),
                "bead.com": np.stack([x + r * np.sin(theta), zero, r * np.cos(theta)], axis=1),
                # the slide rate along the pole, the pole's turn and the cart's speed
                "bead.velocity": np.stack([xv + sv * np.sin(theta) + r * w * np.cos(theta), zero,
                                           sv * np.cos(theta) - r * w * np.sin(theta)], axis=1)}
    gaps = {name: float(np.max(np.linalg.norm(trajectory[name] - value, axis=1))) for name, value in expected.items()}
    # the bead has no hinge: it turns with the pole (the gear), so their orientations stay equal [rad]
    gaps["bead.turn"] = float(np.max(divergence("bead.quat", trajectory["bead.quat"], trajectory["pole.quat"])))
    return gaps


@pytest.mark.parametrize("make", [cart_pole_bead, cart_pole_sleeve_bead])
def test_cart_pole_bead_bodies_follow_the_kinematics_of_the_joint_coordinates(make):
    """The read-back relative to a moving, turning parent is right: what is left is pymunk's joint drift
    (its constraints are corrected softly), which halves with dt. Measured at dt = 1e-3: cart 6.6e-10 m,
    pole 2.2e-4 m, bead 1.1e-3 m; bead velocity 7.1e-3 m/s (each halving with dt through 2.5e-4). A wrong
    read-back (the parent's turn or velocity left out) leaves an O(1) gap that does not halve."""
    coarse, fine = _kinematic_gaps(1e-3, make), _kinematic_gaps(5e-4, make)
    assert coarse["cart.com"] < 1e-8  # a groove on the world along x: nothing lifts the cart
    assert coarse["bead.turn"] < 1e-9  # the gear holds the bead's angle to the pole's (measured 0; 0.78 rad without)
    for name, bound in (("pole.com", 1e-3), ("bead.com", 3e-3), ("bead.velocity", 1.5e-2)):
        assert coarse[name] < bound, name
        assert coarse[name] / fine[name] == pytest.approx(2.0, rel=0.1), name


@pytest.mark.parametrize("make", [cart_pole_bead, telescope])
def test_energy_error_is_first_order_in_dt(make):
    """The physics conserves E; pymunk's E(t) - E(0) halves with dt (measured at dt = 1e-3: 1.08e-2 J of
    |E0| = 4.16 J for the cart-pole-bead, 7.2e-2 J of 8.2 J for the telescope)."""
    scene = make()
    drift = []
    for dt in (1e-3, 5e-4):
        energy = run(scene, "pymunk", dt=dt)["energy"]
        drift.append(np.max(np.abs(energy - energy[0])))
    assert drift[0] / drift[1] == pytest.approx(2.0, rel=0.05)
    assert drift[0] < 0.02 * abs(energy[0])


def test_telescope_converges_at_first_order():
    """|q(dt) - q(dt/2)| / |q(dt/2) - q(dt/4)| -> 2 for a first-order method, for every joint at t_end."""
    scene = telescope()
    final = [{j.name: run(scene, "pymunk", dt=dt)[f"{j.name}.q"][-1] for j in scene.tree.joints}
             for dt in (1e-3, 5e-4, 2.5e-4)]
    for name in final[0]:
        ratio = abs(final[0][name] - final[1][name]) / abs(final[1][name] - final[2][name])
        assert ratio == pytest.approx(2.0, rel=0.1), name


def test_three_link_chain_energy_and_native():
    """A planar 3-link chain: rbody's rk4 keeps E to 1e-8; pymunk's PivotJoints lose it in proportion to
    dt (DESIGN.md); the angles differ from rbody's by what that loss does to the phase (0.05 rad, the chain
    tolerance of validation/tolerances.py). Uses Scene.from_layout (the general engine) when it exists."""
    chain = pendulum_chain(3, theta0=[0.6, 0.3, -0.2], t_end=2.0)
    scene = chain
    if hasattr(Scene, "from_layout"):
        scene = Scene.from_layout(chain.layout, t_end=2.0, name="chain3")
    main = "qpos" if "qpos" in scene.observables else "theta"
    native = run(scene, "rbody", dt=1e-3, method="rk4")
    e0 = chain.energy_of(np.asarray(chain.theta0), np.zeros(3))
    assert np.max(np.abs(native["energy"] - e0)) < 1e-8
    losses = []
    for dt in (1e-3, 5e-4):
        trajectory = run(scene, "pymunk", dt=dt)
        assert trajectory["energy"][0] == pytest.approx(e0, abs=1e-12)
        losses.append(np.max(np.abs(trajectory["energy"] - e0)))
        if dt == 1e-3:
            assert np.max(np.abs(trajectory[main] - native[main])) < 0.05
    assert losses[0] / losses[1] == pytest.approx(2.0, rel=0.15)


def _damped_hinge(t_end: float = 3.0, axis=(0.0, 1.0, 0.0)) -> Scene:
    """A rod turning about its own centre of mass on a hinge with stiffness k, damping c, ref and springref:
    gravity exerts no torque, so q'' = -(k (q - springref) + c q') / I, a damped oscillator."""
    rod = Body("rod", Inertia.solid_cylinder(1.0, 0.05, 1.0, "z"))
    hinge = Joint("spin", "hinge", "rod", axis=axis, qpos0=0.9, qvel0=0.0, stiffness=2.0, damping=0.1,
                  springref=0.5, ref=0.2)
    return Scene.from_layout(Layout(bodies=(rod,), joints=(hinge,)), t_end=t_end, name="damped_hinge")


def _damped_exact(t: np.ndarray, inertia: float) -> np.ndarray:
    k, c, q0, rest = 2.0, 0.1, 0.9, 0.5
    decay, frequency = c / (2 * inertia), np.sqrt(k / inertia - (c / (2 * inertia)) ** 2)
    return rest + (q0 - rest) * np.exp(-decay * t) * (np.cos(frequency * t) + decay / frequency * np.sin(frequency * t))


@pytest.mark.skipif(not hasattr(Scene, "from_layout"), reason="needs the general engine (Scene.from_layout)")
@pytest.mark.parametrize("axis", [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0)])
def test_hinge_spring_damper_and_ref_against_the_damped_oscillator(axis):
    """pymunk's DampedRotarySpring with the rest angle set from springref and ref: q(t) of the closed form to
    first order in dt (measured 9.8e-4 rad at dt = 1e-3 over 3 s, halving with dt), rbody's rk4 to C dt^4
    (5.7e-12 rad). The joint's coordinate follows its axis, so either sign of y gives the same q(t)."""
    scene = _damped_hinge(axis=axis)
    inertia = scene.tree.bodies[0].inertia.moment([0.0, 1.0, 0.0])
    errors = []
    for dt in (1e-3, 5e-4):
        trajectory = run(scene, "pymunk", dt=dt)
        assert trajectory["qpos"][0, 0] == pytest.approx(0.9, abs=1e-12)  # ref read back
        errors.append(np.max(np.abs(trajectory["qpos"][:, 0] - _damped_exact(trajectory.t, inertia))))
    assert errors[0] < 2e-3
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)
    native = run(scene, "rbody", dt=1e-3, method="rk4")
    assert np.max(np.abs(native["qpos"][:, 0] - _damped_exact(native.t, inertia))) < 1e-9


@pytest.mark.skipif(not hasattr(Scene, "from_layout"), reason="needs the general engine (Scene.from_layout)")
def test_a_welded_body_joins_its_carrier_against_the_compound_pendulum():
    """A rod hinged to the world with a ball welded to its end (a body without a joint, as MJCF writes a part):
    pymunk holds both in one body (summed mass, centre of mass, moment by the parallel-axis theorem), so the
    angle follows the closed form of the compound pendulum of rod + ball to pymunk's first-order error
    (measured 2.6e-3 rad over 2 s at theta0 = 1, dt = 1e-3; a moment without the parallel-axis terms is off
    by 0.4 rad), and the ball is read back on the rod (pymunk's pivot drift: 4.6e-4 m)."""
    rod = Inertia.solid_cylinder(1.0, 0.02, 1.0, "z").translated([0.0, 0.0, -0.5])
    ball = Inertia.solid_sphere(0.5, 0.1)
    layout = Layout(bodies=(Body("rod", rod), Body("ball", ball, parent="rod", pos=(0.0, 0.0, -1.0))),
                    joints=(Joint("swing", "hinge", "rod", axis=(0, 1, 0), qpos0=1.0, qvel0=-1.5),))
    scene = Scene.from_layout(layout, t_end=2.0, name="rod_and_ball")
    exact = compound_pendulum(rod + ball.translated([0.0, 0.0, -1.0]), pivot=(0, 0, 0), theta0=1.0, omega0=-1.5,
                              t_end=2.0)
    errors = []
    for dt in (1e-3, 5e-4):
        trajectory = run(scene, "pymunk", dt=dt)
        theta = trajectory["qpos"][:, 0]
        errors.append(np.max(np.abs(theta - exact.exact(trajectory.t)["theta"])))
        on_rod = np.stack([-np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=1)
        assert np.max(np.linalg.norm(trajectory["ball.com"] - on_rod, axis=1)) < 2e-3
        assert np.max(divergence("ball.quat", trajectory["ball.quat"], trajectory["rod.quat"])) < 1e-12
        # the welded ball's own velocity: the rod's turn about the pivot, omega y x r
        omega = trajectory["qvel"][:, 0]
        np.testing.assert_allclose(trajectory["ball.velocity"], omega[:, None] * np.stack(
            [-np.cos(theta), np.zeros_like(theta), np.sin(theta)], axis=1), rtol=0, atol=1e-2)
    assert errors[0] < 5e-3
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)


def test_refusals_name_the_reason():
    bead = cart_pole_bead()
    tilted = dataclasses.replace(bead, tree=Layout(bodies=bead.tree.bodies, joints=(
        bead.tree.joints[0], dataclasses.replace(bead.tree.joints[1], axis=(1.0, 0.0, 0.0)), bead.tree.joints[2])))
    ok, reason = supports(tilted, "pymunk")
    assert not ok and "hinge" in reason and "world y" in reason
    arm = telescope()
    swapped = dataclasses.replace(arm, tree=Layout(bodies=arm.tree.bodies, joints=(
        arm.tree.joints[0], arm.tree.joints[1], Joint("up", "slide", "arm", axis=(1, 0, 0)), arm.tree.joints[2])))
    ok, reason = supports(swapped, "pymunk")
    assert not ok and "hinge 'swing' comes before" in reason
    ok, reason = supports(free_rotation(Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])), omega0=(0, 1, 0),
                                        t_end=1.0), "pymunk")
    assert not ok and "not planar" in reason
    ok, reason = supports(pendulum_chain(2, theta0=[[0.1, 0.2], [0.3, 0.4]], t_end=1.0), "pymunk")
    assert not ok and "batch" in reason
    # rbody refuses a scene with nothing to integrate, MuJoCo a body its compiler rejects
    ok, reason = supports(bead, "rbody")
    assert not ok and "no native model" in reason
    thin = dataclasses.replace(bead, tree=Layout(bodies=(bead.tree.bodies[0], dataclasses.replace(
        bead.tree.bodies[1], inertia=Inertia.rod(1.0, 1.0, "z")), bead.tree.bodies[2]), joints=bead.tree.joints))
    ok, reason = supports(thin, "mujoco")
    assert not ok and "principal moments" in reason
    with pytest.raises(ValueError, match="expected one of"):
        supports(bead, "drake")


def _with_joint(scene: PlanarTree, index: int, **changes) -> PlanarTree:
    joints = list(scene.tree.joints)
    joints[index] = dataclasses.replace(joints[index], **changes)
    return dataclasses.replace(scene, tree=Layout(bodies=scene.tree.bodies, joints=tuple(joints)))


def test_what_pymunk_cannot_hold_in_a_joint_is_refused():
    bead = cart_pole_bead()
    ok, reason = supports(_with_joint(bead, 0, damping=0.5), "pymunk")
    assert not ok and "slide 'x' has stiffness 0 and damping 0.5" in reason
    ok, reason = supports(_with_joint(bead, 1, armature=0.01), "pymunk")
    assert not ok and "armature" in reason
    assert supports(_with_joint(bead, 1, damping=0.5, stiffness=1.0), "pymunk") == (True, "")  # a rotary spring
    ok, reason = supports(_with_joint(bead, 1, kind="ball", qpos0=0.0), "pymunk")
    assert not ok and "ball joint" in reason


@pytest.mark.skipif(not hasattr(Scene, "from_layout"), reason="needs the general engine (Scene.from_layout)")
def test_a_tree_scene_is_planar_by_its_joints_and_shapes_that_touch_nothing_need_no_side_view():
    chain = pendulum_chain(2, theta0=[0.4, 0.1], t_end=0.5).layout
    tilted_box = rbody.Shape("tilted", "box", (0.1, 0.2, 0.3), quat=(np.cos(0.3), np.sin(0.3), 0.0, 0.0))
    bodies = (dataclasses.replace(chain.bodies[0], shapes=chain.bodies[0].shapes + (tilted_box,)),) + chain.bodies[1:]
    scene = Scene.from_layout(dataclasses.replace(chain, bodies=bodies), t_end=0.5)
    assert supports(scene, "pymunk") == (True, "")
    twisted = Scene.from_layout(dataclasses.replace(chain, joints=(
        chain.joints[0], dataclasses.replace(chain.joints[1], axis=(1.0, 0.0, 0.0)))), t_end=0.5)
    ok, reason = supports(twisted, "pymunk")
    assert not ok and "hinge_1" in reason and "world y" in reason
