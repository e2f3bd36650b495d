"""Hard case 10, contacts in the rigid limit (validation/hard/rigid_contacts.py): its measures against closed forms
sampled anywhere, MuJoCo's documented defaults as a bare MJCF file has them, and the quick case run once in rbody,
MuJoCo and pymunk, with what it must find: rbody at round-off (or within its time-stepping's one step per event,
shrinking with the step), MuJoCo's soft contacts sinking and creeping, pymunk's rows present."""

from __future__ import annotations

import math

import numpy as np
import pytest

from validation.hard import rigid_contacts as rc
from validation.hard.suite import CASES, case_function

G = rc.G


# ----- the measures, on closed forms sampled at steps that do not meet the events ---------------------------------

def thrown_samples(t, mu):
    """The thrown sphere's exact com, velocity, omega (T, 3) at times t under friction mu: it rolls from
    2 v0 / (7 mu g) at 5/7 v0 whatever mu."""
    v0, r = rc.THROW_SPEED, rc.RADIUS
    t_star = 2 * v0 / (7 * mu * G)
    sliding = np.minimum(t, t_star)
    v = v0 - mu * G * sliding
    w = 5 * mu * G * sliding / (2 * r)                  # torque mu m g r over I = 2/5 m r^2, about +y
    x = v0 * sliding - mu * G * sliding**2 / 2 + v * (t - sliding)
    zeros = np.zeros_like(t)
    return (np.stack([x, zeros, zeros + r], 1), np.stack([v, zeros, zeros], 1), np.stack([zeros, w, zeros], 1))


def test_thrown_measures_read_the_closed_form_exactly_and_a_late_one_late():
    t = np.arange(0.0, 1.0, 0.00173)                    # no sample at t*
    measured = rc.thrown_measures(t, *thrown_samples(t, rc.THROW_MU))
    assert all(value <= 1e-13 for value in measured.values.values()), measured.values
    # friction 1 % short: sliding ends 2 v0 / (7 mu g) (1/0.99 - 1) late, at the same 5/7 v0
    late = rc.thrown_measures(t, *thrown_samples(t, 0.99 * rc.THROW_MU))
    t_star = 2 * rc.THROW_SPEED / (7 * rc.THROW_MU * G)
    assert late.values["transition time error [s]"] == pytest.approx(t_star / 99, abs=1e-12)
    assert late.values["rolling speed error [m/s]"] <= 1e-15
    com, velocity, omega = thrown_samples(t, rc.THROW_MU)
    sunk = rc.thrown_measures(t, com - np.array([0.0, 0.0, 1e-4]), velocity, omega)
    assert sunk.values["height error [m]"] == pytest.approx(1e-4, abs=1e-15)


def drop_samples(t, e, shift=0.0):
    """The dropped ball's exact com and velocity (T, 3) at times t (impacts at the closed form's times + shift)."""
    impacts = rc.impact_times_closed(e, 12) + shift
    z0, h = rc.RADIUS + rc.DROP_HEIGHT, rc.RADIUS
    z, vz = np.empty_like(t), np.empty_like(t)
    for i, s in enumerate(t):
        k = np.searchsorted(impacts, s, side="right")
        if k == 0:
            z[i], vz[i] = z0 - G * (s - shift) ** 2 / 2 if s > shift else z0, -G * max(s - shift, 0.0)
        else:
            up = e**k * math.sqrt(2 * G * rc.DROP_HEIGHT)
            dt = s - impacts[k - 1]
            z[i], vz[i] = h + up * dt - G * dt**2 / 2, up - G * dt
    zeros = np.zeros_like(t)
    return np.stack([zeros, zeros, z], 1), np.stack([zeros, zeros, vz], 1)


def test_drop_measures_read_impacts_and_bounces_exactly():
    t = np.arange(0.0, 1.5, 0.0021)
    measured = rc.drop_measures(t, *drop_samples(t, 0.5), 0.5)
    assert measured.values["impact time error [s]"] <= 1e-13
    assert measured.values["bounce height error [m]"] <= 1e-13
    shifted = rc.drop_measures(t, *drop_samples(t, 0.5, shift=2e-3), 0.5)
    assert shifted.values["impact time error [s]"] == pytest.approx(2e-3, abs=1e-12)
    assert np.allclose(shifted.extras["impact errors"], 2e-3, atol=1e-12)


def test_incline_measures_tell_a_creeping_block_from_one_at_rest():
    t = np.linspace(0.0, 2.0, 1001)
    R = rc.incline_rotation()
    still = np.tile(R[:, 2] * 0.05, (t.size, 1))
    sticking = math.tan(rc.ALPHA) * (1 + 1e-6)
    assert rc.incline_measures(t, still, sticking, 2e-3).values == {"displacement [m]": 0.0}
    creep = still + np.outer(1e-3 * t, R[:, 0])          # 1 mm/s down the slope
    assert rc.incline_measures(t, creep, sticking, 2e-3).values["displacement [m]"] == pytest.approx(2e-3)
    sliding = math.tan(rc.ALPHA) * 0.5
    a = rc.incline_acceleration(sliding)
    exact = still + np.outer(a * t**2 / 2, R[:, 0])
    measured = rc.incline_measures(t, exact, sliding, 2e-3)
    assert measured.values["position error [m]"] <= 1e-15
    assert measured.extras["scheme error"] == pytest.approx(a * 2.0 * 2e-3 / 2)   # a t dt / 2 at the end


def test_painleve_measures_read_a_rolling_end_as_no_slide_and_a_sliding_one_as_its_slide():
    """A rod turning at -0.5 rad/s on its end's sphere rolling (x_E = x_E0 + r a): no slide, no slip; the same with
    the rod carried 1e-3 m and 0.01 m/s towards -x: that slide and that slip."""
    closed = rc.rod_closed_form()
    ex, ez, r = closed["dx"], closed["dz"] + rc.ROD_RADIUS, rc.ROD_RADIUS
    t = np.linspace(0.0, 0.2, 101)
    omega = -0.5
    a = omega * t
    x = ex + r * a - ex * np.cos(a) - ez * np.sin(a)
    vx = omega * (r + ex * np.sin(a) - ez * np.cos(a))
    qpos, qvel = np.stack([x, 0 * t, a], 1), np.stack([vx, 0 * t, 0 * t + omega], 1)
    rolling = rc.painleve_measures(t, qpos, qvel)
    assert rolling.values["end slide [m]"] <= 1e-16 and rolling.values["slip one step after [m/s]"] <= 1e-16
    drift = 1e-3 * t / t[-1]
    sliding = rc.painleve_measures(t, qpos - np.stack([drift, 0 * t, 0 * t], 1),
                                   qvel - np.stack([0 * t + 1e-3 / t[-1], 0 * t, 0 * t], 1))
    assert sliding.values["end slide [m]"] == pytest.approx(1e-3, rel=1e-12)
    assert sliding.values["slip one step after [m/s]"] == pytest.approx(1e-3 / t[-1], rel=1e-12)
    assert closed["mu_P"] < rc.ROD_MU and closed["Pt"] / closed["Pn"] == pytest.approx(closed["mu_P"], rel=1e-14)


def test_mujoco_defaults_are_a_bare_mjcf_files():
    """The rows named "defaults" are MuJoCo's documented defaults: the backend with MUJOCO_DEFAULTS steps the thrown
    sphere exactly as a bare MJCF file does (no option, no solref, no solimp written)."""
    import mujoco

    import validation

    dt, r, mu, v0 = rc.STEP, rc.RADIUS, rc.THROW_MU, rc.THROW_SPEED
    xml = (f'<mujoco><worldbody><geom type="plane" size="0 0 1" friction="{mu}"/><body pos="0 0 {r}"><freejoint/>'
           f'<geom type="sphere" size="{r}" mass="1" friction="{mu}"/></body></worldbody>'
           f'<keyframe><key qvel="{v0} 0 0 0 0 0"/></keyframe></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.opt.timestep == dt                              # STEP is MuJoCo's default step
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    heights = [data.qpos[2]]
    for _ in range(250):
        mujoco.mj_step(model, data)
        heights.append(data.qpos[2])
    scene = rc.ball_scene(height=0.0, friction=mu, restitution=0.0, speed=v0, planar=False, t_end=0.5)
    run = validation.run(scene, "mujoco", dt=dt, **rc.MUJOCO_DEFAULTS)
    assert np.array_equal(run["ball.com"][:, 2], heights)
    assert np.ptp(heights) > 1e-5                                # and the file's ball does move off r


# ----- the quick case, run once --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return case_function(10)(True, tmp_path_factory.mktemp("case10"))


def rows_of(result, backend, variant="", setting="", measure=""):
    return [r for r in result.rows if r.backend == backend and variant in r.variant and setting in r.setting
            and measure in r.measure]


def test_case_is_registered():
    assert 10 in CASES and case_function(10) is rc.case_rigid_contacts


@pytest.mark.crosssim
def test_rbody_meets_every_closed_form(result):
    rbody = rows_of(result, "rbody")
    assert len(rbody) == 41 and all(r.verdict == "pass" for r in rbody), [r for r in rbody if r.verdict != "pass"]
    # the event-driven scheme: every measure at round-off, but the rod's end, held at the velocity level, whose
    # rolling position RK4 integrates (1.2e-12 m after 0.2 s at 2 ms, measured)
    assert all(r.outcome == "exact" for r in rbody if r.setting.startswith("rk4") and r.measure != "end slide [m]")
    # the time-stepping: round-off except what it locates within a step, whose error is order 1
    order_one = ("impact time error", "bounce height error", "position error", "end slide", "slip one step after")
    for r in rbody:
        if r.setting.startswith("moreau") and not r.measure.startswith(order_one):
            assert r.outcome == "exact", r
    for variant, measure in (("e = 0.5", "impact time error"), ("e = 0.5", "bounce height error"),
                             ("x 0.999999", "position error"), ("Painleve", "end slide"),
                             ("Painleve", "slip one step after")):
        coarse, fine = (rows_of(result, "rbody", variant, f"moreau dt={dt:g}", measure)[0].value
                        for dt in (rc.STEP, rc.FINE))
        assert 0 < fine < coarse / 5, (variant, measure, coarse, fine)    # a step ten times finer, ~ten times less
    # the transition is read off the sliding samples: exact in both schemes, although moreau rolls from the step
    assert all(r.value <= 1e-13 for r in rows_of(result, "rbody", measure="transition time"))


@pytest.mark.crosssim
def test_mujoco_sinks_and_creeps(result):
    for variant in ("box resting", "stack"):
        for dt in (rc.STEP, rc.FINE):
            row = rows_of(result, "mujoco", variant, f"defaults dt={dt:g}", "sinking")[0]
            assert row.outcome == "error" and row.value > 1e-5        # 5.7e-5 m under the box at both steps
    stack = [rows_of(result, "mujoco", "stack", f"defaults dt={dt:g}", "sinking")[0].value for dt in (rc.STEP, rc.FINE)]
    assert stack[1] > 0.5 * stack[0]                  # the defaults' time constant: a finer step does not help
    box = [rows_of(result, "mujoco", "box resting", f"to_mjcf dt={dt:g}", "sinking")[0].value for dt in (rc.STEP, rc.FINE)]
    assert 0 < box[1] and box[0] / box[1] == pytest.approx(100, rel=0.05)    # to_mjcf's 2 dt time constant: dt^2
    for dt in (rc.STEP, rc.FINE):                      # the block that should stick creeps millimetres
        creep = rows_of(result, "mujoco", "x 1.000001", f"defaults dt={dt:g}", "displacement")[0]
        assert creep.outcome == "error" and creep.value > 1e-3
        assert rows_of(result, "mujoco", "x 1.000001", f"to_mjcf dt={dt:g}", "displacement")[0].value > 1e-4
    # where it should slide, it moves ~1e-5 m in the closed form and millimetres in MuJoCo: it cannot tell the two
    assert rows_of(result, "mujoco", "x 0.999999", "defaults", "position error")[0].value > 1e-3
    # Painleve's rod: the rigid end stops at once; MuJoCo's soft friction lets it slide millimetres, at its defaults
    # as far at either step (13 mm, measured), at to_mjcf's settings ten times less at the finer step
    slides = {(label, dt): rows_of(result, "mujoco", "Painleve", f"{label} dt={dt:g}", "end slide")[0].value
              for label in ("defaults", "to_mjcf") for dt in (rc.STEP, rc.FINE)}
    assert slides["defaults", rc.STEP] > 5e-3 and slides["defaults", rc.FINE] > 0.5 * slides["defaults", rc.STEP]
    assert slides["to_mjcf", rc.STEP] > 1e-3 and slides["to_mjcf", rc.FINE] < slides["to_mjcf", rc.STEP] / 5
    refused = rows_of(result, "mujoco", "e = 0.5", "defaults")
    assert len(refused) == 2 and all(r.outcome == "refused" and "restitution" in r.note for r in refused)
    assert all(r.outcome == "error" for r in rows_of(result, "mujoco", "e = 0.5", "to_mjcf"))


@pytest.mark.crosssim
def test_pymunk_rows_exist_or_are_refused_with_a_reason(result):
    pymunk = rows_of(result, "pymunk")
    variants = {r.variant.split(", 10 s")[0].split(", 1 s")[0] for r in result.rows}
    assert {r.variant.split(", 10 s")[0].split(", 1 s")[0] for r in pymunk} == variants
    assert all(r.outcome != "refused" or r.note for r in pymunk)
    assert all(r.outcome == "exact" for r in rows_of(result, "pymunk", "sphere"))   # rolls at 5/7 v0 to round-off
    default = rows_of(result, "pymunk", "x 1.000001", f"planar dt={rc.STEP:g}")[0]
    converged = rows_of(result, "pymunk", "x 1.000001", "100 iterations")[0]
    assert default.outcome == "error" and default.value > 1e-6 and converged.value == 0.0
    sink = [rows_of(result, "pymunk", "stack", f"planar dt={dt:g}", "sinking")[0].value for dt in (rc.STEP, rc.FINE)]
    assert sink[0] / sink[1] == pytest.approx(100, rel=0.05)           # g dt^2 per box before the contacts see them


@pytest.mark.crosssim
def test_findings_name_every_setting(result):
    groups = {(r.backend, r.setting.split(" dt=")[0]) for r in result.rows if r.backend != "rbody"}
    assert len(result.findings) == len(groups) + 3        # and what explains MuJoCo's, pymunk's and the rod's rows
    assert any(f.startswith("Painleve's rod") for f in result.findings)
    for backend, group in groups:
        assert any(f.startswith(f"{backend} [{group}]") for f in result.findings)
    defaults = next(f for f in result.findings if f.startswith("mujoco [defaults]"))
    assert "stack sinking [m]" in defaults and "Refused: drop e = 0.5" in defaults
