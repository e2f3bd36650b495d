"""Fuzzing the command line (issue 12): any arguments end in exit status 0, 1 or 2 with at most a short
message, never a traceback. The work itself is replaced by stubs (an empty case list, stub benchmarks):
what is fuzzed is the handling of the inputs."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import validation.__main__ as cli
from validation import baselines, cases

FLAGS = ["--quick", "--update-baselines", "--backend", "rbody", "mujoco", "bullet", "--out", "--scene", "--case",
         "swinging_rod", "batch", "nope", "0", "3", "99", "-1", "", "\x00", "/proc/forbidden", "report",
         "a/b/c", "x" * 300, "--help", "-h", "--bogus"]
COMMANDS = [[], ["run"], ["export"], ["bench"], ["hard"], ["nonsense"]]


@pytest.fixture
def stubbed(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(baselines, "BASELINE_DIR", tmp_path / "baselines")
    monkeypatch.setattr(cases, "default_cases", lambda quick=False: [])
    import validation.bench.run as bench_run
    import validation.export as export
    import validation.hard.suite as suite

    def run_bench(out, **kwargs):
        out.mkdir(parents=True, exist_ok=True)  # the command checks --out writable without creating it
        (out / "summary.md").write_text("stub")
        return out / "summary.md"

    monkeypatch.setattr(bench_run, "run_bench", run_bench)
    monkeypatch.setattr(suite, "run_hard", lambda out, **kwargs: 0)
    monkeypatch.setattr(export, "export_models", lambda out: [])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                               HealthCheck.function_scoped_fixture])
@given(command=st.sampled_from(COMMANDS), rest=st.lists(st.sampled_from(FLAGS), max_size=5))
def test_any_arguments_end_in_a_status_not_a_traceback(stubbed, capsys, command, rest):
    try:
        status = cli.main(command + rest)
    except SystemExit as exit_:  # argparse: --help (0) or an argument it rejects (2)
        status = exit_.code
    err = capsys.readouterr().err
    assert status in (0, 1, 2)
    assert "Traceback" not in err
    if status == 2 and "error:" in err:
        assert len(err.splitlines()) <= 4


def test_unknown_bench_scene_and_hard_case_are_input_problems(stubbed, capsys):
    assert cli.main(["bench", "--scene", "nope"]) == cli.INPUT_PROBLEM
    assert "--scene nope: expected one of" in capsys.readouterr().err
    assert cli.main(["hard", "--case", "99"]) == cli.INPUT_PROBLEM
    assert "--case 99: expected case numbers 1..10" in capsys.readouterr().err


def test_out_with_a_name_too_long_is_refused_before_any_work(stubbed, capsys, monkeypatch):
    monkeypatch.setattr(cases, "default_cases", lambda quick=False: pytest.fail("ran before checking --out"))
    assert cli.main(["--out", "x" * 300]) == cli.INPUT_PROBLEM
    err = capsys.readouterr().err
    assert "beyond the file system's" in err and len(err.splitlines()) == 1
