"""Issue 23: every Dask worker killed at once mid-run is a SimulationError, not a TypeError."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from rbody import SimulationError, simulate  # noqa: E402
from rbody.scenes import swinging_rod  # noqa: E402


def test_all_workers_killed_at_once_is_a_simulation_error():
    """Both workers of a local cluster killed (SIGKILL) while their tasks run. Before:
    TypeError: cannot unpack non-iterable FutureCancelledError object."""
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=":0") as cluster, distributed.Client(cluster) as client:
        simulate(swinging_rod(1.0, theta0=np.linspace(0.1, 1.0, 8), t_end=0.1), dt=1e-3, client=client)  # warm up
        pids = list(client.run(os.getpid).values())
        started = threading.Event()

        def kill_every_worker():
            started.wait()
            time.sleep(1.5)
            for pid in pids:
                os.kill(pid, signal.SIGKILL)

        threading.Thread(target=kill_every_worker, daemon=True).start()
        scene = swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 40_000), t_end=200.0)  # ~80 s of work: not done first
        started.set()
        with pytest.raises(SimulationError, match=r"the Dask cluster at .* lost the run"):
            simulate(scene, dt=1e-3, client=client, save_every=1000, chunk=4000)
