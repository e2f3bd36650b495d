"""Workers lost mid-run (one, all at once as in issue 23, or the scene scattered to them lost with them): the
batch still gives the serial run's result; a task that kills every worker it runs on, a cluster that keeps
losing the run, and a scheduler gone mid-run are SimulationErrors."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from rbody import SimulationError, simulate  # noqa: E402
from rbody.engine.distributed import RESENDS  # noqa: E402
from rbody.scenes import swinging_rod  # noqa: E402
from rbody.scenes.pendulum import SwingingRod  # noqa: E402


@pytest.fixture()
def cluster():
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=":0") as cluster, distributed.Client(cluster) as client:
        yield cluster, client


def _rod(marker: Path, action: str):
    """A swinging rod of 40 rows whose native model, built in a Dask worker, acts on the cluster when no file
    `marker`-0, `marker`-1 exists yet (it creates one), or every time (an action ending in '-always'):
    'kill' ends the worker's process, 'forget' makes the scheduler forget the scattered scene this task needs
    (as when its last holder dies) and waits until it has. Built outside a worker it is the plain rod.
    A local class, so that Dask sends it by value."""

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class RodThatActsOnItsCluster(SwingingRod):
        marker: str = ""
        action: str = ""

        def native(self):
            try:
                worker = distributed.get_worker()
            except ValueError:  # not in a worker
                return super().native()
            if self._armed():
                if self.action.startswith("kill"):
                    os._exit(1)
                client = distributed.get_client()
                scene = [dependency.key for dependency in worker.state.tasks[worker.get_current_task()].dependencies]
                client.cancel([distributed.Future(key, client) for key in scene], force=True)
                deadline = time.monotonic() + 30.0
                while (time.monotonic() < deadline
                       and client.run_on_scheduler(lambda dask_scheduler: scene[0] in dask_scheduler.tasks)):
                    time.sleep(0.05)
            return super().native()

        def _armed(self) -> bool:
            if self.action.endswith("-always"):
                return True
            for index in range(2 if self.action == "kill-both" else 1):
                try:
                    os.close(os.open(f"{self.marker}-{index}", os.O_CREAT | os.O_EXCL))
                    return True
                except FileExistsError:
                    continue
            return False

    plain = swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 40), t_end=1.0)
    return RodThatActsOnItsCluster(**{f.name: getattr(plain, f.name) for f in dataclasses.fields(plain)},
                                   marker=str(marker), action=action)


def _equal_runs(split, serial) -> None:
    for observable in serial.observables:
        assert np.array_equal(split[observable], serial[observable]), observable


def test_a_worker_killed_mid_run_still_gives_the_full_result(cluster, tmp_path):
    _, client = cluster
    scene = _rod(tmp_path / "killed", "kill")
    serial = simulate(scene, dt=1e-2, method="rk4")
    split = simulate(scene, dt=1e-2, method="rk4", client=client, chunk=4)
    assert (tmp_path / "killed-0").exists()  # a worker did die
    _equal_runs(split, serial)


def test_a_task_that_kills_every_worker_is_an_error_naming_it(tmp_path):
    import dask

    scene = _rod(tmp_path / "killed", "kill-always")
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1,
                                      dashboard_address=":0") as cluster, distributed.Client(cluster) as one:
            with pytest.raises(SimulationError, match=r"task 'rbody-simulate-swinging_rod-rows-0:40-\w+' "
                                                      r"\(rows 0:40 of 40\) lost the worker that ran it 1 times"):
                simulate(scene, dt=1e-2, method="rk4", client=one)


def test_a_forgotten_scene_is_sent_again_and_the_result_is_whole(cluster, tmp_path):
    """The cluster forgets the scattered scene mid-run and cancels every task that needs it ('already
    forgotten', as when Dask's memory manager had left its one copy on a worker that then died). Before:
    SimulationError, the run lost."""
    _, client = cluster
    scene = _rod(tmp_path / "forgot", "forget")
    serial = simulate(scene, dt=1e-2, method="rk4")
    split = simulate(scene, dt=1e-2, method="rk4", client=client, chunk=4)
    assert (tmp_path / "forgot-0").exists()  # the scene was forgotten mid-run
    _equal_runs(split, serial)


def test_every_worker_killed_at_once_still_gives_the_full_result(cluster, tmp_path):
    """Both workers end their process in their first task, with every copy of the scattered scene: the nannies
    start new ones, and the cancelled chunks are sent again (issue 23 made this a SimulationError, not a
    TypeError; now the run goes on, as it does when one worker dies)."""
    _, client = cluster
    scene = _rod(tmp_path / "killed", "kill-both")
    serial = simulate(scene, dt=1e-2, method="rk4")
    split = simulate(scene, dt=1e-2, method="rk4", client=client, chunk=4)
    assert (tmp_path / "killed-0").exists() and (tmp_path / "killed-1").exists()  # both workers died
    _equal_runs(split, serial)


def test_a_cluster_that_forgets_the_scene_every_time_is_an_error_naming_the_rows(cluster, tmp_path):
    _, client = cluster
    scene = _rod(tmp_path / "forgot", "forget-always")
    with pytest.raises(SimulationError, match=rf"lost the run: 10 of its tasks \(rows 0:4 first\) were cancelled "
                                              rf"each of the {RESENDS + 1} times they were sent"):
        simulate(scene, dt=1e-2, method="rk4", client=client, chunk=4)


def test_a_scheduler_stopped_mid_run_is_a_simulation_error_at_once():
    cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0")
    client = distributed.Client(cluster)
    workers = list(client.run(os.getpid).values())
    try:
        simulate(swinging_rod(1.0, theta0=np.linspace(0.1, 1.0, 8), t_end=0.1), dt=1e-3, client=client)  # warm up
        started = threading.Event()

        def stop_the_scheduler():
            started.wait()
            time.sleep(1.5)
            client.sync(cluster.scheduler.close)

        threading.Thread(target=stop_the_scheduler, daemon=True).start()
        scene = swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 40_000), t_end=200.0)  # ~80 s of work: not done first
        started.set()
        begun = time.monotonic()
        with pytest.raises(SimulationError, match=r"the Dask cluster at .* lost the run: its scheduler went away "
                                                  r"mid-run"):
            simulate(scene, dt=1e-3, client=client, save_every=1000, chunk=4000)
        assert time.monotonic() - begun < 30.0  # not the run's 80 s, nor a wait for a scheduler that is gone
    finally:
        for pid in workers:  # their tasks would run on for a minute with no scheduler to send them to
            os.kill(pid, signal.SIGKILL)
        client.close(timeout=2)
        with contextlib.suppress(TimeoutError):  # its scheduler is gone: the nannies end with their close's timeout
            cluster.close(timeout=2)
