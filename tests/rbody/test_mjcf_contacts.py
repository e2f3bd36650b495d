"""MJCF contacts read as MuJoCo's rules keep them (rbody.mjcf.contacts), run rigidly, against the closed forms; MuJoCo's
divergence from the rigid limit on the same file recorded as a finding."""

import numpy as np
import pytest

import rbody
from rbody import from_mjcf
from rbody.mjcf.document import MJCFError

G = 9.81


def rolling_ball(v0=2.0, mu=0.3, extra=""):
    return f"""<mujoco model="roll">
  {extra}
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" friction="0.1"/>
    <body name="ball" pos="0 0 0.1">
      <freejoint name="free"/>
      <geom name="s" type="sphere" size="0.1" mass="1" friction="{mu}"/>
    </body>
  </worldbody>
  <keyframe><key qvel="{v0} 0 0 0 0 0"/></keyframe>
</mujoco>"""


def test_contact_rules_friction_max_and_filters(tmp_path):
    xml = """<mujoco><worldbody>
      <geom name="floor" type="plane" size="0 0 1" friction="0.4"/>
      <body name="a" pos="0 0 1"><freejoint/><geom name="ga" type="sphere" size="0.1" friction="0.2" condim="1"/>
        <body name="child" pos="0 0 0.3"><joint type="hinge"/><geom name="gc" type="capsule" size="0.05 0.1"/></body>
      </body>
      <body name="b" pos="1 0 1"><freejoint/><geom name="gb" type="sphere" size="0.1" priority="1" friction="0.05"/>
      </body>
      <body name="ghost" pos="2 0 1"><freejoint/><geom name="gg" type="sphere" size="0.1" contype="0" conaffinity="0"/>
      </body>
    </worldbody>
    <contact><exclude body1="a" body2="b"/></contact>
    <custom><numeric name="rbody.contact_restitution.gb" data="0.5"/></custom></mujoco>"""
    path = tmp_path / "rules.xml"
    path.write_text(xml)
    scene = from_mjcf(path)
    pairs = {frozenset((c.shape_a, c.shape_b)): c for c in scene.tree.contacts}
    # the parent-child pair a/child is filtered, a/b excluded, the ghost collides with nothing
    assert set(pairs) == {frozenset(p) for p in [("floor", "ga"), ("floor", "gc"), ("floor", "gb"), ("gc", "gb")]}
    assert pairs[frozenset(("floor", "ga"))].friction == 0.4 and pairs[frozenset(("floor", "ga"))].condim == 3
    assert pairs[frozenset(("floor", "gb"))].friction == 0.05          # priority wins over the larger friction
    assert pairs[frozenset(("floor", "gb"))].restitution == 0.5
    assert pairs[frozenset(("floor", "gc"))].restitution == 0.0
    # the same pairs as MuJoCo's broad phase keeps (its contact list with a wide margin)
    mujoco = pytest.importorskip("mujoco")
    wide = xml.replace("<worldbody>", '<default><geom margin="100"/></default><worldbody>', 1)
    m = mujoco.MjModel.from_xml_string(wide)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    seen = {frozenset((m.geom(c.geom1).name, m.geom(c.geom2).name)) for c in d.contact[:d.ncon]}
    assert seen == set(pairs)


def test_unsupported_pair_refused_with_its_line(tmp_path):
    path = tmp_path / "cyl.xml"
    text = ('<mujoco><asset><hfield name="h" nrow="2" ncol="2" size="1 1 0.1 0.1"/></asset><worldbody>'
            '<geom name="floor" type="hfield" hfield="h"/>\n<body name="stand"><inertial pos="0 0 0" mass="1" '
            'diaginertia="1 1 1"/><geom name="plane" type="plane" size="1 1 1"/></body>\n'
            '<geom name="mark" type="sphere" size="0.1" pos="2 0 0"/><body name="frame"><geom name="tag" '
            'type="sphere" size="0.05" pos="3 0 0" mass="0"/></body>'
            '<body><freejoint/><geom name="c" type="ellipsoid" size="0.1 0.2 0.3"/></body></worldbody>{}</mujoco>')
    path.write_text(text.format(""))
    assert len(from_mjcf(path).layout.contacts) == 4  # the ellipsoid with the height field, the plane, the spheres
    path.write_text(text.format('<contact><pair geom1="floor" geom2="plane"/></contact>'))
    with pytest.raises(MJCFError, match=r"cyl.xml, line 1.*'floor' and 'plane' \(line 2\) can collide.*"
                                        r"hfield-plane contacts"):
        from_mjcf(path)
    path.write_text(text.format('<contact><pair geom1="floor" geom2="mark"/></contact>'))  # both on the world
    with pytest.raises(MJCFError, match=r"cyl.xml, line 3.*are both on body 'world':"):
        from_mjcf(path)
    path.write_text(text.format('<contact><pair geom1="tag" geom2="mark"/></contact>'))  # 'frame' is the world's
    with pytest.raises(MJCFError, match=r"both on body 'world' \(body 'frame' has neither mass nor joints"):
        from_mjcf(path)


def test_torsional_and_rolling_friction_read_as_mujoco_combines_them(tmp_path):
    """A geom's friction is (sliding, torsional, rolling), MuJoCo's defaults 1 0.005 0.0001 for what it leaves out;
    the larger of each at equal priority, the higher priority's whole; condim the larger; a <pair>'s five."""
    path = tmp_path / "spin.xml"
    path.write_text('<mujoco><worldbody><geom name="floor" type="plane" size="0 0 1" friction="0.7 0.001"/>\n'
                    '<body pos="0 0 1"><freejoint/><geom name="a" type="sphere" size="0.1" condim="6" '
                    'friction="0.5 0.002 0.003"/></body>\n'
                    '<body pos="1 0 1"><freejoint/><geom name="b" type="sphere" size="0.1" condim="4" priority="1" '
                    'friction="0.4"/></body>\n'
                    '<body pos="3 0 1"><freejoint/><geom name="c" type="sphere" size="0.1"/></body>\n'
                    '<body pos="5 0 1"><freejoint/><geom name="d" type="sphere" size="0.1"/></body>\n'
                    '</worldbody><contact><pair geom1="floor" geom2="d" condim="6" friction="0.9 0.9 0.01 0.02"/>'
                    '</contact></mujoco>')
    pairs = {frozenset((c.shape_a, c.shape_b)): c for c in from_mjcf(path).tree.contacts}
    a, b, c, d = (pairs[frozenset(("floor", name))] for name in "abcd")
    assert (a.condim, a.friction, a.torsion, a.rolling) == (6, 0.7, 0.002, 0.003)    # the larger of each
    assert (b.condim, b.friction, b.torsion, b.rolling) == (4, 0.4, 0.005, 0.0)      # priority: b's own, defaults
    assert (c.condim, c.torsion, c.rolling) == (3, 0.0, 0.0)                          # condim 3: no torque
    assert (d.condim, d.friction, d.torsion, d.rolling) == (6, 0.9, 0.01, 0.02)      # the pair's own


def test_rolling_ball_from_mjcf_and_mujoco_divergence(tmp_path):
    """The sphere thrown sliding: rbody rolls at 5/7 v0 from t* = 2 v0 / (7 mu g), height r to round-off; MuJoCo
    (its defaults: soft contact, pyramidal cone, dt 2 ms) on the same file sinks and slips: a finding, printed."""
    v0, mu, dt = 2.0, 0.3, 1e-3
    path = tmp_path / "roll.xml"
    path.write_text(rolling_ball(v0, mu))
    scene = from_mjcf(path, t_end=1.0, keyframe=0)
    run = rbody.simulate(scene, dt=dt)
    v, spin, z = run["ball.velocity"][:, 0], run["ball.omega"][:, 1], run["ball.com"][:, 2]
    t_star = 2 * v0 / (7 * mu * G)
    after = run.t > t_star + dt
    np.testing.assert_allclose(v[after], 5 / 7 * v0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[after] - 0.1 * spin[after], 0.0, rtol=0, atol=1e-12)
    assert np.abs(z - 0.1).max() <= 1e-15
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.timestep = dt
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    sink, speed = 0.0, []
    for _ in range(1000):
        mujoco.mj_step(m, d)
        sink = max(sink, 0.1 - d.qpos[2])
        speed.append(d.qvel[0])
    slip = d.qvel[0] - 0.1 * d.qvel[4]
    print(f"MuJoCo (defaults, dt={dt}): sinks {sink:.3g} m, final speed {speed[-1]:.6f} m/s against 5/7 v0 = "
          f"{5 / 7 * v0:.6f}, slip {slip:.3g} m/s; rbody: {abs(v[-1] - 5 / 7 * v0):.2g} m/s, height exact")
    assert sink > 1e-6                                    # MuJoCo's soft contact sinks (the finding, measured)


def rolling_friction_ball(cone="pyramidal", dt=2e-3):
    """A solid ball (r 0.1 m, 1 kg) rolling at 1 m/s on a floor, condim 6, torsional 0.02 m, rolling 0.01 m."""
    return f"""<mujoco><option timestep="{dt}" cone="{cone}"/><worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <body name="ball" pos="0 0 0.1"><freejoint/>
      <geom name="s" type="sphere" size="0.1" mass="1" condim="6" friction="1 0.02 0.01"/></body>
  </worldbody><keyframe><key qvel="1 0 0 0 10 0"/></keyframe></mujoco>"""


def test_rolling_friction_from_mjcf_and_mujoco_divergence(tmp_path):
    """The chapter's rolling ball with rolling friction (condim 6): rbody decelerates it at mu_r g / (r (1 + 2/5))
    without slip; MuJoCo bounds sliding and rolling friction in one cone, so that a rolling torque at its bound
    leaves no friction force to decelerate the centre: the ball slips and decelerates less (a finding, printed and
    asserted measurable: 5 % less with its default pyramidal cone, 0.05 % with the elliptic one)."""
    dt, r, mu_r = 2e-3, 0.1, 0.01
    decel = mu_r * G / (r * 1.4)
    path = tmp_path / "rolling.xml"
    path.write_text(rolling_friction_ball(dt=dt))
    run = rbody.simulate(from_mjcf(path, t_end=1.0, keyframe=0), dt=dt)
    v, spin = run["ball.velocity"][:, 0], run["ball.omega"][:, 1]
    np.testing.assert_allclose(v, 1.0 - decel * run.t, rtol=0, atol=1e-12)
    assert np.abs(v - r * spin).max() <= 1e-12
    mujoco = pytest.importorskip("mujoco")
    for cone, least in (("pyramidal", 1e-2), ("elliptic", 1e-4)):
        path.write_text(rolling_friction_ball(cone, dt))
        m = mujoco.MjModel.from_xml_path(str(path))
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        samples = []
        for _ in range(400):
            mujoco.mj_step(m, d)
            samples.append((d.time, d.qvel[0], d.qvel[0] - r * d.qvel[4]))
        t, speed, slip = np.array(samples).T
        later = t > 0.1
        mujoco_decel = -np.polyfit(t[later], speed[later], 1)[0]
        print(f"MuJoCo ({cone}, dt={dt}): deceleration {mujoco_decel:.6f} m/s^2 against {decel:.6f} "
              f"({mujoco_decel / decel - 1:+.2%}), slip up to {np.abs(slip[later]).max():.3g} m/s; rbody exact")
        assert abs(mujoco_decel / decel - 1) > least                # the finding, measured


def incline_xml(mu, alpha=0.3, dt=1e-3):
    q = f"{float(np.cos(alpha / 2))!r} 0 {float(np.sin(alpha / 2))!r} 0"
    n = np.array([np.sin(alpha), 0.0, np.cos(alpha)])  # the plane's normal (its z axis turned by alpha about y)
    pos = " ".join(repr(float(c)) for c in 0.05 * n)
    return f"""<mujoco model="incline"><option timestep="{dt}"/>
  <worldbody>
    <geom name="ramp" type="plane" size="0 0 1" quat="{q}" friction="{float(mu)!r}"/>
    <body name="box" pos="{pos}" quat="{q}"><freejoint/>
      <geom name="b" type="box" size="0.1 0.1 0.05" mass="1" friction="{float(mu)!r}"/></body>
  </worldbody></mujoco>"""


def test_block_on_incline_from_mjcf_sticks_and_mujoco_creeps(tmp_path):
    """mu = tan(alpha)(1 + 1e-6): rbody's block stays put (round-off) through from_mjcf; MuJoCo's (defaults) creeps
    down the slope, since its friction is a soft constraint (a finding, printed and asserted measurable)."""
    alpha, t_end, dt = 0.3, 2.0, 1e-3
    path = tmp_path / "incline.xml"
    path.write_text(incline_xml(np.tan(alpha) * (1 + 1e-6), alpha, dt))
    run = rbody.simulate(from_mjcf(path, t_end=t_end), dt=dt)
    moved = np.abs(run["box.com"] - run["box.com"][0]).max()
    assert moved <= 1e-13
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    start = d.qpos[:3].copy()
    mujoco.mj_forward(m, d)
    start = d.qpos[:3].copy()
    for _ in range(int(round(t_end / dt))):
        mujoco.mj_step(m, d)
    creep = np.linalg.norm(d.qpos[:3] - start)
    print(f"block at mu = tan(alpha)(1 + 1e-6), {t_end} s: rbody moved {moved:.2g} m; MuJoCo (defaults) {creep:.3g} m")
    assert creep > 1e-6


def test_pair_of_one_bodys_geoms_refused_with_its_line(tmp_path):
    """A <pair> of two geoms of one body (fixed to each other) is an MJCFError naming the <pair>'s line and the body,
    before the layout is built; a pair across a welded child body (no joint: still two bodies) loads."""
    xml = """<mujoco><worldbody><body name="a"><freejoint/><geom name="g1" type="sphere" size="0.1"/>
      <geom name="g2" type="sphere" size="0.1" pos="0.3 0 0"/>
      <body name="b" pos="0 0.3 0"><geom name="g3" type="sphere" size="0.1"/></body></body></worldbody>
      <contact>
        <pair geom1="g1" geom2="g2"/>
      </contact></mujoco>"""
    path = tmp_path / "same_body.xml"
    path.write_text(xml)
    with pytest.raises(MJCFError, match=r"same_body.xml, line 5.*geom1='g1' and geom2='g2' are both on body 'a'"):
        from_mjcf(path)
    path.write_text(xml.replace('geom2="g2"', 'geom2="g3"'))
    pairs = {frozenset((c.shape_a, c.shape_b)) for c in from_mjcf(path).tree.contacts}
    assert frozenset(("g1", "g3")) in pairs


def test_explicit_pair_replaces_the_dynamic_one(tmp_path):
    """<pair> with its own friction and condim (MuJoCo's defaults for a pair: friction 1, condim 3), whatever the
    filters (contype 0 here), and in place of the dynamic pair of the same geoms, as MuJoCo's contact list shows."""
    xml = """<mujoco><default><pair friction="0.7 0.7 0.005 0.0001 0.0001"/></default><worldbody>
      <geom name="floor" type="plane" size="0 0 1" friction="0.2"/>
      <body name="a" pos="0 0 1"><freejoint/><geom name="ga" type="sphere" size="0.1"/></body>
      <body name="b" pos="1 0 1"><freejoint/><geom name="gb" type="box" size="0.1 0.1 0.1" contype="0" conaffinity="0"/>
      </body></worldbody>
      <contact><pair geom1="floor" geom2="ga" condim="1"/><pair geom1="gb" geom2="floor"/></contact></mujoco>"""
    path = tmp_path / "pairs.xml"
    path.write_text(xml)
    contacts = {frozenset((c.shape_a, c.shape_b)): c for c in from_mjcf(path).tree.contacts}
    assert set(contacts) == {frozenset(("floor", "ga")), frozenset(("floor", "gb"))}
    assert contacts[frozenset(("floor", "ga"))].friction == 0.7 and contacts[frozenset(("floor", "ga"))].condim == 1
    assert contacts[frozenset(("floor", "gb"))].friction == 0.7 and contacts[frozenset(("floor", "gb"))].condim == 3
    mujoco = pytest.importorskip("mujoco")
    wide = xml.replace('<pair geom1="floor" geom2="ga" condim="1"/>', '<pair geom1="floor" geom2="ga" condim="1" '
                       'margin="10"/>').replace('<pair geom1="gb" geom2="floor"/>',
                                                '<pair geom1="gb" geom2="floor" margin="10"/>')
    m = mujoco.MjModel.from_xml_string(wide)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    seen = {frozenset((m.geom(c.geom1).name, m.geom(c.geom2).name)): (c.friction[0], c.dim)
            for c in d.contact[:d.ncon]}
    assert seen == {frozenset(("floor", "ga")): (0.7, 1), frozenset(("floor", "gb")): (0.7, 3)}
