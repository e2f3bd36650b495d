"""validation.compare and `python -m validation compare`: the table, the report, assert_agree, baselines,
bad input.

Bounds: rbody's rk4 and MuJoCo's RK4 are the same scheme on the same equations, so on a contact-free model
they differ by round-off (measured 8e-16 rad on the double pendulum over 2 s); against the swinging rod's
closed form both are off by rk4's C dt^4 (6.7e-12 rad over 2 s at dt = 1e-3, the 1e-9 of the tolerance table);
pymunk's PivotJoint loses energy in proportion to dt and lags in phase by 2.9e-3 rad over 2 s (theta0 = 1).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

import rbody
from rbody import Inertia
from rbody.scenes import free_rotation, pendulum_chain, swinging_rod
from validation import Comparison, check_baseline, compare, save_baseline
from validation.__main__ import main
from validation.comparison import divergence

pytestmark = pytest.mark.crosssim

MODEL = """\
from rbody import scenes
chain = scenes.pendulum_chain(2, theta0=[0.5, 0.3], t_end=1.0)
def rod():
    return scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
"""

DOUBLE_PENDULUM_MJCF = """\
<mujoco model="double_pendulum">
  <option timestep="0.001" integrator="RK4"/>
  <worldbody>
    <body name="upper" euler="0 30 0">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -1" size="0.02" mass="1" contype="0" conaffinity="0"/>
      <body name="lower" pos="0 0 -1">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -1" size="0.02" mass="1" contype="0" conaffinity="0"/>
        <body name="weight" pos="0 0 -1">
          <geom type="sphere" size="0.05" mass="0.2" contype="0" conaffinity="0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def rod_comparison() -> Comparison:
    return compare(swinging_rod(1.0, theta0=1.0, t_end=2.0), dt=1e-3)


def test_table_rows_for_each_observable_and_pair(rod_comparison):
    c = rod_comparison
    assert set(c.trajectories) == {"rbody", "mujoco", "pymunk"} and c.method == "rk4"
    pairs = {r.pair for r in c.rows}
    assert pairs == {"rbody-mujoco", "rbody-pymunk", "mujoco-pymunk", "rbody-exact", "mujoco-exact", "pymunk-exact"}
    assert c.observables == ("theta", "omega", "energy")
    assert c.row("theta", "rbody", "mujoco").largest < 1e-13
    assert 1e-13 < c.row("theta", "rbody", "exact").largest < 1e-9
    lag = c.row("theta", "pymunk", "exact")
    assert 1e-3 < lag.largest < 0.05 and 0 < lag.time <= 2.0
    # the time of the largest divergence is where its curve peaks
    curve = c.curves[("theta", "pymunk-exact")]
    assert c.t[np.argmax(curve)] == lag.time and curve.max() == lag.largest
    text = c.table()
    assert "rbody-mujoco" in text and "max divergence" in text


def test_assert_agree_passes_and_fails_when_it_should(rod_comparison):
    rod_comparison.assert_agree({"theta": 0.05, "omega": 0.05, "energy": 0.05})
    with pytest.raises(AssertionError) as failure:
        rod_comparison.assert_agree({"theta": 1e-9, "*": 1.0})
    message = str(failure.value)
    for pair in ("rbody-pymunk", "mujoco-pymunk", "pymunk-exact"):
        assert f"theta {pair}" in message
    assert "rbody-mujoco" not in message and "omega" not in message
    with pytest.raises(AssertionError, match="energy"):
        rod_comparison.assert_agree(1e-9)  # one float for every observable
    # at the boundary: the largest divergence itself passes, anything below it breaches
    worst = max(r.largest for r in rod_comparison.rows if r.observable == "theta")
    rod_comparison.assert_agree({"theta": worst})
    with pytest.raises(AssertionError, match="breach"):
        rod_comparison.assert_agree({"theta": worst * (1 - 1e-9)})
    # only the pairs of the engines named: rbody and MuJoCo run the same RK4
    rod_comparison.assert_agree({"theta": 1e-13, "omega": 1e-13}, between=("rbody", "mujoco"))
    rod_comparison.assert_agree({"theta": 1e-9}, between=("rbody", "mujoco", "exact"))
    with pytest.raises(AssertionError, match="theta rbody-pymunk"):
        rod_comparison.assert_agree({"theta": 1e-3}, between=("rbody", "pymunk"))
    with pytest.raises(ValueError, match="bullet"):
        rod_comparison.assert_agree(1.0, between=("rbody", "bullet"))
    with pytest.raises(ValueError, match="thetta"):
        rod_comparison.assert_agree({"thetta": 1e-3})  # a typo would check nothing
    with pytest.raises(ValueError, match=">= 0"):
        rod_comparison.assert_agree({"theta": -1.0})


def test_assert_agree_with_one_engine_and_no_closed_form_compared_nothing():
    chain = pendulum_chain(2, theta0=[0.5, 0.3], t_end=0.2)
    with pytest.raises(AssertionError, match="nothing was compared"):
        compare(chain, engines=["rbody"]).assert_agree(1e-6)


def test_refused_engine_is_listed_with_its_reason():
    spinning = free_rotation(Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])), omega0=(0.05, 2.0, 0.05), t_end=0.5)
    c = compare(spinning, dt=1e-3)
    assert c.runs["pymunk"].status == "refused" and "not planar" in c.runs["pymunk"].note
    assert {r.pair for r in c.rows} >= {"rbody-mujoco", "rbody-exact", "mujoco-exact"}
    c.assert_agree({"omega_body": 1e-9})
    assert "refused" in c.to_markdown()


def test_orientation_divergence_is_the_rotation_angle():
    q = np.array([[1.0, 0.0, 0.0, 0.0]] * 3)
    angle = np.array([0.0, 1e-9, 0.5])
    turned = np.stack([np.cos(angle / 2), 0 * angle, 0 * angle, np.sin(angle / 2)], axis=1)
    np.testing.assert_allclose(divergence("body.quat", q, turned), angle, rtol=1e-9, atol=0)
    np.testing.assert_allclose(divergence("body.quat", turned, -turned), 0.0,
                               rtol=0, atol=1e-15)  # the sign of q is no rotation
    np.testing.assert_allclose(divergence("body.com", np.zeros((1, 3)), np.array([[3.0, 4.0, 0.0]])), [5.0])


def test_bad_input_raises_before_any_run(tmp_path):
    rod = swinging_rod(1.0, theta0=1.0, t_end=1.0)
    with pytest.raises(ValueError, match="drake"):
        compare(rod, engines=["rbody", "drake"])
    with pytest.raises(ValueError, match="dt"):
        compare(rod, dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        compare(rod, dt=-1e-3)
    with pytest.raises(ValueError, match="batch"):
        compare(pendulum_chain(2, theta0=[[0.1, 0.2], [0.3, 0.4]], t_end=1.0))
    with pytest.raises(ValueError, match="verlet"):
        compare(pendulum_chain(2, theta0=[0.1, 0.2], t_end=1.0), method="verlet")
    with pytest.raises(ValueError, match="no such file"):
        compare(tmp_path / "missing.xml")


def _write_model(tmp_path: Path) -> str:
    (tmp_path / "model.py").write_text(MODEL)
    return str(tmp_path / "model.py")


def test_command_end_to_end(tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["compare", f"{_write_model(tmp_path)}:chain", "--out", str(out), "--dt", "1e-3"])
    printed = capsys.readouterr()
    assert status == 0
    lines = [line.split() for line in printed.out.splitlines()]
    rows = {(line[0], line[1]): float(line[2]) for line in lines[2:]}
    assert set(rows) == {(o, p) for o in ("theta", "omega", "energy")
                         for p in ("rbody-mujoco", "rbody-pymunk", "mujoco-pymunk")}
    assert rows[("theta", "rbody-mujoco")] < 1e-12
    assert 1e-4 < rows[("theta", "rbody-pymunk")] < 0.05
    for engine in ("rbody", "mujoco", "pymunk"):
        assert f"] {engine}: " in printed.err  # one progress line per engine
    report = (out / "pendulum_chain.md").read_text()
    assert "| theta | rbody-mujoco |" in report and "(pendulum_chain_divergence.png)" in report
    assert (out / "pendulum_chain_divergence.png").stat().st_size > 10_000
    assert sorted(p.name for p in out.iterdir()) == ["pendulum_chain.md", "pendulum_chain_divergence.png"]  # no temp


@pytest.mark.skipif(not hasattr(rbody, "from_mjcf"), reason="rbody.from_mjcf (MJCF import) not on this branch yet")
def test_command_on_an_mjcf_double_pendulum(tmp_path, capsys):
    """A user's MJCF: rbody (rk4) and MuJoCo (RK4) run the same equations, so they agree to round-off; the
    model is planar (hinges along y; the weight, a body without a joint, welded to the lower link), so pymunk
    runs it too, within its PivotJoint phase lag."""
    model = tmp_path / "double_pendulum.xml"
    model.write_text(DOUBLE_PENDULUM_MJCF)
    status = main(["compare", str(model), "--t-end", "1.0", "--out", str(tmp_path / "out")])
    assert status == 0
    assert (tmp_path / "out" / "double_pendulum.md").exists() or list((tmp_path / "out").glob("*.md"))
    c = compare(model, t_end=1.0)
    assert c.dt == 1e-3  # the model's <option timestep>
    assert c.runs["mujoco"].trajectory.meta["integrator"] == "RK4"  # and its integrator
    assert c.source == str(model) and str(model) in c.to_markdown()
    assert c.runs["pymunk"].status == "ran", c.runs["pymunk"].note
    assert c.row("qpos", "rbody", "mujoco").largest < 1e-12
    assert 1e-5 < c.row("qpos", "rbody", "pymunk").largest < 0.05
    assert c.row("weight.com", "rbody", "mujoco").largest < 1e-12


def test_baseline_round_trip_and_exit_codes(tmp_path, capsys, monkeypatch):
    model, base, out = f"{_write_model(tmp_path)}:rod", tmp_path / "base", str(tmp_path / "out")
    assert main(["compare", model, "--out", out, "--baseline", str(base), "--update-baseline"]) == 0
    files = sorted(p.name for p in base.glob("*.json"))
    assert "rbody-mujoco.json" in files and "pymunk-exact.json" in files
    assert main(["compare", model, "--out", out, "--baseline", str(base)]) == 0
    # the API reads the same folder, as a str or a Path
    c = compare(swinging_rod(1.0, theta0=1.0, t_end=1.0))
    assert check_baseline(c, str(base)) == [] and check_baseline(c, base) == []
    # a baseline ten times tighter than pymunk's divergences: a regression, exit 1
    recorded = json.loads((base / "rbody-pymunk.json").read_text())
    recorded["metrics"] = {k: v / 10 for k, v in recorded["metrics"].items()}
    (base / "rbody-pymunk.json").write_text(json.dumps(recorded))
    capsys.readouterr()
    assert main(["compare", model, "--out", out, "--baseline", str(base)]) == 1
    err = capsys.readouterr().err
    assert "REGRESSION rbody-pymunk swinging_rod/theta" in err
    assert any("rbody-pymunk" in m for m in check_baseline(c, base))
    assert "## Regressions against the baseline" in (Path(out) / "swinging_rod.md").read_text()
    # an engine asked for that no longer runs the model is a regression too; one left out is not
    assert not any("not measured now" in m for m in check_baseline(compare(c.scene, engines=["rbody", "mujoco"]), base))

    def refuse(scene):
        raise NotImplementedError("pretend pymunk lost its pivot joints")

    import validation.backends.pymunk as pymunk_backend
    monkeypatch.setattr(pymunk_backend, "check", refuse)
    refused = compare(c.scene, engines=["rbody", "pymunk"])
    assert refused.runs["pymunk"].status == "refused"
    assert "rbody-pymunk swinging_rod/theta: recorded in the baseline, not measured now" in check_baseline(refused, base)


def test_a_divergence_without_a_baseline_or_a_broken_file_exits_2(tmp_path, capsys):
    model, base, out = f"{_write_model(tmp_path)}:rod", tmp_path / "base", str(tmp_path / "out")
    assert main(["compare", model, "--engines", "rbody,mujoco", "--out", out, "--baseline", str(base),
                 "--update-baseline"]) == 0
    capsys.readouterr()
    assert main(["compare", model, "--out", out, "--baseline", str(base)]) == 2  # pymunk now runs too
    err = capsys.readouterr().err
    assert "MISSING no baseline for rbody-pymunk swinging_rod/theta" in err and "--update-baseline" in err
    (base / "rbody-mujoco.json").write_text('{"metrics": {"swinging_rod/theta": ')  # an interrupted write
    assert main(["compare", model, "--engines", "rbody,mujoco", "--out", out, "--baseline", str(base)]) == 2
    err = capsys.readouterr().err
    assert "error: baseline file" in err and "rbody-mujoco.json" in err and "Traceback" not in err
    assert "comparing" not in err  # checked before any run


def test_save_baseline_then_check_through_the_api(tmp_path):
    c = compare(swinging_rod(1.0, theta0=0.5, t_end=0.5), engines=["rbody", "mujoco"])
    written = save_baseline(c, str(tmp_path / "b"))
    assert [p.name for p in written] == ["mujoco-exact.json", "rbody-exact.json", "rbody-mujoco.json"]
    assert check_baseline(c, tmp_path / "b") == []
    with pytest.raises(ValueError, match="no such folder"):
        check_baseline(c, tmp_path / "nowhere")
    with pytest.raises(ValueError, match="holds no divergences"):
        check_baseline(compare(pendulum_chain(1, theta0=[0.2], t_end=0.2), engines=["rbody", "mujoco"]), tmp_path / "b")


@pytest.mark.parametrize("arguments, message", [
    (["/nonexistent/model.xml"], "no such file"),
    (["MODEL:rod", "--engines", "rbody,drake"], "drake"),
    (["MODEL:rod", "--dt", "0"], "dt=0.0"),
    (["MODEL:rod", "--dt=-1e-3"], "dt=-0.001"),
    (["MODEL:rod", "--t-end=-1"], "t_end"),
    (["MODEL:rod", "--method", "leapfrog"], "leapfrog"),
    (["MODEL:rod", "--update-baseline"], "--update-baseline needs --baseline"),
    (["MODEL:rod", "--baseline", "/nonexistent/dir"], "no such folder"),
    (["MODEL:nothing"], "has no 'nothing'"),
    (["model.txt"], "expected an MJCF file"),
    (["BROKEN"], "broken.xml"),
])
def test_bad_input_exits_2_with_a_message_and_no_traceback(tmp_path, capsys, arguments, message):
    model = _write_model(tmp_path)
    (tmp_path / "broken.xml").write_text("<mujoco>\n  <worldbody>\n    <body>\n</mujoco>\n")  # malformed XML
    arguments = [a.replace("MODEL", model).replace("BROKEN", str(tmp_path / "broken.xml")) for a in arguments]
    assert main(["compare", *arguments, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "error:" in err and message in err and "Traceback" not in err
    out = tmp_path / "out"
    assert not out.exists() or not any(out.iterdir())  # nothing run, nothing written


def test_unknown_option_exits_2():
    with pytest.raises(SystemExit) as stop:
        main(["compare", "x.xml", "--frobnicate"])
    assert stop.value.code == 2


def test_report_files_are_renamed_into_place(tmp_path, rod_comparison):
    from validation.comparison import write_report

    path = write_report(rod_comparison, tmp_path)
    assert path.name == "swinging_rod.md" and "![Divergence against time](swinging_rod_divergence.png)" in path.read_text()
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]


def test_the_name_compare_is_the_function_and_the_tolerance_table_has_its_own_module():
    import validation
    from validation.tolerances import TOLERANCES, tolerance

    assert callable(validation.compare) and validation.compare is compare
    assert TOLERANCES and tolerance("pendulum", "rbody", "max_abs_error").value == 1e-9


@pytest.mark.skipif(not hasattr(rbody.Scene, "from_layout"), reason="needs the general engine (Scene.from_layout)")
def test_a_run_that_leaves_a_declared_joint_limit_is_a_failure_in_every_engine():
    """A model's declared range (an MJCF limit, scene.limits) that a run leaves: no engine here models limits,
    so the run is reported failed with the joint and the time, and assert_agree names it."""
    import dataclasses

    from rbody.mjcf import MJCFScene

    layout = pendulum_chain(2, theta0=[0.5, 0.3], t_end=1.0).layout
    scene = MJCFScene(name="limited", t_end=1.0, tree=layout, limits={"hinge_1": (-0.35, 0.35)})
    c = compare(scene, dt=1e-3)
    for engine in ("rbody", "mujoco", "pymunk"):
        run = c.runs[engine]
        assert run.status == "failed" and "joint 'hinge_1' left its range [-0.35, 0.35] at t=" in run.note, engine
    with pytest.raises(AssertionError, match="engine mujoco failed"):
        c.assert_agree(1.0)
    wide = dataclasses.replace(scene, limits={"hinge_1": (-3.0, 3.0)})
    assert all(r.status == "ran" for r in compare(wide, dt=1e-3).runs.values())
