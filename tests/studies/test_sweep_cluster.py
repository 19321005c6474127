"""A sweep on a real Dask cluster: a scheduler and two workers started as separate processes with the
``dask`` command-line tools. One worker is killed mid-study: its runs are retried on the other, no
row is lost, and the table equals the same sweep run in this process (the runs are deterministic)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from viz3d.studies.execute import STORE_NAME, Cluster
from viz3d.studies.plan import grid_points
from viz3d.sweep import COST, sweep

from conftest import SCENES

SCENE = SCENES / "spherical_pendulum.toml"
DASK = Path(sys.executable).parent / "dask"
#: Short NumPy-path runs (0.1-0.6 s each: a worker is almost never between two runs when it is killed).
OVERRIDES = ["sim.t_end=0.8", "sim.compiled=false"]
GRID = {"sim.dt": [1e-3, 2e-3, 2.5e-3, 4e-3], "sim.integrator": ["rk4", "heun", "euler"]}
METRICS = ("status", "energy_drift_rel", "max_constraint_violation", "t_final")
#: Seconds a started process may take to be ready.
STARTUP = 60.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([str(DASK), *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


def _wait_for_workers(address: str, n: int) -> None:
    from distributed import Client

    with Client(address, timeout="30s") as client:
        client.wait_for_workers(n, timeout=STARTUP)


@pytest.fixture
def cluster():
    """(scheduler address, [worker processes]) on loopback; every process stopped afterwards."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_start("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard")]
    try:
        procs += [_start("worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--name", f"w{i}")
                  for i in range(2)]
        _wait_for_workers(address, 2)
        yield address, procs[1:]
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def _kill_after_rows(store: Path, rows: int, worker: subprocess.Popen, killed: list) -> None:
    """Kill ``worker`` (SIGKILL, no goodbye) once ``store`` holds ``rows`` rows; note how many it held."""
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        n = len(store.read_text().splitlines()) if store.exists() else 0
        if n >= rows:
            os.killpg(worker.pid, signal.SIGKILL)
            killed.append(n)
            return
        time.sleep(0.02)


def _retried(address: str, keys: list[str]) -> set[str]:
    """Keys the scheduler took back from a worker that died while running them (its transition log)."""
    from distributed import Client

    with Client(address, timeout="30s") as client:
        story = client.story(*keys)
    return {e[1] for e in story if e[2] == "processing" and e[3] == "released" and "worker-cleanup" in e[5]}


def _metrics_table(report) -> list[list]:
    cost = len(COST) + 1  # cost columns and the key
    return [row[:-cost] for row in report.table()]


def test_a_killed_workers_runs_are_retried_and_the_table_equals_the_local_one(cluster, tmp_path):
    address, workers = cluster
    points = grid_points(GRID)
    keys = tuple(GRID)
    killed = []
    watcher = threading.Thread(target=_kill_after_rows, args=(tmp_path / STORE_NAME, 3, workers[0], killed))
    watcher.start()
    remote = sweep(SCENE, keys, points, METRICS, Cluster(scheduler=address), tmp_path, OVERRIDES)
    watcher.join()
    assert killed and killed[0] < len(points), "the worker was not killed mid-study"
    assert workers[0].poll() is not None and workers[1].poll() is None
    assert len(remote.table()) == len(points) and not remote.failed
    retried = _retried(address, [o.key for o in remote.outcomes])
    assert retried, "no run was in flight on the killed worker"
    assert all(o.row["status"] == "ok" for o in remote.outcomes if o.key in retried)
    local = sweep(SCENE, keys, points, METRICS, Cluster(workers=1), None, OVERRIDES)
    assert _metrics_table(remote) == _metrics_table(local)
    assert [o.key for o in remote.outcomes] == [o.key for o in local.outcomes]
    assert len((tmp_path / STORE_NAME).read_text().splitlines()) == len(points)


@pytest.mark.slow
def test_the_default_local_cluster_gives_the_table_of_this_process(tmp_path):
    points = grid_points(GRID)
    local = sweep(SCENE, tuple(GRID), points, METRICS, Cluster(workers=2), tmp_path, OVERRIDES)
    here = sweep(SCENE, tuple(GRID), points, METRICS, Cluster(workers=1), None, OVERRIDES)
    assert _metrics_table(local) == _metrics_table(here) and not local.failed
