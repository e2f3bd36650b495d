"""The commands' independent runs as tasks: here, one after another, or on a Dask cluster.

    with connect(scheduler=None, workers=None) as client:   # both None: no cluster, Dask not imported
        results = run_tasks(client, tasks, what="bench", timed=True)

A task is (name, function, args): function(*args), a module-level function (workers import it by name)
with arguments that pickle. run_tasks returns the results in the order of `tasks`, whatever order they
finish in, so that the tables, CSVs and reports built from them equal the serial run's (timings aside).
Progress on stderr: tasks done of all.

--workers N: a local cluster of N worker processes, one thread each. --scheduler ADDRESS: the workers of
an existing cluster (`dask scheduler`, `dask worker ADDRESS`), which need rbody and validation installed.

Timed tasks (the benchmark's sweeps, timed=True) each hold the worker resource "timing", of which a worker
has one: a worker runs one timed task at a time whatever its thread count, so that no timing shares its
worker with another run. The local cluster's workers have it; an existing cluster's workers are started
with `dask worker ADDRESS --nthreads 1 --resources timing=1`, else the timed command refuses to start.

A worker that dies mid-task: Dask runs the task again on another worker (up to the scheduler's
`distributed.scheduler.allowed-failures`, 3 by default); beyond that, or on any task's error, the command
stops with an error naming the task, before anything is written to its report folder.
"""

from __future__ import annotations

import contextlib
import sys
import time
import uuid
from typing import Any, Callable, Iterator, Sequence

TIMING = "timing"  # the worker resource a timed task holds (one per worker)
CONNECT_TIMEOUT = "10s"
HANDSHAKE_SECONDS = 15.0  # the whole first exchange with a scheduler (connect, handshake, identity) is bounded by this
WORKER_WAIT_SECONDS = 30.0  # a timed run on a cluster with no worker yet (starting, or restarted by its nanny) waits this


class ClusterUnavailable(ValueError):
    """No Dask scheduler answers as Dask at the address given (nothing listens, or something else does), or the
    cluster options are wrong: a set-up problem, found before any work (the commands exit with status 2)."""

Task = tuple[str, Callable[..., Any], tuple]


@contextlib.contextmanager
def connect(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A dask.distributed.Client of a local cluster of `workers` processes (one thread and one "timing"
    resource each), or of the scheduler at address `scheduler`; None when both are None. Closed on exit.
    Raises ClusterUnavailable (a ValueError) when both are given, for workers < 1, and naming the address when no
    Dask scheduler answers there within HANDSHAKE_SECONDS (scheduler_answers: also when something else listens
    there, which would otherwise hold the Client in its handshake for minutes)."""
    if scheduler is not None and workers is not None:
        raise ClusterUnavailable(f"--scheduler {scheduler} and --workers {workers}: give one of them")
    if scheduler is None and workers is None:
        yield None
        return
    from distributed import Client, LocalCluster

    if workers is not None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ClusterUnavailable(f"--workers {workers!r}: expected a whole number of worker processes >= 1")
        with LocalCluster(n_workers=workers, processes=True, threads_per_worker=1, resources={TIMING: 1},
                          dashboard_address=":0") as cluster, Client(cluster) as client:
            yield client
        return
    scheduler_answers(scheduler)
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as error:
        raise ClusterUnavailable(f"--scheduler {scheduler}: no Dask scheduler answered there within {CONNECT_TIMEOUT} "
                                 f"({type(error).__name__}: {error}); start one with `dask scheduler` and workers "
                                 f"with `dask worker {scheduler}`") from None
    with client:
        yield client


def scheduler_answers(address: str, seconds: float | None = None) -> None:
    """Return when a Dask scheduler answers at `address` (a comm connection, its handshake, and the scheduler's
    reply to "identity"), all within `seconds`; else ClusterUnavailable saying what answered: nothing, something
    silent (a handshake that never ends: distributed's Client would wait for minutes), or something that is not
    Dask (garbage a Client would try to read as a frame of exabytes)."""
    import asyncio

    from asyncio import open_connection

    from distributed.comm import connect as open_comm
    from distributed.comm.addressing import parse_address, parse_host_port

    seconds = HANDSHAKE_SECONDS if seconds is None else seconds
    if not isinstance(address, str) or not address:
        raise ClusterUnavailable(f"--scheduler {address!r}: expected an address such as tcp://HOST:8786")
    if address.startswith("inproc://"):
        return  # a scheduler in this process

    async def accepted() -> bool:
        """Whether a TCP connection to the address is accepted (a plain socket, before distributed's connect,
        whose attempts are timed in fifths of its timeout: a pause of this process, such as a garbage collection
        in a large one, would otherwise turn a silent server into an unreachable one)."""
        scheme, location = parse_address(address, strict=False)
        if scheme != "tcp":
            return True  # tls, ucx, ws: left to distributed's connect
        host, port = parse_host_port(location)
        _reader, writer = await open_connection(host, port)
        writer.close()
        return True

    async def identity():
        comm = await open_comm(address, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    timeouts = (TimeoutError, asyncio.TimeoutError)  # one class from Python 3.11
    start = time.perf_counter()
    connected = False
    try:
        connected = asyncio.run(asyncio.wait_for(accepted(), seconds / 2))
        left = max(seconds - (time.perf_counter() - start), 0.1)
        reply = asyncio.run(asyncio.wait_for(identity(), left))
    except Exception as error:  # noqa: BLE001 - whatever went wrong, no Dask scheduler answered
        after = f"after {time.perf_counter() - start:.1f} s"
        start_one = f"start one with `dask scheduler` and workers with `dask worker {address}`"
        if not connected:  # refused, unreachable, or no connection accepted within seconds / 2
            raise ClusterUnavailable(f"--scheduler {address}: no Dask scheduler answered there ({_what(error)}), "
                                     f"{after}; {start_one}") from None
        if isinstance(error, timeouts) or isinstance(error.__cause__, timeouts):
            raise ClusterUnavailable(f"--scheduler {address}: something accepted the connection but did not answer "
                                     f"as a Dask scheduler within {seconds:g} s (no handshake): is the port right? "
                                     f"Start a scheduler with `dask scheduler`") from None
        raise ClusterUnavailable(f"--scheduler {address}: what answered there is not a Dask scheduler "
                                 f"({_what(error)}), {after}; {start_one}") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise ClusterUnavailable(f"--scheduler {address}: what answered there is not a Dask scheduler (it replied "
                                 f"{str(reply)[:200]!r} to 'identity')")


def _what(error: BaseException) -> str:
    """An error as "Type: message" (its first 200 characters), "timed out" for a timeout without a message."""
    text = str(error)[:200]
    if not text:
        return "timed out"
    return f"{type(error).__name__}: {text}"


def run_tasks(client: Any, tasks: Sequence[Task], *, what: str, timed: bool = False, log=None) -> list:
    """The result of each task, in the order of `tasks`: run here in that order (client None), or on the
    cluster of `client` (timed: one at a time per worker, module docstring). A task's error is raised with a
    note naming the task; a task that lost more workers than Dask retries it on is a RuntimeError naming it.
    Progress goes to `log` (default sys.stderr)."""
    log = log or sys.stderr
    if client is None:
        results = []
        for k, (name, function, args) in enumerate(tasks, 1):
            start = time.perf_counter()
            try:
                results.append(function(*args))
            except Exception as error:
                error.add_note(f"in task {name} of {what}")
                raise
            print(f"[{what} {k}/{len(tasks)}] {name} {time.perf_counter() - start:.1f} s", file=log, flush=True)
        return results
    return _run_on_cluster(client, tasks, what=what, timed=timed, log=log)


def _run_on_cluster(client: Any, tasks: Sequence[Task], *, what: str, timed: bool, log) -> list:
    from concurrent.futures import CancelledError

    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    address = client.scheduler.address
    if timed:
        _check_timing_resource(client, address)
    token = uuid.uuid4().hex[:8]
    futures, names = [], {}
    try:
        for index, (name, function, args) in enumerate(tasks):
            future = client.submit(function, *args, key=f"{what}-{index}-{_key_safe(name)}-{token}", pure=False,
                                   resources={TIMING: 1} if timed else None)
            futures.append(future)
            names[future.key] = name
        results: dict[str, Any] = {}
        started = time.perf_counter()
        for done, future in enumerate(as_completed(futures), 1):
            name = names[future.key]
            try:
                results[future.key] = future.result()
            except KilledWorker as error:
                raise RuntimeError(
                    f"task {name} of {what} lost the worker that ran it {error.allowed_failures + 1} times: Dask ran "
                    f"it again after each worker death, up to distributed.scheduler.allowed-failures = "
                    f"{error.allowed_failures} (scheduler {address}, last worker {error.last_worker.address})"
                ) from None
            except CancelledError as error:  # every worker killed at once, or the scheduler gone
                raise RuntimeError(f"task {name} of {what} was cancelled by the Dask cluster at {address} (its "
                                   f"workers or its scheduler were lost: {type(error).__name__}: {error})") from None
            except Exception as error:
                error.add_note(f"in task {name} of {what}, on the Dask cluster at {address}")
                raise
            print(f"[{what} {done}/{len(tasks)} tasks done, {time.perf_counter() - started:.0f} s] {name}",
                  file=log, flush=True)
            future.release()
        return [results[future.key] for future in futures]
    finally:
        for future in futures:
            future.cancel()


def _check_timing_resource(client: Any, address: str) -> None:
    """Refuse a timed run on a cluster none of whose workers has the "timing" resource (its tasks would wait
    forever). A cluster with no worker at all is given WORKER_WAIT_SECONDS for one to join: workers that are still
    starting, or that their nanny is restarting after a crash, are not yet listed."""
    if not client.scheduler_info(n_workers=-1)["workers"]:
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_SECONDS)
        except TimeoutError:
            pass  # refused below, naming the 0 workers
    workers = client.scheduler_info(n_workers=-1)["workers"]
    if not any(info.get("resources", {}).get(TIMING) for info in workers.values()):
        raise ClusterUnavailable(f"the Dask cluster at {address} has {len(workers)} workers and none with the resource "
                         f"'{TIMING}': timed runs need it, one per worker, so that each timing has its worker to "
                         f"itself; start workers with `dask worker {address} --nthreads 1 --resources {TIMING}=1`")


def _key_safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_.:" else "_" for c in name)
