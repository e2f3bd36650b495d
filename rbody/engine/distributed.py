"""A batch on a Dask cluster: simulate(scene, ..., client=client) splits the rows of the native model.

A scene's native model is rows: y0 (B, n) and params (B, p), one row per batch element, and the compiled
loops integrate each row on its own (rbody.engine.integrators: a batch gives the same bits as single
runs). So the rows are cut into chunks of `chunk` rows, one Dask task each:

    scene  -> every worker once (client.scatter), stripped of its cached values
    task k -> on a worker: scene.native_model rows [start, stop), the same compiled loop as a serial run,
              its states (T, stop - start, n) and first failed steps (stop - start,) sent back
    here   -> each chunk's states written into out (T, B, n) as it arrives

and simulate then forms the observables here, with the scene's own observe, as in a serial run: the
Trajectory equals the serial one bit for bit (same shapes, same values, lazy observables still lazy),
on workers with the same processor and library versions as this process (across processors the last
bits may differ: DESIGN.md, "Results that hold on any machine").

A worker that dies mid-run loses its task, and Dask runs it again on another worker (up to the
scheduler's `distributed.scheduler.allowed-failures`, 3 by default); a task that has killed that many
workers is a SimulationError naming its rows. Workers that die with the last copy of the scattered scene
(all at once, or the one Dask's memory manager left it on) make the cluster cancel the tasks that need
it: those chunks are sent again, scene and all, up to RESENDS times. Dask is imported only here, and only
when a client is given.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import uuid
from functools import cached_property
from typing import Any

import numpy as np

from rbody.checks import whole_number
from rbody.engine.methods import method as method_record
from rbody.engine.runner import integrate_model
from rbody.errors import SimulationError
from rbody.engine.native import Experiment, NativeModel

# A chunk of rows is at least this many batch elements (unless the batch is smaller): below it the cost
# of a task (sending the states back, about a millisecond of scheduling) is no longer small.
MIN_CHUNK = 4096
# Chunks per worker thread: several, so that a slow worker, or one that dies, delays only a small part.
CHUNKS_PER_THREAD = 4
# Where a scene keeps its prepared runs (rbody.simulation.prepare): never shipped to a worker.
PREPARED_KEY = "_prepared"
# How long a cluster without workers is waited for before giving up [s].
WORKER_WAIT_SECONDS = 30.0
# How many times the chunks whose tasks the cluster cancelled are sent again. Dask's active memory manager
# keeps one copy of the scattered scene once its waiting tasks sit on one worker; if that worker then dies,
# the scene is forgotten and every task still needing it is cancelled ("already forgotten"), not retried.
RESENDS = 3


def chunk_rows(batch: int, threads: int) -> int:
    """Rows per task for a batch of `batch` rows on `threads` worker threads: ceil(B / (4 threads)), at
    least MIN_CHUNK (and never more than the batch)."""
    return max(1, min(batch, max(MIN_CHUNK, math.ceil(batch / (CHUNKS_PER_THREAD * max(threads, 1))))))


def check_client(client: Any) -> int:
    """The number of worker threads of a running dask.distributed.Client (waiting up to WORKER_WAIT_SECONDS
    for a first worker). Raises ValueError naming the scheduler's address when `client` is not a Client, is
    closed, or has no worker."""
    from distributed import Client

    if not isinstance(client, Client):
        raise ValueError(f"client={client!r}: expected a dask.distributed.Client (or None to run here)")
    address = _address(client)
    if client.status != "running":
        raise ValueError(f"client of the Dask scheduler at {address} is {client.status}: connect a new "
                         "dask.distributed.Client")
    try:
        threads = sum(client.nthreads().values())
        if threads == 0:
            client.wait_for_workers(1, timeout=WORKER_WAIT_SECONDS)
            threads = sum(client.nthreads().values())
    except (OSError, TimeoutError) as error:
        raise ValueError(f"the Dask scheduler at {address} has no worker, or cannot be reached "
                         f"({type(error).__name__}: {error})") from None
    return threads


def integrate_on_cluster(client: Any, scene: Experiment, model: NativeModel, method: str, dt: float, nsteps: int,
                         save_every: int, out: np.ndarray, chunk: int | None = None) -> np.ndarray:
    """Integrate the rows of `model` (scene.native_model) on the cluster of `client` into out
    (nsteps // save_every + 1, B, n), in place; returns failed (B,) int64, the first non-finite step of each
    row or -1, as the serial loops do.

    chunk: rows per task (>= 1), default chunk_rows(B, worker threads).
    Chunks whose tasks the cluster cancels are sent again, up to RESENDS times (see there).
    Raises ValueError for a bad chunk or client (before any task), SimulationError when a task lost more
    workers than Dask retries it on, when chunks are cancelled more than RESENDS times, or when the
    scheduler is lost mid-run.
    """
    from distributed.scheduler import KilledWorker

    batch = model.y0.shape[0]
    if chunk is not None:
        whole_number(chunk, "chunk")
    threads = check_client(client)
    rows = chunk if chunk is not None else chunk_rows(batch, threads)
    address = _address(client)
    failed = np.empty(batch, dtype=np.int64)
    chunks = [(start, min(batch, start + rows)) for start in range(0, batch, rows)]
    rows_of = {}  # every task key sent: its chunk (start, stop)
    sent = 0
    try:
        while chunks:
            first = f"{len(chunks)} of its tasks (rows {chunks[0][0]}:{chunks[0][1]} first)"
            if client.status != "running":
                raise SimulationError(f"scene {scene.describe()}: the Dask cluster at {address} lost the run: its "
                                      f"scheduler went away mid-run (client {client.status}) with {first} not done; "
                                      "run it again, or without a client")
            if sent > RESENDS:
                raise SimulationError(f"scene {scene.describe()}: the Dask cluster at {address} lost the run: {first} "
                                      f"were cancelled each of the {sent} times they were sent (the scene scattered "
                                      "to the workers lost with every worker that held it); run it again, or "
                                      "without a client")
            chunks = _send_chunks(client, scene, chunks, method, dt, nsteps, save_every, out, failed, rows_of)
            sent += 1
        return failed
    except KilledWorker as error:
        start, stop = rows_of.get(error.task, ("?", "?"))
        raise SimulationError(
            f"scene {scene.describe()}: task {error.task!r} (rows {start}:{stop} of {batch}) lost the worker "
            f"that ran it {error.allowed_failures + 1} times: Dask ran it again after each worker death, up to "
            f"distributed.scheduler.allowed-failures = {error.allowed_failures} times (scheduler {address}, last "
            f"worker {error.last_worker.address})") from None
    except OSError as error:
        raise SimulationError(f"scene {scene.describe()}: the Dask cluster at {address} lost the run: its scheduler "
                              f"went away mid-run ({type(error).__name__}: {error}); run it again, or without a "
                              "client") from None


def _send_chunks(client: Any, scene: Experiment, chunks: list[tuple[int, int]], method: str, dt: float, nsteps: int,
                 save_every: int, out: np.ndarray, failed: np.ndarray,
                 rows_of: dict[str, tuple[int, int]]) -> list[tuple[int, int]]:
    """One sending of `chunks` (start, stop) to the cluster: the scene scattered to every worker, a task per
    chunk (its key and chunk recorded in rows_of), each chunk's states written into out and its failed steps
    into failed as it arrives. Returns the chunks whose tasks the cluster cancelled (their scattered scene lost
    with the last worker that held it), to be sent again; a task's error or a KilledWorker is raised."""
    from concurrent.futures import CancelledError

    from distributed import as_completed
    from distributed.client import FutureCancelledError

    batch = out.shape[1]
    token = uuid.uuid4().hex[:8]
    futures = {}
    cancelled = []
    try:
        shipped = client.scatter(portable(scene), broadcast=True, hash=False)
        for start, stop in chunks:
            key = f"rbody-simulate-{scene.name}-rows-{start}:{stop}-{token}"
            future = client.submit(integrate_rows, shipped, start, stop, method, dt, nsteps, save_every,
                                   key=key, pure=False)
            futures[future.key] = future
            rows_of[future.key] = (start, stop)
        for future in as_completed(list(futures.values())):
            start, stop = rows_of[future.key]
            try:
                result = future.result()  # a task's error or a KilledWorker is raised here, not unpacked
            except (FutureCancelledError, CancelledError):
                cancelled.append((start, stop))
                continue
            if not (isinstance(result, tuple) and len(result) == 2):
                raise SimulationError(f"scene {scene.describe()}: task {future.key!r} (rows {start}:{stop} of {batch}) "
                                      f"returned {type(result).__name__}, not its states: the Dask cluster at "
                                      f"{_address(client)} lost it")
            out[:, start:stop], failed[start:stop] = result
            future.release()
    finally:
        for future in futures.values():
            future.cancel()
    return sorted(cancelled)


def integrate_rows(scene: Experiment, start: int, stop: int, method: str, dt: float, nsteps: int,
                   save_every: int) -> tuple[np.ndarray, np.ndarray]:
    """The task of one chunk, run on a worker: rows [start, stop) of scene.native_model integrated as a
    serial run would; returns states (nsteps // save_every + 1, stop - start, n) and failed (stop - start,).
    numba's threads are limited to the worker's threads, so that a worker per core does not oversubscribe."""
    import numba

    model = getattr(scene, "native_model_for", lambda _method: scene.native_model)(method)  # once per worker
    rows = dataclasses.replace(model, y0=np.ascontiguousarray(model.y0[start:stop]),
                               params=np.ascontiguousarray(model.params[start:stop]))
    out = np.empty((nsteps // save_every + 1,) + rows.y0.shape)
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(previous, _worker_threads())))  # this thread's launches only
    try:
        failed = integrate_model(rows, method_record(method), dt, nsteps, save_every, out)  # as simulate runs them
    finally:
        numba.set_num_threads(previous)
    return out, failed


def portable(scene: Experiment) -> Experiment:
    """A shallow copy of `scene` without its cached values (the native model holds compiled functions and
    closures, and the batch's states) and without its prepared runs (rbody.simulation.prepare keeps them in
    PREPARED_KEY, each holding the model): what is sent to the workers, who build their own."""
    bare = copy.copy(scene)
    state = vars(bare)
    for name in list(state):
        if name == PREPARED_KEY or isinstance(getattr(type(scene), name, None), cached_property):
            del state[name]
    return bare


def _worker_threads() -> int:
    try:
        from distributed import get_worker

        return int(get_worker().state.nthreads)
    except (ImportError, ValueError, AttributeError):  # not in a worker (a direct call): no limit
        return 1 << 30


def _address(client: Any) -> str:
    """The scheduler's address, also for a closed client (which no longer holds its connection)."""
    address = getattr(getattr(client, "scheduler", None), "address", None)
    if address is None:
        start = getattr(client, "_start_arg", None)  # the address or cluster the client was made with
        address = start if isinstance(start, str) else getattr(start, "scheduler_address", None)
    return str(address) if address else "(unknown address)"
