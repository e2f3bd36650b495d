"""validation.cluster and the commands' --workers / --scheduler: the same results as the serial run."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

from validation import cluster  # noqa: E402
from validation.__main__ import main  # noqa: E402


@pytest.fixture(scope="module")
def shared_cluster():
    with cluster.connect(workers=2) as client:  # 2 processes, one thread and one "timing" resource each
        yield client


@pytest.fixture
def client(shared_cluster):
    """The module's cluster with both its workers up: a test kills one on purpose, and its nanny restarts it."""
    shared_cluster.wait_for_workers(2, timeout=60)
    return shared_cluster


def _square(x: float) -> float:
    return x * x


def test_results_come_back_in_task_order(client, capsys):
    tasks = [(f"square {k}", _square, (k,)) for k in range(12)]
    assert cluster.run_tasks(client, tasks, what="test") == [k * k for k in range(12)]
    assert cluster.run_tasks(None, tasks, what="test") == [k * k for k in range(12)]
    assert "[test 12/12 tasks done" in capsys.readouterr().err  # the progress of the cluster run


def _overlaps(spans) -> bool:
    spans = sorted(spans)
    return any(later[0] < earlier[1] for earlier, later in zip(spans, spans[1:]))


def test_timed_tasks_run_one_at_a_time_per_worker():
    def span(seconds):  # the wall-clock interval of one task
        start = time.time()
        time.sleep(seconds)
        return start, time.time()

    tasks = [(f"sleep {k}", span, (0.2,)) for k in range(4)]
    # one worker of 2 threads: untimed tasks share it, timed ones (resource "timing": 1) take turns
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, resources={cluster.TIMING: 1},
                                  dashboard_address=":0") as two_threads, distributed.Client(two_threads) as client:
        assert _overlaps(cluster.run_tasks(client, tasks, what="test"))
        assert not _overlaps(cluster.run_tasks(client, tasks, what="test", timed=True))


def test_a_failing_task_is_raised_with_its_name(client):
    def fails():
        raise ArithmeticError("the simulator blew up")

    with pytest.raises(ArithmeticError, match="blew up") as caught:
        cluster.run_tasks(client, [("fine", _square, (2,)), ("the bad one", fails, ())], what="test")
    assert any("in task the bad one of test" in note for note in caught.value.__notes__)


def test_a_worker_killed_mid_task_is_retried(client, tmp_path):
    marker = tmp_path / "killed"

    def dies_once(marker, x):
        try:
            os.close(os.open(marker, os.O_CREAT | os.O_EXCL))
        except FileExistsError:
            return x * x
        os._exit(1)  # the first attempt ends its worker's process

    results = cluster.run_tasks(client, [(f"task {k}", dies_once, (str(marker), k)) for k in range(4)], what="test")
    assert marker.exists() and results == [0, 1, 4, 9]


def test_bad_cluster_options_are_refused():
    with pytest.raises(ValueError, match="give one of them"):
        with cluster.connect("tcp://127.0.0.1:8786", 2):
            pass
    with pytest.raises(ValueError, match="--workers 0: expected a whole number"):
        with cluster.connect(workers=0):
            pass
    with cluster.connect() as none:
        assert none is None


def test_an_unreachable_scheduler_is_an_error_naming_its_address(monkeypatch, capsys):
    """(Exit status 2 since issue 23: a set-up problem, not a regression; before, a traceback and status 1.)"""
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "1s")
    monkeypatch.setattr(cluster, "HANDSHAKE_SECONDS", 2.0)
    assert main(["--scheduler", "tcp://127.0.0.1:9", "--backend", "rbody", "--quick"]) == 2
    assert "--scheduler tcp://127.0.0.1:9: no Dask scheduler answered" in capsys.readouterr().err
    with pytest.raises(ValueError, match=re.escape("--scheduler tcp://127.0.0.1:9: no Dask scheduler answered")):
        with cluster.connect("tcp://127.0.0.1:9"):
            pass


def test_timed_runs_refuse_a_cluster_without_the_timing_resource():
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=2, dashboard_address=":0") as plain:
        with distributed.Client(plain) as client:
            with pytest.raises(ValueError, match="none with the resource 'timing'.*--resources timing=1"):
                cluster.run_tasks(client, [("one", _square, (1,))], what="bench", timed=True)


def test_timed_runs_wait_for_a_worker_to_join_and_refuse_a_cluster_that_has_none(monkeypatch):
    import threading

    with distributed.LocalCluster(n_workers=0, processes=False, threads_per_worker=1, resources={cluster.TIMING: 1},
                                  dashboard_address=":0") as empty, distributed.Client(empty) as client:
        monkeypatch.setattr(cluster, "WORKER_WAIT_SECONDS", 0.5)
        with pytest.raises(ValueError, match="has 0 workers and none with the resource 'timing'"):
            cluster.run_tasks(client, [("one", _square, (3,))], what="bench", timed=True)
        monkeypatch.setattr(cluster, "WORKER_WAIT_SECONDS", 60.0)
        joins = threading.Timer(1.0, empty.scale, (1,))  # a worker that joins while the run waits
        joins.start()
        try:
            assert cluster.run_tasks(client, [("one", _square, (3,))], what="bench", timed=True) == [9]
        finally:
            joins.join()


def _table(text: str) -> list[list[str]]:
    """The printed table without its last column (the wall time of each run)."""
    return [line.split()[:-1] for line in text.splitlines() if line.strip()]


def test_the_main_command_on_a_cluster_prints_the_serial_table(client, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster, "connect", _reuse(client))
    assert main(["--quick", "--backend", "rbody", "--out", str(tmp_path / "serial")]) == 0
    serial = capsys.readouterr().out
    assert main(["--quick", "--backend", "rbody", "--workers", "2", "--out", str(tmp_path / "cluster")]) == 0
    on_cluster = capsys.readouterr().out
    assert len(_table(serial)) > 20 and _table(on_cluster) == _table(serial)


def _reuse(client):
    """connect() that hands out the module's cluster for --workers (starting one per command is slow)."""
    import contextlib

    @contextlib.contextmanager
    def connect(scheduler=None, workers=None):
        yield client if workers else None

    return connect


def _hard_rows(text: str) -> list[list[str]]:
    """The hard tables' rows without the time column (the 7th of 8; the `rbody` column may be empty)."""
    rows = []
    for line in text.splitlines():
        cells = re.split(r"\s{2,}", line.rstrip())
        if len(cells) >= 7:
            rows.append(cells[:6] + cells[7:])
    return rows


# Fast cases of the suite (a few seconds together), enough to cover rbody, MuJoCo and pymunk rows and figures.
HARD_CASES = ["--case", "4", "--case", "5", "--case", "6", "--case", "9"]


def test_hard_quick_on_a_cluster_gives_the_serial_tables(client, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster, "connect", _reuse(client))
    main(["hard", "--quick", *HARD_CASES, "--out", str(tmp_path / "serial")])
    serial = capsys.readouterr().out
    main(["hard", "--quick", *HARD_CASES, "--workers", "2", "--out", str(tmp_path / "cluster")])
    on_cluster = capsys.readouterr().out
    assert len(_hard_rows(serial)) > 50 and _hard_rows(on_cluster) == _hard_rows(serial)
    drawn = sorted(p.name for p in (tmp_path / "serial").iterdir())
    assert "hard_large_steps.png" in drawn and sorted(p.name for p in (tmp_path / "cluster").iterdir()) == drawn


def test_a_failed_hard_run_writes_nothing_to_its_report_folder(tmp_path, monkeypatch):
    from validation.hard import suite

    def breaks(quick, out):
        (out / "hard_half_done.png").write_bytes(b"figure")
        raise RuntimeError("a case that fails after drawing")

    monkeypatch.setitem(suite._CASES, 9, breaks)
    report = tmp_path / "report"
    report.mkdir()
    (report / "hard.md").write_text("the last complete run")
    with pytest.raises(RuntimeError, match="fails after drawing") as caught:
        main(["hard", "--quick", "--case", "5", "--case", "9", "--out", str(report)])
    assert any("in task case 9 of hard" in note for note in caught.value.__notes__)
    assert sorted(p.name for p in report.iterdir()) == ["hard.md"]  # no figure of case 5, none half done
    assert (report / "hard.md").read_text() == "the last complete run"


def _bench_points(path) -> list[dict]:
    """bench.csv's points without the timing columns (costs, steps per second, repeats)."""
    from validation.bench.csvfile import read_csv

    timing = ("seconds_per_sim_second", "stepping_seconds_per_sim_second", "steps_per_second", "repeats")
    return [{k: "nan" if v != v else v for k, v in row.items() if k not in timing} for row in read_csv(path)]


def test_bench_on_a_cluster_gives_the_serial_points(client, tmp_path, monkeypatch):
    monkeypatch.setattr(cluster, "connect", _reuse(client))
    main(["bench", "--quick", "--scene", "rolling_disc", "--out", str(tmp_path / "serial")])
    main(["bench", "--quick", "--scene", "rolling_disc", "--workers", "2", "--out", str(tmp_path / "cluster")])
    serial = _bench_points(tmp_path / "serial" / "bench.csv")
    assert len(serial) > 20 and not any(row["failure"].startswith("not run") for row in serial)
    assert _bench_points(tmp_path / "cluster" / "bench.csv") == serial


def test_compare_on_a_cluster_gives_the_serial_divergences(client):
    """The compare command's engine runs as tasks: an MJCF tree (rbody, MuJoCo and pymunk all run it) and a
    scene of rbody's own with a closed form; the divergences are the serial ones, row for row."""
    from rbody.scenes import swinging_rod
    from validation.comparison import compare

    model = Path(__file__).resolve().parents[2] / "models" / "double_pendulum.xml"
    for source in (model, swinging_rod(1.0, theta0=1.0, t_end=1.0)):
        serial = compare(source, t_end=0.5)
        on_cluster = compare(source, t_end=0.5, client=client)
        assert [r.status for r in on_cluster.runs.values()] == [r.status for r in serial.runs.values()]
        assert len(serial.rows) >= 3 and on_cluster.rows == serial.rows
