"""Issue 23: a long run shows its progress and the time left (simulate(..., progress=...)), with the bits of a run
that shows none."""

from __future__ import annotations

import importlib
import io

import numpy as np
import pytest

from rbody import Inertia, SimulationError, simulate
from rbody import progress as progress_lines
from rbody.scenes import free_rotation, pendulum_chain, swinging_rod

simulation = importlib.import_module("rbody.simulation")

CASES = {
    "rod rk4": (lambda: swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 7), t_end=2.0), "rk4"),
    "rod verlet": (lambda: swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 7), t_end=2.0), "verlet"),
    "rod yoshida6": (lambda: swinging_rod(1.0, theta0=1.0, t_end=2.0), "yoshida6"),
    "rod symplectic_euler": (lambda: swinging_rod(1.0, theta0=1.0, t_end=2.0), "symplectic_euler"),
    "chain euler": (lambda: pendulum_chain(2, theta0=[0.2, 0.1], t_end=0.5), "euler"),
    "free rotation splitting": (lambda: free_rotation(Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])),
                                                      omega0=(0.1, 2.0, 0.1), t_end=2.0), "splitting"),
}


@pytest.fixture
def many_segments(monkeypatch):
    """Segments of a few samples each: the run is cut many times."""
    monkeypatch.setattr(simulation, "PROBE_ELEMENT_STEPS", 50)
    monkeypatch.setattr(simulation, "SEGMENT_SECONDS", 1e-9)
    monkeypatch.setattr(progress_lines, "LOG_SECONDS", 0.0)


@pytest.mark.filterwarnings("ignore::rbody.errors.AccuracyWarning")  # euler at 1 ms on the chain: 2 % per period
@pytest.mark.parametrize("name", list(CASES))
def test_a_run_with_progress_equals_one_without_bit_for_bit(name, many_segments, capsys):
    build, method = CASES[name]
    plain = simulate(build(), dt=1e-3, method=method, save_every=3, progress=False)
    shown = simulate(build(), dt=1e-3, method=method, save_every=3, progress=True)
    for observable in plain.observables:
        assert np.array_equal(shown[observable], plain[observable]), observable
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) >= 3, lines
    assert lines[-1].startswith(f"rbody {method} ") and "100 % (" in lines[-1] and "left" in lines[-1]
    assert any(" % (" in line and " s left" in line for line in lines[:-1])


def test_no_line_under_pytest_by_default_nor_with_false(many_segments, capsys):
    assert not progress_lines.interactive()
    simulate(swinging_rod(1.0, theta0=1.0, t_end=2.0), dt=1e-3)
    simulate(swinging_rod(1.0, theta0=1.0, t_end=2.0), dt=1e-3, progress=False)
    assert capsys.readouterr().err == ""


def test_methods_that_carry_more_than_the_state_run_in_one_loop(many_segments, capsys, monkeypatch):
    calls = []
    original = simulation.integrate_segment
    monkeypatch.setattr(simulation, "integrate_segment", lambda *a: calls.append(1) or original(*a))
    for method in ("gauss6", "reference"):
        scene = swinging_rod(1.0, theta0=1.0, t_end=0.2)
        shown = simulate(scene, dt=1e-3, method=method, progress=True)
        assert np.array_equal(shown["theta"], simulate(scene, dt=1e-3, method=method, progress=False)["theta"])
    assert calls == []


def test_a_failing_run_fails_the_same_way_with_progress(many_segments, capsys):
    """The first failed step of each element is kept across segments: the same error, the same step."""
    scene = pendulum_chain(2, theta0=[[0.2, 0.1], [3.0, 3.1]], omega0=[[0.0, 0.0], [40.0, -40.0]], t_end=2.0)
    messages = []
    for progress in (False, True):
        with pytest.raises(SimulationError) as error:
            simulate(scene, dt=0.02, method="euler", progress=progress)
        messages.append(str(error.value))
    assert messages[0] == messages[1]


def test_progress_values_are_checked():
    with pytest.raises(ValueError, match=r"progress='yes': expected True, False or None"):
        simulate(swinging_rod(1.0, theta0=1.0, t_end=1.0), dt=1e-3, progress="yes")


def test_the_line_gives_the_share_done_and_the_time_left(monkeypatch):
    clock = iter([0.0, 10.0, 10.0, 40.0, 40.0])
    monkeypatch.setattr(progress_lines.time, "perf_counter", lambda: next(clock))
    stream = io.StringIO()
    line = progress_lines.Progress("rbody rk4 rod", 1000, stream=stream)   # started at t = 0
    line.update(250)                                                       # at 10 s: a quarter done
    assert stream.getvalue().strip() == "rbody rk4 rod: 25 % (250 of 1e+03 steps, 10 s so far), 30 s left"
    line.finish()                                                          # at 40 s
    assert stream.getvalue().strip().splitlines()[-1] == "rbody rk4 rod: 100 % (1e+03 of 1e+03 steps, 40 s so far), 0 s left"
