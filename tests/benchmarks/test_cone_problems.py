"""benchmarks/cone_problems.py: the problems it captures are the steps' own (each solves again from its start to
within its tolerance, the spread steps are where it says), its file reads back whole, and bad arguments are refused
before any run."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from rbody.engine.constraints.stepping import cone_solve

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "cone_problems.py"
spec = importlib.util.spec_from_file_location("cone_problems", SCRIPT)
problems_script = importlib.util.module_from_spec(spec)
sys.modules["cone_problems"] = problems_script
spec.loader.exec_module(problems_script)

BLOCK = """<mujoco model="tipping_block">
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" friction="0.8"/>
    <body name="block" pos="0 0 0.06" euler="8 5 0"><freejoint/><geom type="box" size="0.1 0.06 0.04"/></body>
  </worldbody>
</mujoco>"""

HINGED = """<mujoco model="hinged"><worldbody><body><joint type="hinge"/><geom size="0.1"/></body></worldbody></mujoco>"""


@pytest.fixture(scope="module")
def captured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cone_problems")
    model = folder / "block.xml"
    model.write_text(BLOCK)
    out = folder / "block.npz"
    problems_script.capture(model, out, steps=60, lift=0.01, keep=3)
    return out


def test_the_captured_problems_are_the_steps_own_and_solve_again_within_their_tolerance(captured):
    meta, problems = problems_script.load(captured)
    assert meta["model"] == "block.xml" and meta["steps"] == 60 and meta["lift"] == 0.01
    spread = [info["step"] for info in meta["kept"] if not info["slow"]]
    assert set(spread) <= {0, 29, 59} and len(meta["kept"]) >= 3  # the block lands within the run: some steps have
    assert sum(info["slow"] for info in meta["kept"]) >= 1           # contacts, the first (in the air) none
    assert 0 not in spread  # the block falls 1 cm first: the first step has no contact, so no problem
    for info, problem in zip(meta["kept"], problems):
        assert 0.0 <= info["replay_dy"] <= 1e-12  # the step replayed in Python ends where the native one did
        W = problem["W"]
        assert W.shape == (info["rows"], info["rows"]) and np.allclose(W, W.T, rtol=0, atol=1e-12 * abs(W).max())
        lam = problem["lam"].copy()
        residual = cone_solve(W, problem["b"], problem["lo"], problem["hi"], problem["role"], problem["mu"], lam,
                              float(problem["tolerance"]), int(problem["sweeps"]))
        assert residual <= float(problem["tolerance"])
        assert np.any(lam > 0.0)  # a contact that pushes: the block is held up by the floor


def test_the_timing_of_a_suite_prints_every_problem_and_the_totals(captured, capsys):
    problems_script.time_suite(captured, repeats=2, as_json=True)
    answer = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    meta, _problems = problems_script.load(captured)
    assert Path(answer["rbody"]) == SCRIPT.parents[1]
    assert len(answer["results"]) == len(meta["kept"])
    assert all(len(r["seconds"]) == 2 and min(r["seconds"]) > 0.0 for r in answer["results"])


def test_bad_arguments_are_refused_before_any_run(tmp_path):
    model = tmp_path / "hinged.xml"
    model.write_text(HINGED)
    with pytest.raises(ValueError, match=r"lift=0\.1: hinged\.xml's first joint is not a free joint"):
        problems_script.capture(model, tmp_path / "out.npz", steps=10, lift=0.1, keep=2)
    with pytest.raises(ValueError, match=r"keep=0"):
        problems_script.capture(model, tmp_path / "out.npz", steps=10, lift=0.0, keep=0)
    with pytest.raises(ValueError, match=r"out='.*out\.txt': expected a file name ending in \.npz"):
        problems_script.capture(model, tmp_path / "out.txt", steps=10, lift=0.0, keep=2)
    with pytest.raises(ValueError, match=r"no such file"):
        problems_script.time_suite(tmp_path / "missing.npz", repeats=1, as_json=False)
    with pytest.raises(ValueError, match=r"not a checkout of rbody"):
        problems_script.compare(tmp_path / "missing.npz", tmp_path, repeats=1)
    assert not list(tmp_path.glob("*.npz"))


def test_the_census_times_every_step_and_keeps_its_residual(tmp_path, capsys):
    model = tmp_path / "block.xml"
    model.write_text(BLOCK)
    result = problems_script.census_runs(model, steps=60, lift=0.01, runs=2)
    assert Path(result["rbody"]) == SCRIPT.parents[1]
    assert len(result["seconds"]) == 2 and all(len(run) == 60 and min(run) > 0.0 for run in result["seconds"])
    assert len(result["residual"]) == len(result["rows"]) == 60
    assert result["rows"][0] == 0 and max(result["rows"]) > 0  # in the air first, then on the floor
    assert max(result["residual"]) <= 1e-10  # every step accepted within the step's tolerance (scale 1 here)
    problems_script.census(model, steps=60, lift=0.01, runs=1, other=None)
    printed = capsys.readouterr().out
    assert "| this (" in printed and "this: above 1e-13:" in printed and "this: slowest: " in printed


def test_the_census_refuses_bad_arguments_before_any_run(tmp_path):
    model = tmp_path / "block.xml"
    model.write_text(BLOCK)
    with pytest.raises(ValueError, match=r"steps=0 and runs=1: expected positive counts"):
        problems_script.census_runs(model, steps=0, lift=0.0, runs=1)
    with pytest.raises(ValueError, match=r"model='.*missing\.xml': no such file"):
        problems_script.census_runs(tmp_path / "missing.xml", steps=5, lift=0.0, runs=1)
    with pytest.raises(ValueError, match=r"not a checkout of rbody"):
        problems_script.census(model, steps=5, lift=0.0, runs=1, other=tmp_path)
