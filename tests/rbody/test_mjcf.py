"""rbody.to_mjcf: MuJoCo compiles what rbody writes and holds rbody's mass properties to 1e-12.

MuJoCo's compiled body_inertia is the principal moments and body_iquat their axes; the tensor is
rebuilt as R diag(I) R^T (R from body_iquat) in the body frame and compared with the tensor rbody
wrote. Measured (mujoco 4.0): fullinertia comes back within 8e-15 relative; a turned hoop or disc
(on A + B = C) is refused by MuJoCo about 40 % of the time when written as a full tensor, which is
why to_mjcf writes such bodies in principal form (test_boundary_bodies_compile).
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import warnings
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

mujoco = pytest.importorskip("mujoco")

from rbody import Body, Contact, Inertia, Joint, Layout, Scene, Shape, to_mjcf  # noqa: E402
from rbody.mjcf import (CONTACT_SOLIMP, ExportedInertia, exported_inertia, impact_damping_ratio,  # noqa: E402
                        initial_state, MUJOCO_MIN_MOMENT, pushing_restitution)
from rbody.motion import quat_to_matrix  # noqa: E402
from rbody.scenes import compound_pendulum, pendulum_chain, rolling, rolling_race, swinging_rod  # noqa: E402

RTOL = 1e-12


@dataclass(frozen=True, kw_only=True)
class Handmade(Scene):
    """A scene given directly by its layout (tests only)."""

    parts: Layout

    def _layout(self) -> Layout:
        return self.parts


def handmade(bodies, joints, fixed=(), contacts=(), name="handmade", gravity=9.81) -> Handmade:
    return Handmade(name=name, t_end=1.0, gravity=gravity,
                    parts=Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=tuple(fixed),
                                 contacts=tuple(contacts)))


def compile_scene(scene, **kwargs):
    return mujoco.MjModel.from_xml_string(to_mjcf(scene, **kwargs))


def compiled_tensor(model, body_id: int) -> np.ndarray:
    """R diag(I) R^T (3,3): MuJoCo's principal moments and axes back to a tensor in the body frame."""
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.body_iquat[body_id])
    rotation = rotation.reshape(3, 3)
    return rotation @ np.diag(model.body_inertia[body_id]) @ rotation.T


def assert_round_trip(scene, **kwargs) -> dict[str, ExportedInertia]:
    """MuJoCo's mass, centre of mass and tensor of every body equal what rbody wrote, to 1e-12."""
    model = compile_scene(scene, **kwargs)
    written = {}
    for body in scene.layout.bodies:
        exported = exported_inertia(body, min_inertia=kwargs.get("min_inertia"))
        inertia = exported.inertia
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body.name)
        assert b > 0, body.name
        assert model.body_mass[b] == pytest.approx(inertia.mass, rel=RTOL, abs=0)
        scale = max(np.linalg.norm(inertia.com), math.sqrt(np.max(np.abs(inertia.tensor)) / inertia.mass))
        np.testing.assert_allclose(model.body_ipos[b], inertia.com, rtol=0, atol=RTOL * scale)
        np.testing.assert_allclose(compiled_tensor(model, b), inertia.tensor, rtol=0,
                                   atol=RTOL * np.max(np.abs(inertia.tensor)))
        if not exported.note:  # nothing raised: what MuJoCo holds is rbody's body itself
            np.testing.assert_array_equal(inertia.tensor, body.inertia.tensor)
        written[body.name] = exported
    return written


# ----- every scene -------------------------------------------------------------------------------------

def available_scenes():
    """One unbatched scene of every family that exists (modules appear as the scenes are written)."""
    box = Inertia.box(2.0, (0.1, 0.2, 0.5)).rotated([0.9, 0.1, -0.3, 0.2]).translated([0.01, 0.02, -0.3])
    scenes = [
        swinging_rod(1.0, 1 / 3, theta0=1.0, t_end=1.0),
        compound_pendulum(box, pivot=(0.0, 0.0, 0.0), theta0=0.5, t_end=1.0),
        pendulum_chain(3, masses=[1.0, 2.0, 0.5], theta0=[0.1, 0.2, 0.3], t_end=1.0),
        rolling_race(("disc", "hollow_cylinder", "solid_sphere", "spherical_shell"), radius=0.1, incline=0.3,
                     length=1.0),
    ]
    scenes += [rolling(body, radius=0.1, incline=0.3, friction=f, t_end=1.0)
               for body in ("disc", "hollow_cylinder", "solid_sphere", "spherical_shell") for f in (0.0, 1.0)]
    optional = {
        "rbody.scenes.free_rotation": lambda m: [m.free_rotation(
            Inertia.box(3.0, (0.2, 0.5, 0.9)).rotated([0.8, 0.3, 0.4, -0.1]).translated([0.1, -0.2, 0.3]),
            omega0=[1.0, 2.0, 0.5], t_end=1.0)],
        "rbody.scenes.collisions": lambda m: [m.pi_collisions(2, speed=0.01),
                                              m.line_collisions([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [1.0, 0.0, -1.0],
                                                                walls=(0.0, 4.0), restitution=0.5, t_end=2.0)],
        "rbody.scenes.variable_mass": lambda m: [m.rocket(10.0, burn_rate=1.0, exhaust_speed=100.0, dry_mass=2.0,
                                                          t_end=1.0),
                                                 m.avalanche(0.5, t_end=1.0)],
        "rbody.scenes.two_body": lambda m: [m.two_body(1.0, 2.0, separation=(1.0, 0.0, 0.0),
                                                       relative_velocity=(0.0, 0.0, 1.0), t_end=1.0)],
    }
    for module, make in optional.items():
        try:
            scenes += make(importlib.import_module(module))
        except ImportError:
            pass
    return scenes


SCENES = available_scenes()


@pytest.mark.parametrize("scene", SCENES, ids=[s.describe()[:60] for s in SCENES])
def test_every_scene_round_trips(scene):
    written = assert_round_trip(scene, dt=1e-3)
    # Only zero moments of thin bodies may be raised; every other body is written exactly.
    for body in scene.layout.bodies:
        moments = np.linalg.eigvalsh(body.inertia.tensor)
        if moments[0] > 1e-12 * moments[-1]:
            assert written[body.name].note == ""


def test_swinging_rod_zero_moment_takes_the_capsule_thickness():
    """The rod's moment about its own axis is 0; MuJoCo needs one, so it becomes that of the capsule
    (radius r = L/100, half length L/2) with the rod's mass: m_c r^2/2 + 2/5 m_s r^2 by volume."""
    length, mass = 1.0, 1 / 3
    scene = swinging_rod(length, mass, theta0=1.0, t_end=1.0)
    model = compile_scene(scene)
    r, h = 0.01 * length, length / 2
    cylinder, ball = 2 * math.pi * r**2 * h, 4 / 3 * math.pi * r**3
    m_c = mass * cylinder / (cylinder + ball)
    expected = m_c * r**2 / 2 + 0.4 * (mass - m_c) * r**2
    moments = np.sort(model.body_inertia[1])
    assert moments[0] == pytest.approx(expected, rel=RTOL)
    assert moments[1:] == pytest.approx([mass * length**2 / 12] * 2, rel=RTOL)
    text = to_mjcf(scene)
    assert "raised to" in text and "'rod'" in text  # the comment says what was changed


def test_min_inertia_floors_every_moment():
    scene = swinging_rod(1.0, 1.0, theta0=1.0, t_end=1.0)
    model = compile_scene(scene, min_inertia=1e-3)
    assert np.sort(model.body_inertia[1]) == pytest.approx([1e-3, 1 / 12, 1 / 12], rel=RTOL)
    assert "min_inertia=0.001" in to_mjcf(scene, min_inertia=1e-3)


# ----- random bodies --------------------------------------------------------------------------------------

unit = st.floats(-1.0, 1.0)
quaternions = st.tuples(unit, unit, unit, unit).filter(lambda q: np.linalg.norm(q) > 0.1)
shifts = st.tuples(*[st.floats(-10.0, 10.0)] * 3)


def pendulum_of(body: Inertia):
    """The body hung from a hinge 0.5 m from its centre of mass, along its x axis."""
    return compound_pendulum(body, pivot=tuple((body.com + [0.5, 0.0, 0.0]).tolist()), theta0=0.3, t_end=1.0)


@settings(max_examples=60, deadline=None)
@given(mass=st.floats(1e-3, 1e3), sides=st.tuples(*[st.floats(1e-2, 10.0)] * 3), quat=quaternions, shift=shifts)
def test_random_boxes_round_trip(mass, sides, quat, shift):
    body = Inertia.box(mass, sides).rotated(np.array(quat) / np.linalg.norm(quat)).translated(shift)
    assert_round_trip(pendulum_of(body))


@settings(max_examples=60, deadline=None)
@given(masses=st.lists(st.floats(1e-2, 10.0), min_size=4, max_size=8), data=st.data(), quat=quaternions,
       shift=shifts)
def test_random_point_sets_round_trip(masses, data, quat, shift):
    points = data.draw(st.lists(st.tuples(unit, unit, unit), min_size=len(masses), max_size=len(masses)))
    body = Inertia.point_masses(masses, points)
    moments = np.linalg.eigvalsh(body.tensor)
    assume(moments[0] > 1e-6 * moments[-1])  # not a line of particles (that needs min_inertia)
    body = body.rotated(np.array(quat) / np.linalg.norm(quat)).translated(shift)
    assert_round_trip(pendulum_of(body))


@settings(max_examples=80, deadline=None)
@given(kind=st.sampled_from(["hoop", "disc"]), mass=st.floats(1e-2, 1e2), radius=st.floats(1e-2, 10.0),
       quat=quaternions)
def test_boundary_bodies_compile(kind, mass, radius, quat):
    """A hoop or disc (A + B = C exactly) turned at random: MuJoCo compiles it and holds its tensor."""
    body = getattr(Inertia, kind)(mass, radius).rotated(np.array(quat) / np.linalg.norm(quat))
    written = assert_round_trip(pendulum_of(body))
    assert written["body"].form == "principal"


# ----- precision, names, refusals -------------------------------------------------------------------------

def test_numbers_keep_every_digit():
    """A mass of 1/3 and a tensor of thirds come back exactly: no 6-digit truncation anywhere."""
    body = Inertia(1 / 3, [1 / 7, -2 / 3, 1e-7 / 3], np.diag([1 / 3, 2 / 7, 0.5]))
    scene = pendulum_of(body)
    text = to_mjcf(scene, dt=1 / 3000)
    assert 'mass="0.3333333333333333"' in text
    model = mujoco.MjModel.from_xml_string(text)
    assert model.body_mass[1] == 1 / 3
    np.testing.assert_array_equal(model.body_ipos[1], body.com)
    assert model.opt.timestep == 1 / 3000
    assert 'qpos="0.3"' in text


def test_comment_says_what_and_where_from():
    text = to_mjcf(swinging_rod(1.0, theta0=1.0, t_end=1.0))
    comment = text[text.index("<!--"):text.index("-->")]
    assert "Generated by rbody" in comment and "swinging_rod" in comment
    assert "contype=conaffinity=0" in comment
    assert "--" not in comment[4:]


def point_body(name="p", shapes=()):
    return Body(name, Inertia.point_masses([1.0], [[0.0, 0.0, -1.0]]), shapes=shapes)


def test_point_mass_needs_min_inertia_or_a_shape():
    scene = handmade([point_body()], [Joint("h", "hinge", "p", axis=(0.0, 1.0, 0.0))])
    with pytest.raises(ValueError, match="min_inertia"):
        to_mjcf(scene)
    model = compile_scene(scene, min_inertia=1e-6)
    assert model.body_inertia[1] == pytest.approx([1e-6] * 3, rel=RTOL)
    with pytest.raises(ValueError, match="min_inertia"):
        to_mjcf(scene, min_inertia=1e-16)  # below MuJoCo's least moment
    ball = handmade([point_body(shapes=(Shape("ball", "sphere", (0.1,), pos=(0.0, 0.0, -1.0)),))],
                    [Joint("h", "hinge", "p", axis=(0.0, 1.0, 0.0))])
    assert compile_scene(ball).body_inertia[1] == pytest.approx([0.4 * 0.1**2] * 3, rel=RTOL)


def test_tiny_body_below_mujocos_limit_is_refused():
    tiny = Body("tiny", Inertia.solid_sphere(1e-6, 1e-5))  # moments 4e-17 kg m^2 < 1e-14
    with pytest.raises(ValueError, match="1e-14"):
        to_mjcf(handmade([tiny], [Joint("h", "hinge", "tiny")]))
    assert MUJOCO_MIN_MOMENT == 1e-14


hinge = Joint("h", "hinge", "b")
ball = Body("b", Inertia.solid_sphere(1.0, 0.1), shapes=(Shape("s", "sphere", (0.1,)),))


@pytest.mark.parametrize("bodies, joints, fixed, contacts, match", [
    ([ball, dataclasses.replace(ball, name="b", shapes=())], [hinge], [], [], "two bodys are called 'b'"),
    ([dataclasses.replace(ball, name="world")], [], [], [], "world"),
    ([ball], [hinge, dataclasses.replace(hinge, body="b")], [], [], "two joints"),
    ([ball], [hinge], [Shape("s", "plane", (1.0, 1.0))], [], "two shapes"),
    ([dataclasses.replace(ball, name="a\tb")], [dataclasses.replace(hinge, body="a\tb")], [], [], "control"),
    ([ball], [dataclasses.replace(hinge, body="nobody")], [], [], "not a body"),
    ([dataclasses.replace(ball, parent="nobody")], [hinge], [], [], "parent"),
    ([ball], [hinge], [], [Contact("s", "floor")], "not a shape"),
    ([dataclasses.replace(ball, shapes=(Shape("p", "plane", (1.0, 1.0)),))], [hinge], [], [], "plane"),
    ([dataclasses.replace(ball, shapes=(Shape("s", "box", (0.1, 0.0, 0.1)),))], [hinge], [], [], "size"),
    ([dataclasses.replace(ball, shapes=(Shape("s", "sphere", (0.1, 0.2)),))], [hinge], [], [], "1 sizes"),
    ([ball, Body("c", Inertia.solid_sphere(1.0, 0.1), parent="b")], [hinge, Joint("f", "free", "c")], [], [],
     "free joint"),
])
def test_what_mujoco_refuses_is_refused_first(bodies, joints, fixed, contacts, match):
    with pytest.raises(ValueError, match=match):
        to_mjcf(handmade(bodies, joints, fixed, contacts))


def test_empty_names_are_refused_when_the_body_or_joint_is_made():
    """(Before issue 23 to_mjcf refused them; Body and Joint now check their fields at construction.)"""
    with pytest.raises(ValueError, match="non-empty"):
        dataclasses.replace(ball, name="")
    with pytest.raises(ValueError, match="non-empty"):
        dataclasses.replace(hinge, body="")


def test_batched_scene_is_refused():
    with pytest.raises(ValueError, match="item"):
        to_mjcf(swinging_rod(1.0, theta0=[0.1, 0.2], t_end=1.0))


# ----- contacts, state, mesh ---------------------------------------------------------------------------

def two_balls(restitution: float, friction: float = 0.0):
    balls = [Body(f"b{i}", Inertia.solid_sphere(1.0, 0.1), shapes=(Shape(f"s{i}", "sphere", (0.1,)),),
                  pos=(0.5 * i, 0.0, 0.0)) for i in range(2)]
    joints = [Joint(f"x{i}", "slide", f"b{i}", axis=(1.0, 0.0, 0.0), qvel0=1.0 - 2 * i) for i in range(2)]
    return handmade(balls, joints, [Shape("floor", "plane", (0.0, 0.0), pos=(0.0, 0.0, -0.1))],
                    [Contact("s0", "s1", friction=friction, restitution=restitution),
                     Contact("s0", "floor", friction=0.5, restitution=0.0)])


def pair_of(model, geom1: str, geom2: str) -> int:
    """Index of the compiled pair between two named geoms (MuJoCo sorts the pairs)."""
    wanted = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in (geom1, geom2)}
    return next(p for p in range(model.npair) if {model.pair_geom1[p], model.pair_geom2[p]} == wanted)


def test_elastic_impacts_get_the_undamped_stiff_contact():
    dt = 2e-3
    model = compile_scene(two_balls(1.0), dt=dt)
    assert model.npair == 2 and model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    impact, resting = pair_of(model, "s0", "s1"), pair_of(model, "s0", "floor")
    assert model.pair_dim[impact] == 1
    np.testing.assert_array_equal(model.pair_solref[impact], [-1 / dt**2, 0.0])
    np.testing.assert_array_equal(model.pair_solimp[impact, :3], CONTACT_SOLIMP)
    # the frictional resting pair: condim 3, friction mu, critically damped with time constant 2 dt
    assert model.pair_dim[resting] == 3 and model.pair_friction[resting, 0] == 0.5
    np.testing.assert_array_equal(model.pair_solref[resting], [2 * dt, 1.0])
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and model.opt.impratio == 100
    # nothing else collides
    assert np.all(model.geom_contype == 0) and np.all(model.geom_conaffinity == 0)


def test_inelastic_impact_damping_follows_the_restitution():
    """0 < e < 1: K = (pi / (30 dt))^2 and B = 2 zeta sqrt(K / 0.99), zeta giving restitution e to a
    spring-damper that pushes but never pulls."""
    dt, e = 1e-3, 0.5
    model = compile_scene(two_balls(e), dt=dt)
    stiffness, damping = -model.pair_solref[pair_of(model, "s0", "s1")]
    assert stiffness == pytest.approx((math.pi / (30 * dt)) ** 2, rel=1e-15)
    zeta = damping / (2 * math.sqrt(stiffness / 0.99))
    assert pushing_restitution(zeta) == pytest.approx(e, rel=1e-12)


@pytest.mark.parametrize("zeta", [0.05, 0.3, 0.7, 0.99, 1.0, 1.5, 4.0])
def test_pushing_restitution_matches_the_integrated_contact(zeta):
    """x'' = -x - 2 zeta x' from x = 0, x' = 1, integrated (scipy, 1e-12) until the force x + 2 zeta x'
    falls to 0: the closed form gives -x'(end); for zeta -> 0 it tends to 1 and exceeds exp(-pi zeta /
    sqrt(1 - zeta^2)), the restitution of a contact that would pull until x = 0."""
    from scipy.integrate import solve_ivp

    def ends(t, y):
        return y[0] + 2 * zeta * y[1]

    ends.terminal, ends.direction = True, -1
    solution = solve_ivp(lambda t, y: [y[1], -y[0] - 2 * zeta * y[1]], (0.0, 100.0), [0.0, 1.0], events=ends,
                         rtol=1e-12, atol=1e-14)
    assert pushing_restitution(zeta) == pytest.approx(-solution.y_events[0][0][1], rel=1e-9)
    if zeta < 1:
        assert pushing_restitution(zeta) > math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
    assert impact_damping_ratio(pushing_restitution(zeta)) == pytest.approx(zeta, rel=1e-6)


def test_settings_override_the_defaults():
    model = compile_scene(two_balls(1.0), dt=1e-3, integrator="RK4", solref=(0.01, 0.5), solimp=(0.9, 0.95, 0.001),
                          condim=3, cone="pyramidal", impratio=2.0, noslip_iterations=5)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    np.testing.assert_array_equal(model.pair_solref, [[0.01, 0.5]] * 2)
    assert list(model.pair_dim) == [3, 3] and model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert model.opt.impratio == 2.0 and model.opt.noslip_iterations == 5
    for bad in ({"integrator": "rk4"}, {"cone": "round"}, {"condim": 2}, {"solref": (1.0,)}, {"dt": 0.0}):
        with pytest.raises(ValueError):
            to_mjcf(two_balls(1.0), **bad)


def test_joints_carry_no_damping_armature_or_limits():
    model = compile_scene(pendulum_chain(3, theta0=[0.1, 0.2, 0.3], t_end=1.0))
    for field in ("dof_damping", "dof_armature", "dof_frictionloss", "jnt_stiffness"):
        assert np.all(getattr(model, field) == 0), field
    assert not np.any(model.jnt_limited)


def test_free_joint_angular_velocity_is_written_in_the_body_frame():
    """Keyframe qvel = (v origin, R^T omega): MuJoCo then reports the scene's world omega and the
    centre-of-mass velocity v + omega x (com - origin)."""
    quat = np.array([0.8, 0.1, -0.5, 0.3]) / np.linalg.norm([0.8, 0.1, -0.5, 0.3])
    body = Body("b", Inertia.box(2.0, (0.3, 0.5, 0.7)).translated([0.1, 0.2, -0.1]), pos=(1.0, 2.0, 3.0),
                quat=tuple(quat))
    v, omega = np.array([0.3, -0.2, 0.1]), np.array([1.0, -2.0, 3.0])
    scene = handmade([body], [Joint("free", "free", "b", qvel0=(tuple(v), tuple(omega)))], gravity=0.0)
    qpos, qvel = initial_state(scene.layout)
    rotation = quat_to_matrix(quat)
    np.testing.assert_allclose(qvel[3:], rotation.T @ omega, rtol=0, atol=1e-15)
    model = compile_scene(scene)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    twist = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, 1, twist, 0)
    np.testing.assert_allclose(twist[:3], omega, rtol=0, atol=1e-14)
    com = np.array(body.pos) + rotation @ body.inertia.com
    np.testing.assert_allclose(data.xipos[1], com, rtol=0, atol=1e-14)
    np.testing.assert_allclose(twist[3:], v + np.cross(omega, com - np.array(body.pos)), rtol=0, atol=1e-14)


def u_prism(path) -> str:
    """A non-convex U-shaped prism saved as OBJ: in the x-y plane a bar 0.75 x 0.25 with two arms 0.25 x 0.5
    standing on its ends, 0.25 thick. Its centroid lies in the notch, outside the body."""
    trimesh = pytest.importorskip("trimesh")
    outline = 0.25 * np.array([[0, 0], [3, 0], [3, 3], [2, 3], [2, 1], [1, 1], [1, 3], [0, 3]], dtype=float)
    n = len(outline)
    vertices = np.vstack([np.column_stack([outline, np.zeros(n)]), np.column_stack([outline, np.full(n, 0.25)])])
    caps = [[0, 1, 4], [0, 4, 5], [0, 5, 7], [5, 6, 7], [1, 2, 4], [2, 3, 4]]  # counter-clockwise seen from +z
    faces = [[a, c, b] for a, b, c in caps] + [[a + n, b + n, c + n] for a, b, c in caps]
    for i in range(n):
        j = (i + 1) % n
        faces += [[i, j, j + n], [i, j + n, i + n]]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight and mesh.volume == pytest.approx(7 / 16 * 0.25, rel=1e-12)
    file = str(path / "u_prism.obj")
    mesh.export(file)
    return file


def test_mesh_shape_gets_an_exact_inertia_asset(tmp_path):
    """The mesh asset says inertia="exact"; the body's mass properties are rbody's (explicit); and MuJoCo's
    own exact inertia of this non-convex mesh agrees with rbody's (its 'legacy' default does not)."""
    file = u_prism(tmp_path)
    mass = 2.0
    body = Inertia.from_mesh(file, mass=mass)
    exact = (Inertia.box(mass * 3 / 7, (0.75, 0.25, 0.25)).translated([0.375, 0.125, 0.125])
             + Inertia.box(mass * 2 / 7, (0.25, 0.5, 0.25)).translated([0.125, 0.5, 0.125])
             + Inertia.box(mass * 2 / 7, (0.25, 0.5, 0.25)).translated([0.625, 0.5, 0.125]))
    np.testing.assert_allclose(body.tensor, exact.tensor, rtol=0, atol=1e-14)
    scene = compound_pendulum(body, pivot=(0.0, 0.0, 0.125), theta0=0.2, t_end=1.0,
                              shapes=(Shape("u_prism", "mesh", mesh=file),))
    text = to_mjcf(scene)
    assert f'<mesh name="u_prism" file="{file}" inertia="exact"/>' in text
    assert_round_trip(scene)
    # MuJoCo's inertia from the geom (inertiafromgeom) with each mesh inertia mode
    found = {}
    for mode in ("exact", "legacy"):
        geometric = text.replace('inertiafromgeom="false"', 'inertiafromgeom="true"').replace(
            'inertia="exact"', f'inertia="{mode}"').replace("<geom ", f'<geom mass="{2.0!r}" ')
        model = mujoco.MjModel.from_xml_string(geometric)
        found[mode] = compiled_tensor(model, 1)
    written = exported_inertia(scene.layout.bodies[0]).inertia.tensor
    np.testing.assert_allclose(found["exact"], written, rtol=0, atol=1e-10 * np.max(np.abs(written)))
    assert np.max(np.abs(found["legacy"] - written)) > 1e-2 * np.max(np.abs(written))


def test_unit_axes_and_quaternions_are_written_as_given():
    """A vector already unit to 2 eps is not divided by its norm (whose last bit depends on the CPU's SIMD
    kernels): the axis (cos 0.14, 0, -sin 0.14), whose numpy norm here is 1 - 1.1e-16, is written as given."""
    a = 0.14
    axis = (math.cos(a), 0.0, -math.sin(a))
    quat = (math.cos(a / 2), 0.0, math.sin(a / 2), 0.0)
    joint = Joint("x", "slide", "b", axis=axis)
    assert joint.axis == axis
    body = Body("b", Inertia.solid_sphere(1.0, 0.1), shapes=(Shape("s", "sphere", (0.1,), quat=quat),), quat=quat)
    assert body.shapes[0].quat == quat
    text = to_mjcf(handmade([body], [joint]))
    assert f'axis="{axis[0]!r} 0.0 {axis[2]!r}"' in text
    assert text.count(f'quat="{quat[0]!r} 0.0 {quat[2]!r} 0.0"') == 2  # the body and its geom
    assert Joint("y", "slide", "b", axis=(3.0, 0.0, 4.0)).axis == (0.6, 0.0, 0.8)  # others are still normalised


@pytest.mark.parametrize("dt", [1e-200, 1e200])
def test_extreme_step_is_a_value_error_naming_it(dt):
    with pytest.raises(ValueError, match="dt="):
        to_mjcf(two_balls(1.0), dt=dt)


extreme = st.floats(min_value=5e-324, max_value=1.7e308, allow_nan=False, allow_infinity=False)


@settings(max_examples=80, deadline=None)
@given(mass=extreme, radius=extreme, dt=extreme, floor=st.none() | extreme, ratio=st.none() | extreme,
       restitution=st.sampled_from([0.0, 1e-300, 0.5, 1.0]), friction=st.sampled_from([0.0, 0.5, 1e300]))
def test_to_mjcf_on_extreme_values_gives_text_or_a_value_error(mass, radius, dt, floor, ratio, restitution, friction):
    """Never an OverflowError or ZeroDivisionError: a ValueError naming the value, or a model."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            body = Body("b", Inertia.solid_sphere(mass, radius), shapes=(Shape("s", "sphere", (radius,)),))
    except (ValueError, OverflowError, RuntimeWarning):
        assume(False)  # not a body rbody holds (Inertia's own refusal, or its overflow)
    balls = two_balls(restitution, friction)
    for scene in (handmade([body], [Joint("h", "hinge", "b")]), balls):
        try:
            text = to_mjcf(scene, dt=dt, min_inertia=floor, impratio=ratio)
        except ValueError:
            continue
        assert "<mujoco" in text and "nan" not in text and "inf" not in text


# ----- roll joints: a slide and a hinge tied by a joint equality ----------------------------------------------

def rolling_tree_scene(body="disc", radius=0.1, incline=0.5, **joint_changes):
    """The rolling scene's reduced tree (one roll joint) as a scene, with the roll joint's fields changed."""
    tree = rolling(body, radius=radius, incline=incline, t_end=1.0).rolling_tree()
    joint = dataclasses.replace(tree.joints[0], **joint_changes)
    return handmade(tree.bodies, [joint], fixed=tree.fixed, name=f"rolling_tree_{body}")


def test_roll_joint_is_a_slide_along_l_and_a_hinge_tied_by_a_stiff_equality():
    radius, incline, dt = 0.1, 0.5, 1e-3
    scene = rolling_tree_scene(radius=radius, incline=incline)
    assert_round_trip(scene, dt=dt)  # the mass properties as rbody computed them
    model = compile_scene(scene, dt=dt)
    slide = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "roll_slide")
    hinge = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "roll")
    assert (slide, hinge) == (0, 1)  # slide first, then the hinge (the order rbody composes them in)
    assert model.jnt_type[slide] == mujoco.mjtJoint.mjJNT_SLIDE and model.jnt_type[hinge] == mujoco.mjtJoint.mjJNT_HINGE
    # l = y x n = (cos alpha, 0, -sin alpha): down the slope
    np.testing.assert_allclose(model.jnt_axis[slide], [math.cos(incline), 0.0, -math.sin(incline)], rtol=0, atol=1e-15)
    np.testing.assert_allclose(model.jnt_axis[hinge], [0.0, 1.0, 0.0], rtol=0, atol=0)
    assert model.neq == 1 and model.eq_type[0] == mujoco.mjtEq.mjEQ_JOINT
    assert (model.eq_obj1id[0], model.eq_obj2id[0]) == (slide, hinge)
    np.testing.assert_array_equal(model.eq_data[0, :5], [0.0, radius, 0.0, 0.0, 0.0])  # slide = a hinge
    np.testing.assert_allclose(model.eq_solref[0], [2 * dt, 1.0], rtol=1e-15)
    np.testing.assert_allclose(model.eq_solimp[0, :3], [0.9999, 0.9999, 0.001], rtol=1e-15)
    assert "Roll joints (roll)" in to_mjcf(scene, dt=dt)  # the reduction is stated in the model


def test_roll_joint_initial_state_and_ref_place_the_body_as_rbody_does():
    """slide = a q0 and hinge = q0 in the keyframe, refs a ref and ref: MuJoCo then puts the centre at
    a (q0 - ref) l from its reference place, turned by q0 - ref about y (rbody.layout.Joint's roll)."""
    radius, incline, q0, rate, ref = 0.2, 0.4, 1.3, -0.7, 0.25
    scene = rolling_tree_scene(radius=radius, incline=incline, qpos0=q0, qvel0=rate, ref=ref)
    model = compile_scene(scene, dt=1e-3)
    np.testing.assert_allclose(model.qpos0, [radius * ref, ref], rtol=1e-15)
    qpos, qvel = initial_state(scene.layout)
    np.testing.assert_allclose(qpos, [radius * q0, q0], rtol=1e-15)
    np.testing.assert_allclose(qvel, [radius * rate, rate], rtol=1e-15)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    body = scene.layout.bodies[0]
    down = np.array([math.cos(incline), 0.0, -math.sin(incline)])
    np.testing.assert_allclose(data.xipos[1], np.array(body.pos) + radius * (q0 - ref) * down, rtol=0, atol=1e-15)
    turn = q0 - ref
    np.testing.assert_allclose(data.xquat[1], [math.cos(turn / 2), 0.0, math.sin(turn / 2), 0.0], rtol=0, atol=1e-15)
    # the centre's velocity is a q' l, the contact point's velocity zero
    velocity = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, 1, velocity, 0)  # (omega, v) at the com
    np.testing.assert_allclose(velocity[3:], radius * rate * down, rtol=0, atol=1e-15)
    normal = np.array([math.sin(incline), 0.0, math.cos(incline)])
    np.testing.assert_allclose(velocity[3:] + np.cross(velocity[:3], -radius * normal), 0.0, rtol=0, atol=1e-15)


# Measured (mujoco 4.0, RK4, disc a = 0.1 m on 0.5 rad, 1 s): the soft equality leaves the distance short by
# 5.36e-6 (dt = 1e-2), 5.36e-8 (1e-3), 5.36e-10 (1e-4) of the distance travelled, with the slide ahead of
# a hinge by 1.26e-5, 1.26e-7, 1.26e-9 m: both fall as dt^2 (the equality's stiffness grows as 1/dt^2).
# MuJoCo's Euler and implicitfast add their own first-order error (1.0e-3 relative at dt = 1e-3).
ROLL_EQUALITY_ERROR = {1e-3: 5.36e-8, 1e-4: 5.36e-10}


@pytest.mark.parametrize("body", ["disc", "hollow_cylinder", "solid_sphere", "spherical_shell"])
def test_mujoco_rolls_the_exported_roll_joint_by_the_closed_form(body):
    """x'' = g sin(alpha) / (1 + k): MuJoCo's run of the exported tree within the soft equality's error."""
    radius, incline = 0.1, 0.5
    scene = rolling(body, radius=radius, incline=incline, t_end=1.0)
    tree = handmade(scene.rolling_tree().bodies, scene.rolling_tree().joints, name=body)
    errors = {}
    for dt in ROLL_EQUALITY_ERROR:
        model = compile_scene(tree, dt=dt, integrator="RK4")
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        steps = round(1.0 / dt)
        distance, slip = np.empty(steps + 1), np.empty(steps + 1)
        distance[0], slip[0] = 0.0, 0.0
        for k in range(steps):
            mujoco.mj_step(model, data)
            distance[k + 1] = radius * data.qpos[1]
            slip[k + 1] = data.qpos[0] - radius * data.qpos[1]
        exact = scene.exact(np.arange(steps + 1) * dt)["distance"]
        assert scene.acceleration == pytest.approx(9.81 * math.sin(incline) / (1 + RATIO_OF[body]), rel=1e-15)
        errors[dt] = float(np.max(np.abs(distance - exact)) / exact[-1])
        assert errors[dt] <= 2 * ROLL_EQUALITY_ERROR[dt], (dt, errors[dt])

        assert np.max(np.abs(slip)) <= 0.2 * dt**2, (dt, np.max(np.abs(slip)))
    assert errors[1e-3] / errors[1e-4] > 50  # the soft equality's dt^2, not a fixed offset


RATIO_OF = {"disc": 1 / 2, "hollow_cylinder": 1.0, "solid_sphere": 2 / 5, "spherical_shell": 2 / 3}


def test_roll_joint_passive_attributes_go_on_the_hinge_the_coordinate_q():
    scene = rolling_tree_scene(damping=0.3, stiffness=2.0, springref=0.4, armature=0.01)
    model = compile_scene(scene, dt=1e-3)
    np.testing.assert_array_equal(model.dof_damping, [0.0, 0.3])
    np.testing.assert_array_equal(model.dof_armature, [0.0, 0.01])
    np.testing.assert_array_equal(model.jnt_stiffness, [0.0, 2.0])
    np.testing.assert_array_equal(model.qpos_spring, [0.0, 0.4])


def test_roll_joint_names_and_degrees_of_freedom_are_checked():
    tree = rolling(radius=0.1, incline=0.5).rolling_tree()
    body = tree.bodies[0]
    clash = Joint("roll_slide", "slide", "body", axis=(0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="roll_slide"):
        to_mjcf(handmade([body], [tree.joints[0], clash]))
    many = [Joint(f"s{i}", "slide", "body", axis="z") for i in range(5)]
    with pytest.raises(ValueError, match="at most 6 degrees of freedom"):
        to_mjcf(handmade([body], [*many, tree.joints[0]]))


def test_exported_roll_tree_has_the_engines_kinematics():
    """A user's tree (Scene.from_layout) with a roll joint carrying a pendulum, at a state away from rest: the
    exported model's body poses and velocities (MuJoCo's kinematics) equal the general engine's."""
    tree = rolling("spherical_shell", radius=0.2, incline=0.3).rolling_tree()
    wheel = dataclasses.replace(tree.joints[0], ref=0.2)
    bob = Body("bob", Inertia.box(0.3, (0.05, 0.1, 0.2)).translated([0.0, 0.0, -0.25]), parent="body",
               pos=(0.0, 0.0, 0.0))
    swing = Joint("swing", "hinge", "bob", axis=(0.0, 1.0, 0.0))
    user = Scene.from_layout(Layout(bodies=(*tree.bodies, bob), joints=(wheel, swing)), t_end=1.0,
                             qpos0=[1.1, -0.4], qvel0=[2.0, 0.7])
    model = compile_scene(user, dt=1e-3)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    np.testing.assert_allclose(data.qpos, [0.2 * 1.1, 1.1, -0.4], rtol=1e-15)
    mujoco.mj_forward(model, data)
    states = user.multibody.body_states(np.array([1.1, -0.4]), np.array([2.0, 0.7]))
    for i, name in enumerate(user.multibody.body_names):
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, b, velocity, 0)
        np.testing.assert_allclose(states["com"][i], data.xipos[b], rtol=0, atol=1e-14)
        np.testing.assert_allclose(states["velocity"][i], velocity[3:], rtol=0, atol=1e-14)
        np.testing.assert_allclose(states["omega"][i], velocity[:3], rtol=0, atol=1e-14)


def test_exported_roll_joint_reads_back_as_a_slide_and_a_hinge_tied_by_a_joint_equality():
    """MJCF has no roll joint: what to_mjcf writes for one (a slide, a hinge and a joint equality slide - ref =
    a (hinge - ref)) reads back as exactly that, the equality held rigidly, its softness noted."""
    from rbody.mjcf import from_mjcf

    radius = 0.1
    read = from_mjcf(to_mjcf(rolling_tree_scene(radius=radius), dt=1e-3))
    assert [j.kind for j in read.tree.joints] == ["slide", "hinge"]
    (equality,) = read.tree.equalities
    assert (equality.kind, equality.joint1, equality.joint2) == ("joint", "roll_slide", "roll")
    assert equality.polycoef == (0.0, radius, 0.0, 0.0, 0.0) and equality.active
    assert any("rigidly" in note for note in read.import_notes)
