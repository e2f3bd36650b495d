"""benchmarks/gjk_touching.py: its poses touch as asked (within the regime's range of the other geom), its counts
add up to the poses of each class, and bad arguments are refused before any run."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from rbody.engine.contacts.convex import INFO, signed_distance

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "gjk_touching.py"
spec = importlib.util.spec_from_file_location("gjk_touching", SCRIPT)
gjk_touching = importlib.util.module_from_spec(spec)
sys.modules["gjk_touching"] = gjk_touching
spec.loader.exec_module(gjk_touching)


def test_the_poses_touch_and_the_counts_add_up():
    table = gjk_touching.poses(2, "touching", seed=3)
    assert table["kinds"].shape == (72, 2) and table["positions"].shape == (72, 2, 3)
    geoms = gjk_touching.shapes()
    normal, xa, xb, info = np.empty(3), np.empty(3), np.empty(3), np.zeros(INFO)
    for (i, j), (pa, pb), (Ra, Rb) in zip(table["kinds"], table["positions"], table["rotations"]):
        info[4:] = -1
        d = signed_distance(geoms[i][0], pa, Ra, geoms[i][1], geoms[i][2], geoms[j][0], pb, Rb, geoms[j][1],
                            geoms[j][2], np.zeros(3), normal, xa, xb, info)
        assert abs(d) <= 1e-9 + 1e-12  # the bisection's target, within GJK's tolerance
    result = gjk_touching.measure(table, repeats=1)
    assert result["polytope"]["poses"] == 2 * 16 and result["curved"]["poses"] == 2 * 20
    for name in ("polytope", "curved"):
        r = result[name]
        assert r["converged"] + r["stalled"] + r["other"] == r["poses"]
        assert r["iterations"] >= 1.0
    assert result["cost_min"] > 0.0


@pytest.mark.parametrize("argv, message", [(["--poses", "0"], "poses=0"), (["--repeats", "0"], "repeats=0"),
                                           (["--other", "/nonexistent"], "not a checkout")])
def test_bad_arguments_are_refused(argv, message):
    with pytest.raises(ValueError, match=message):
        gjk_touching.main(argv)
