"""Animations in the validation commands: compare --animate and the main command's scenes in motion."""

import numpy as np
import pytest
from PIL import Image

from rbody import Body, Inertia, Joint, Layout, Scene, Shape
from rbody.animation import BODY_COLOURS
from validation.__main__ import main
from validation.animations import MOVIES, chapter_animations
from validation.comparison import compare, write_report

pytestmark = pytest.mark.crosssim

MJCF = """<mujoco model="bob">
  <option timestep="0.01" integrator="RK4"/>
  <worldbody>
    <body name="bob">
      <joint name="pin" type="hinge" axis="0 1 0"/>
      <geom type="sphere" size="0.15" pos="0 0 -0.6" mass="1"/>
    </body>
  </worldbody>
  <keyframe><key qpos="2.5"/></keyframe>
</mujoco>
"""


def bob(theta0: float = 2.5) -> Scene:
    ball = Body("bob", Inertia.solid_sphere(1.0, 0.15).translated([0.0, 0.0, -0.6]),
                shapes=(Shape("ball", "sphere", (0.15,), pos=(0.0, 0.0, -0.6)),))
    return Scene.from_layout(Layout(bodies=(ball,), joints=(Joint("pin", "hinge", "bob", axis=(0, 1, 0),
                                                                  qpos0=theta0),)), t_end=3.0, name="bob")


def frames(path):
    image = Image.open(path)
    out, start = [], 0
    for k in range(image.n_frames):
        image.seek(k)
        out.append((start, np.asarray(image.convert("RGB"))))
        start += image.info["duration"]
    return out


def test_each_engine_is_drawn_where_it_reports_its_centre_of_mass_and_diverging_runs_apart(tmp_path):
    # pymunk's pivot loses energy in proportion to dt: at dt = 10 ms its bob falls behind by tens of pixels
    comparison = compare(bob(), ("rbody", "pymunk"), dt=1e-2, t_end=3.0)
    lines = []
    write_report(comparison, tmp_path, animate=True, say=lines.append)
    path = tmp_path / "bob_motion.gif"
    assert "![The runs in motion](bob_motion.gif)" in (tmp_path / "bob.md").read_text()
    assert any(line.startswith("animation: bob_motion.gif") for line in lines)
    assert Image.open(path).size == (2 * 480, 360)  # rbody and pymunk side by side
    rbody_run, pymunk_run = comparison.trajectories["rbody"], comparison.trajectories["pymunk"]
    # the same runs drawn flat, so that the body is found by its colour
    from rbody import animate

    again = animate(comparison.scene, comparison.trajectories, tmp_path / "flat.gif", shaded=False, progress=False)
    width = again.width // 2
    nominal = again.interval / again.speed * 1000
    apart = 0.0
    colour = np.array([int(BODY_COLOURS[0][i:i + 2], 16) for i in (1, 3, 5)])
    for start, frame in frames(again.path):
        time = again.times[int(round(start / nominal))]
        drawn = []
        for panel, run in enumerate((rbody_run, pymunk_run)):
            k = int(np.searchsorted(run.t, time + 1e-9, side="right") - 1)
            rows, cols = np.nonzero(np.all(frame[:, panel * width:(panel + 1) * width] == colour, axis=-1))
            centroid = np.array([cols.mean() + 0.5 + panel * width, rows.mean() + 0.5])
            expected = again.project(run["bob.com"][k], panel)
            assert np.linalg.norm(centroid - expected) < 0.5
            drawn.append(centroid - [panel * width, 0])
        apart = max(apart, float(np.linalg.norm(drawn[0] - drawn[1])))
    assert apart > 20


def test_compare_animate_writes_the_motion_beside_the_divergence_figure(tmp_path, capsys):
    model = tmp_path / "bob.xml"
    model.write_text(MJCF)
    out = tmp_path / "report"
    status = main(["compare", str(model), "--t-end", "0.5", "--animate", "--out", str(out)])
    assert status == 0, capsys.readouterr().err
    report = (out / "bob.md").read_text()
    assert "bob_divergence.png" in report and "![The runs in motion](bob_motion.gif)" in report
    image = Image.open(out / "bob_motion.gif")
    assert image.n_frames > 5 and image.size[0] == 3 * image.size[1] * 4 // 3  # rbody, mujoco, pymunk
    assert "animation: bob_motion.gif" in capsys.readouterr().err


def test_compare_animate_refuses_a_scene_it_cannot_draw_before_any_run(tmp_path, capsys):
    source = tmp_path / "cloud.py"
    source.write_text("from rbody import scenes\n\ndef cloud():\n    return scenes.particles(3, seed=1, t_end=0.1)\n")
    out = tmp_path / "report"
    status = main(["compare", f"{source}:cloud", "--animate", "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 2 and "cannot be drawn" in err and "comparing" not in err
    assert not out.exists()


def test_the_chapter_animations_draw_each_scene_in_the_engines_asked_for(tmp_path):
    written = chapter_animations(tmp_path, engines=("rbody",), quick=True)
    assert [name for _caption, name in written] == [f"{movie.name}.gif" for movie in MOVIES]
    for _caption, name in written:
        image = Image.open(tmp_path / name)
        assert image.n_frames > 5
        width, height = image.size
        assert width in (height, height * 4 // 3)  # one panel: rbody's
