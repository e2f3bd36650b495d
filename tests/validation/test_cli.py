"""The main command end to end on its quick set: table, report, figures, exit status."""

import json

import pytest

from validation import baselines
from validation.__main__ import main

pytestmark = pytest.mark.crosssim


def test_quick_run_writes_table_report_and_figures(tmp_path, capsys):
    status = main(["--quick", "--out", str(tmp_path)])
    printed = capsys.readouterr().out
    assert "scene" in printed and "verdict" in printed
    for backend in ("rbody", "mujoco", "pymunk", "pinocchio", "bullet"):  # the peers where they express a scene
        assert backend in printed
    report = (tmp_path / "report.md").read_text()
    assert "## Results" in report and "| scene |" in report
    pictures = sorted(p.name for p in tmp_path.glob("*.png"))
    assert "swinging_rod.png" in pictures
    for name in pictures:
        assert f"({name})" in report
        assert (tmp_path / name).stat().st_size > 10_000
    # the chapter's scenes in motion, every engine side by side (validation/animations.py)
    from validation.animations import MOVIES

    movies = sorted(p.name for p in tmp_path.glob("*_motion.gif"))
    assert movies == sorted(f"{movie.name}.gif" for movie in MOVIES)
    assert "## The scenes in motion" in report
    for name in movies:
        assert f"({name})" in report
    assert status == 0, "a metric is worse than its recorded baseline: see the REGRESSION lines"


def test_regression_against_baseline_is_detected(tmp_path):
    row = type("Row", (), dict(case="c", backend="rbody", metric="max_abs_error", value=1e-6))
    (tmp_path / "rbody.json").write_text(json.dumps({"versions": {}, "metrics": {"c/max_abs_error": 1e-9}}))
    assert baselines.regressions([row], tmp_path)
    row.value = 1.5e-9
    assert not baselines.regressions([row], tmp_path)
    count = type("Row", (), dict(case="c", backend="rbody", metric="count_error", value=1.0))
    (tmp_path / "rbody.json").write_text(json.dumps({"versions": {}, "metrics": {"c/count_error": 0.0}}))
    assert baselines.regressions([count], tmp_path)


def test_unknown_backend_lists_the_valid_ones():
    import validation
    from rbody import scenes

    with pytest.raises(ValueError, match="'rbody', 'mujoco', 'pymunk'"):
        validation.run(scenes.swinging_rod(1.0, theta0=0.5, t_end=0.1), "drake", dt=1e-3)
