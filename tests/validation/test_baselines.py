"""The main command's baselines and exit status: read and checked before any run, repaired by
--update-baselines, a missing one reported and not a pass; 1 = regression, 2 = a problem with the inputs."""

from __future__ import annotations

import json

import pytest

from validation import baselines, cases
from validation.__main__ import INPUT_PROBLEM, OK, REGRESSION, _parser, main


@pytest.fixture
def one_case(monkeypatch, tmp_path):
    """The main command on the quick swinging rod alone, against baselines in a temporary folder."""
    monkeypatch.setattr(baselines, "BASELINE_DIR", tmp_path / "baselines")
    rod = [case for case in cases.pendulum_cases(True) if case.name == "swinging_rod"]
    assert rod
    monkeypatch.setattr(cases, "default_cases", lambda quick=False: rod)
    return baselines.mode_dir(True) / "rbody.json"


def _run(tmp_path, *extra):
    return main(["--quick", "--backend", "rbody", "--out", str(tmp_path / "report"), *extra])


BROKEN = [("", "is empty"), ('{"metrics": {"swinging_rod/max_abs_error": 1e-1', "is not valid JSON"),
          ("[1, 2]", "holds a JSON list"), ('{"metrics": [1]}', "has 'metrics' of type list"),
          ('{"metrics": {"a/b": "small"}}', "has metric 'a/b' = 'small', expected a finite number"),
          ('{"metrics": {"a/b": true}}', "expected a finite number")]


@pytest.mark.parametrize("text, problem", BROKEN, ids=[p for _t, p in BROKEN])
def test_broken_baseline_is_named_before_any_run_and_repaired(one_case, tmp_path, monkeypatch, capsys, text,
                                                              problem):
    one_case.parent.mkdir(parents=True)
    one_case.write_text(text)
    rod = cases.default_cases(True)
    monkeypatch.setattr(cases, "default_cases", lambda quick=False: pytest.fail("ran before checking the baselines"))
    assert _run(tmp_path) == INPUT_PROBLEM
    message = capsys.readouterr().err
    assert str(one_case) in message and problem in message
    assert "python -m validation --quick --update-baselines" in message and "Traceback" not in message
    assert len(message.splitlines()) <= 3
    monkeypatch.setattr(cases, "default_cases", lambda quick=False: rod)
    assert _run(tmp_path, "--update-baselines") == OK                   # repairs it without reading it
    assert "swinging_rod/max_abs_error" in baselines.read(one_case)["metrics"]
    assert _run(tmp_path) == OK


def test_missing_baseline_is_reported_and_not_a_pass(one_case, tmp_path, capsys):
    assert _run(tmp_path) == INPUT_PROBLEM                               # no folder at all
    err = capsys.readouterr().err
    assert "no baseline for rbody swinging_rod/" in err and "--update-baselines" in err
    assert "no baseline for rbody" in (tmp_path / "report" / "report.md").read_text()
    assert _run(tmp_path, "--update-baselines") == OK
    data = json.loads(one_case.read_text())
    data["metrics"] = {k: v for k, v in data["metrics"].items() if not k.endswith("max_abs_error")}
    one_case.write_text(json.dumps(data))                                # one entry missing
    assert _run(tmp_path) == INPUT_PROBLEM
    assert "no baseline for rbody swinging_rod/max_abs_error (no entry)" in capsys.readouterr().err


def test_regression_exits_1(one_case, tmp_path):
    assert _run(tmp_path, "--update-baselines") == OK
    data = json.loads(one_case.read_text())
    key = next(k for k in data["metrics"] if k.endswith("max_abs_error"))
    data["metrics"][key] = 1e-20                                          # far better than any run
    one_case.write_text(json.dumps(data))
    assert _run(tmp_path) == REGRESSION


def test_regressions_accepts_str_and_path(tmp_path):
    row = type("Row", (), dict(case="c", backend="rbody", metric="max_abs_error", value=1e-6))
    (tmp_path / "rbody.json").write_text(json.dumps({"versions": {}, "metrics": {"c/max_abs_error": 1e-9}}))
    assert baselines.regressions([row], str(tmp_path)) == baselines.regressions([row], tmp_path) != []
    assert "no baseline for rbody c/max_abs_error" in baselines.regressions([row], tmp_path / "elsewhere")[0]


def test_out_not_writable_is_a_short_message_and_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cases, "default_cases", lambda quick=False: pytest.fail("ran before checking --out"))
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for command in ([], ["hard", "--quick"], ["bench", "--quick"], ["export"]):
        assert main([*command, "--out", str(blocker / "report")]) == INPUT_PROBLEM
        err = capsys.readouterr().err
        assert "cannot write into" in err and "Traceback" not in err and len(err.splitlines()) == 1


def test_help_documents_the_exit_status():
    text = _parser().format_help()
    assert "Exit status: 0" in text and "1 a regression" in text and "2 a problem with the inputs" in text
