"""The engine installs without its peers: rbody imports and runs a scene with MuJoCo, pymunk, matplotlib, Dask
and mpmath all absent, and what needs one of them says which extra installs it."""

from __future__ import annotations

import subprocess
import sys
import textwrap

BLOCKED = ("mujoco", "pymunk", "matplotlib", "mpmath", "dask", "distributed")

PROGRAM = textwrap.dedent(f"""
    import importlib.abc, sys

    class Absent(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {BLOCKED!r}:
                raise ModuleNotFoundError(f"No module named {{name!r}}")
            return None

    sys.meta_path.insert(0, Absent())
    import rbody
    from rbody.scenes import pi_collisions, swinging_rod

    run = rbody.simulate(swinging_rod(1.0, theta0=1.0, t_end=0.01), dt=1e-3)
    print("theta", float(run["theta"][-1]))
    print("loaded", sorted(m for m in sys.modules if m.split(".")[0] in {BLOCKED!r}))
    try:
        pi_collisions(digits=2).expected_collisions
    except ImportError as error:
        print("refused", error)
""")


def test_rbody_runs_without_the_peers_and_names_the_extra_it_lacks():
    result = subprocess.run([sys.executable, "-c", PROGRAM], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    lines = dict(line.split(" ", 1) for line in result.stdout.strip().splitlines())
    assert 0.9 < float(lines["theta"]) < 1.0  # released at rest from 1 rad: it has begun to fall
    assert lines["loaded"] == "[]"
    assert "mpmath" in lines["refused"] and 'rbody[exact]' in lines["refused"]
