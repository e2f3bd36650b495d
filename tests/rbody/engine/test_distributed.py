"""simulate(scene, client=...): a batch split over a Dask cluster equals the serial run bit for bit."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from rbody import Body, Inertia, Joint, Layout, Scene, simulate  # noqa: E402
from rbody.engine.distributed import MIN_CHUNK, chunk_rows, portable  # noqa: E402
from rbody.scenes import free_rotation, pendulum_chain, rocket, rolling_race, swinging_rod, two_body  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0") as cluster:
        with distributed.Client(cluster) as client:
            yield client


def _batches():
    theta0 = np.linspace(0.1, 3.0, 37)
    return {
        "rod rk4": (swinging_rod(1.0, mass=np.linspace(1.0, 2.0, 37), theta0=theta0, t_end=1.0), "rk4"),
        "rod verlet, 2-D batch": (swinging_rod(1.0, theta0=theta0.reshape(1, 37) + np.zeros((3, 1)),
                                               omega0=np.array([[0.0], [1.0], [-2.0]]), t_end=1.0), "verlet"),
        "chain gauss6": (pendulum_chain([1.0, 0.5], masses=[1.0, 2.0], theta0=np.stack([theta0, -theta0], axis=1),
                                        t_end=0.5), "gauss6"),
        "free rotation splitting": (free_rotation(Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])),
                                                  omega0=np.stack([np.full(37, 0.1), theta0, np.ones(37)], axis=1),
                                                  t_end=1.0), "splitting"),
        # one race: its bodies are the rows of the native model, the scene itself unbatched
        "race of 4 bodies": (rolling_race(("disc", "hollow_cylinder", "solid_sphere", "spherical_shell"),
                                          radius=0.1, incline=0.3, length=1.0), "rk4"),
        # the step cut at burn-out (simulate's other path)
        "rocket across burn-out": (rocket(1.0, burn_rate=0.1, exhaust_speed=np.linspace(1.0, 3.0, 37), dry_mass=0.5,
                                          t_end=8.0), "rk4"),
        # a tree of the general engine: a hinge, then a ball joint whose quaternion the finish hook renormalises
        "tree hinge + ball": (Scene.from_layout(_arm_and_ball(), t_end=0.5,
                                                qvel0=np.stack([theta0, np.ones(37), -theta0, 0.5 * theta0], axis=1)),
                              "rk4"),
        "two bodies": (two_body(1.0, np.linspace(0.5, 2.0, 37), separation=1.0, relative_velocity=1.0, t_end=2.0),
                       "verlet"),
    }


def _arm_and_ball() -> Layout:
    body = Inertia(1.0, np.zeros(3), np.diag([0.1, 0.2, 0.25]))
    return Layout(bodies=(Body("arm", body, pos=(0.0, 0.0, -0.5)),
                          Body("ball", body, parent="arm", pos=(0.3, 0.0, -0.5))),
                  joints=(Joint("hinge", "hinge", "arm", axis=(0.0, 1.0, 0.0), anchor=(0.0, 0.0, 0.5)),
                          Joint("socket", "ball", "ball")))


@pytest.mark.parametrize("name", list(_batches()))
def test_a_split_batch_equals_the_serial_run_bit_for_bit(client, name):
    scene, method = _batches()[name]
    serial = simulate(scene, dt=1e-2, method=method)
    split = simulate(scene, dt=1e-2, method=method, client=client, chunk=5)
    assert np.array_equal(split.t, serial.t)
    assert split.observables == serial.observables
    for observable in serial.observables:
        assert split[observable].shape == serial[observable].shape, observable
        assert np.array_equal(split[observable], serial[observable], equal_nan=True), observable
    assert split.meta == serial.meta


def test_default_chunks_and_lazy_energy(client):
    rod = swinging_rod(1.0, theta0=np.linspace(0.1, 3.0, 3 * MIN_CHUNK), t_end=0.2)
    serial = simulate(rod, dt=1e-2, method="rk4", save_every=2)
    split = simulate(rod, dt=1e-2, method="rk4", save_every=2, client=client)  # default chunk: 3 tasks
    assert not split.data.is_computed("energy")  # a lazy observable stays lazy
    for observable in ("theta", "omega", "energy"):
        assert np.array_equal(split[observable], serial[observable]), observable


def test_chunk_size_from_batch_and_threads():
    assert chunk_rows(10**6, 2) == 125_000  # ceil(B / (4 threads))
    assert chunk_rows(20_000, 2) == MIN_CHUNK  # at least a few thousand rows
    assert chunk_rows(1000, 64) == 1000  # never more than the batch
    assert chunk_rows(1, 1) == 1


def test_without_a_client_dask_is_never_imported():
    code = ("import sys, numpy as np, rbody; from rbody import scenes; "
            "rbody.simulate(scenes.swinging_rod(1.0, theta0=np.linspace(0.1, 1, 8), t_end=0.1), dt=1e-2); "
            "print('dask' in sys.modules, 'distributed' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert result.stdout.split() == ["False", "False"]


def test_bad_clients_and_chunks_are_refused_before_any_task(client):
    rod = swinging_rod(1.0, theta0=np.linspace(0.1, 1.0, 8), t_end=0.1)
    with pytest.raises(ValueError, match="chunk=5: rows per task of a Dask client"):
        simulate(rod, dt=1e-2, chunk=5)
    with pytest.raises(ValueError, match="chunk=0: expected a whole number"):
        simulate(rod, dt=1e-2, client=client, chunk=0)
    with pytest.raises(ValueError, match="client='tcp://127.0.0.1:8786': expected a dask.distributed.Client"):
        simulate(rod, dt=1e-2, client="tcp://127.0.0.1:8786")
    closed = distributed.Client(client.scheduler.address)
    closed.close()
    with pytest.raises(ValueError, match=f"scheduler at {client.scheduler.address} is closed"):
        simulate(rod, dt=1e-2, client=closed)


def test_an_unreachable_scheduler_is_an_error_naming_its_address():
    # rbody takes a connected Client; connecting is Dask's, and its error names the address.
    with pytest.raises(OSError, match="127.0.0.1:9"):
        distributed.Client("tcp://127.0.0.1:9", timeout="2s")


def test_the_scenes_sent_to_workers_carry_no_cached_model():
    rod = swinging_rod(1.0, theta0=np.linspace(0.1, 1.0, 8), t_end=0.1)
    rod.native_model  # noqa: B018 - cache it, as simulate does
    assert "native_model" in vars(rod)
    bare = portable(rod)
    assert "native_model" not in vars(bare) and "native_model" in vars(rod)
    assert np.array_equal(bare.native_model.y0, rod.native_model.y0)
