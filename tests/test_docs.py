"""The documentation as a user meets it: every Python example of the README runs as written (in order, in one
namespace, as a reader would paste them), and the API reference builds from the docstrings without a warning."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)

# The arm the README's examples load: a planar double pendulum in MJCF with MuJoCo's RK4 (the examples say so).
ARM_XML = """<mujoco model="arm">
  <option integrator="RK4" timestep="0.001"/>
  <worldbody>
    <body name="upper">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.8" size="0.02" mass="1"/>
      <body name="lower" pos="0 0 -0.8">
        <joint name="elbow" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <keyframe><key name="start" qpos="1.0 0.0"/></keyframe>
</mujoco>
"""


# The URDF arm of the README's robot example: two links on revolute joints about y.
ARM_URDF = """<robot name="arm">
  <link name="base"/>
  <link name="upper">
    <inertial><origin xyz="0 0 -0.4"/><mass value="1"/><inertia ixx="0.054" iyy="0.054" izz="0.0005" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="lower">
    <inertial><origin xyz="0 0 -0.25"/><mass value="0.5"/><inertia ixx="0.0105" iyy="0.0105" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/><origin xyz="0 0 -0.8"/>
    <axis xyz="0 1 0"/><dynamics damping="0.01"/></joint>
</robot>
"""


def readme_examples() -> list[str]:
    return FENCE.findall((ROOT / "README.md").read_text())


def test_the_readme_has_python_examples():
    assert len(readme_examples()) >= 3


def test_every_readme_example_runs(tmp_path, monkeypatch):
    """The examples in README order, in one namespace, in a folder holding the arm.xml and arm.urdf they read. A block that
    defines test functions (the regression-test example) has them called, after recording the baseline the
    example's comment says how to record."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "arm.xml").write_text(ARM_XML)
    (tmp_path / "arm.urdf").write_text(ARM_URDF)
    namespace: dict = {"__name__": "readme", "__file__": str(tmp_path / "test_readme.py")}
    for number, code in enumerate(readme_examples(), 1):
        before = set(namespace)
        exec(compile(code, f"README.md example {number}", "exec"), namespace)
        for name in sorted(set(namespace) - before):
            if name.startswith("test_") and callable(namespace[name]):
                from validation import compare, save_baseline

                save_baseline(compare(tmp_path / "arm.xml", t_end=2.0), tmp_path / "baselines")
                namespace[name]()
    # what the first example promises: the disc's moment about a rim point, and the rod's run against its
    # closed form
    assert namespace["disc"].about([0.5, 0.0, 0.0])[2, 2] == pytest.approx(0.75, rel=1e-15)
    assert 0 < namespace["error"] < 1e-6
    assert np.all(np.isfinite(namespace["run"]["theta"]))


def test_the_api_reference_builds_without_a_warning(tmp_path):
    pytest.importorskip("sphinx")
    result = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(ROOT / "docs" / "api"),
                             str(tmp_path / "html")], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]
    page = (tmp_path / "html" / "index.html").read_text()
    for name in ("rbody.layout.Layout", "rbody.simulation.simulate", "rbody.engine.multibody.Multibody",
                 "rbody.mjcf.parse.from_mjcf", "rbody.inertia.Inertia.from_mesh"):
        assert f'id="{name}"' in page, name
