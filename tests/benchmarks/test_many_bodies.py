"""benchmarks/many_bodies.py: a layer of spheres resting on a floor, rbody's compiled step beside MuJoCo's."""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
spec = importlib.util.spec_from_file_location("many_bodies", ROOT / "benchmarks" / "many_bodies.py")
many_bodies = importlib.util.module_from_spec(spec)
spec.loader.exec_module(many_bodies)


def test_a_small_layer_rests_on_its_floor_in_rbody_and_sinks_in_mujoco(capsys):
    """Four spheres, 30 steps: rbody's at their resting height to the last bit, MuJoCo's defaults below it (its
    soft contacts hold a sphere at a depth, 9.8e-4 m here); the table names the sizes: 24 dofs, 10 pairs of 3 rows."""
    many_bodies.main(["--sides", "2", "--steps", "30", "--repeats", "1"])
    row = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 4 |")]
    assert len(row) == 1
    cells = [cell.strip() for cell in row[0].strip("|").split("|")]
    assert cells[1] == "24" and cells[2] == "30"
    assert float(cells[4]) == 0.0
    assert float(cells[6]) > 1e-5
    load, prepare = (float(x) for x in cells[8].split(","))
    assert load > 0.0 and prepare > 0.0 and float(cells[9]) > 0.0


def test_bad_counts_are_refused():
    with pytest.raises(ValueError, match="sides=\\[0\\]"):
        many_bodies.main(["--sides", "0"])
    with pytest.raises(ValueError, match="steps=0"):
        many_bodies.main(["--steps", "0"])
