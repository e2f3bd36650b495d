"""Issue 23: MuJoCo's and pymunk's long runs show progress with the time left (progress=True, or None in an
interactive session for long runs), and the same run either way."""

from __future__ import annotations

import numpy as np
import pytest

from rbody import progress as progress_lines
from rbody.scenes import swinging_rod

mujoco_backend = pytest.importorskip("validation.backends.mujoco")
pymunk_backend = pytest.importorskip("validation.backends.pymunk")


@pytest.mark.parametrize("backend", [mujoco_backend, pymunk_backend], ids=["mujoco", "pymunk"])
def test_a_run_with_progress_prints_the_time_left_and_is_the_same_run(backend, monkeypatch, capsys):
    monkeypatch.setattr(progress_lines, "LOG_SECONDS", 0.0)
    monkeypatch.setattr(mujoco_backend, "_CHUNK_BYTES", 64 * 1024)  # many chunks
    rod = swinging_rod(1.0, theta0=1.0, t_end=5.0)
    quiet = backend.run(rod, 1e-3, progress=False)
    assert capsys.readouterr().err == ""
    shown = backend.run(rod, 1e-3, progress=True)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) >= 2 and lines[-1].startswith(f"{backend.name} ") and "100 % (5e+03 of 5e+03 steps" in lines[-1]
    assert all(" left" in line for line in lines)
    assert np.array_equal(shown["theta"], quiet["theta"])


def test_no_progress_under_pytest_by_default(capsys):
    mujoco_backend.run(swinging_rod(1.0, theta0=1.0, t_end=2.0), 1e-3)
    assert capsys.readouterr().err == ""
