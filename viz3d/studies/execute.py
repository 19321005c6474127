"""Running a study's points: in this process, on a local Dask cluster (one worker process per core),
or on an existing Dask scheduler (``--scheduler tcp://host:8786``), with one task function for all.

A run is a pure task: ``run_task(task) -> row`` depends only on the task (the resolved scene and the
measure), so Dask may run it again elsewhere when a worker dies. A run that fails, diverges or raises
comes back as a row carrying its diagnosis; a point the scene refuses is a row too. Rows are plain
data (``dict``), appended to the results store (``Store``) as they arrive, keyed by the hash of the
resolved scene and the measure, so a study started again runs only what is missing.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import pickle
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from viz3d.scene.load import Scene, load_scene
from viz3d.scene.schema import SceneError
from viz3d.studies.plan import Point
from viz3d.studies.resolved import ResolvedScene, resolve, scene_on_disk

#: Seconds to wait for an existing scheduler to answer.
CONNECT_TIMEOUT = "10s"


class Measure(Protocol):
    """What one run computes: ``measure(scene) -> row`` (a ``dict`` of plain values). Measures are
    frozen dataclasses (picklable, compared by value); a row's ``status`` is ``"ok"`` or a diagnosis."""

    def __call__(self, scene: Scene) -> dict: ...


@dataclass(frozen=True)
class Cluster:
    """Where a study runs.

    Attributes
    ----------
    workers : int
        Local worker processes (one thread each); 1, without ``scheduler``: in this process.
    scheduler : str or None
        Address of an existing Dask scheduler (``tcp://host:8786``); its workers run the study.
    """

    workers: int = 1
    scheduler: str | None = None

    @property
    def in_process(self) -> bool:
        return self.scheduler is None and self.workers <= 1


#: Runs in this process, one after the other (the default of the library's studies).
IN_PROCESS = Cluster()


def local_cores() -> int:
    """Cores this process may run on (the default number of local workers)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


@dataclass(frozen=True)
class Task:
    """One run: the resolved scene, the measure, and the key naming both (``task_key``)."""

    key: str
    scene: ResolvedScene
    measure: Measure


def task_key(scene: ResolvedScene, measure: Measure) -> str:
    """``viz3d-run-<sha256>`` of the resolved scene's key and the pickled measure: equal keys, equal rows."""
    h = hashlib.sha256(scene.key.encode() + pickle.dumps(measure))
    return f"viz3d-run-{h.hexdigest()[:32]}"


def run_task(task: Task) -> dict:
    """The row of one run (pure: a function of ``task`` only). Whatever the run raises becomes the
    row's ``status`` (``raised <Type>: message``), so a study never loses a point to an exception."""
    try:
        with scene_on_disk(task.scene) as scene:
            row = task.measure(scene)
    except Exception as exc:  # noqa: BLE001 - a row with the diagnosis instead of a lost study
        return {"status": f"raised {type(exc).__name__}: {exc}"}
    return {"status": "ok", **row}


@dataclass(frozen=True)
class Store:
    """The results store of a study: JSON lines ``{"key": ..., "row": {...}}`` in ``path``, one per run,
    appended as runs finish (a line cut short by an interruption is ignored when read back)."""

    path: Path

    def load(self) -> dict[str, dict]:
        rows = {}
        if self.path.is_file():
            for line in self.path.read_text(encoding="utf-8").splitlines():
                with contextlib.suppress(ValueError, KeyError, TypeError):
                    entry = json.loads(line)
                    rows[entry["key"]] = entry["row"]
        return rows

    def append(self, key: str, row: dict) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a", encoding="utf-8") as fh:
            fh.write(json.dumps({"key": key, "row": row}, default=_plain) + "\n")
            fh.flush()


def _plain(x: Any) -> Any:
    """JSON form of numpy scalars and arrays."""
    return x.tolist() if hasattr(x, "tolist") else str(x)


@dataclass(frozen=True)
class Outcome:
    """What a study's runner returns for each point, in the points' order.

    Attributes
    ----------
    point : Point
    key : str or None
        The run's key (``task_key``); None for a point the scene refused.
    row : dict or None
        The measure's row with ``status``; None for a point not run (``max_runs``).
    cached : bool
        The row came from the results store.
    """

    point: Point
    key: str | None
    row: dict | None
    cached: bool = False


def run_study(path, points: Sequence[Point], measure: Measure, cluster: Cluster = IN_PROCESS, *,
              overrides: Sequence[str] = (), mesh_dirs: Sequence[Path] = (), store: Store | None = None,
              progress: bool = False, max_runs: int | None = None) -> list[Outcome]:
    """Run ``measure`` on the scene ``path`` at every point (``overrides`` first, then the point's).

    Points the scene refuses are rows at once (``status`` ``refused: ...``); points whose key is in
    ``store`` are not run again; at most ``max_runs`` new runs are made (the rest are left ``None``)."""
    outcomes, tasks = _prepare(path, points, measure, list(overrides), tuple(mesh_dirs), store)
    todo = list(tasks.values())[:max_runs]
    rows: dict[str, dict] = {}
    bar = StudyProgress(len(todo), sys.stderr if progress else None)

    def arrived(key: str, row: dict) -> None:
        rows[key] = row
        if store is not None and not row["status"].startswith("lost"):
            store.append(key, row)
        bar.update(not row["status"] == "ok")

    try:
        _execute(todo, cluster, arrived)
    finally:
        bar.close()
    return [o if o.row is not None or o.key not in rows else Outcome(o.point, o.key, rows[o.key]) for o in outcomes]


def _prepare(path, points, measure, overrides, mesh_dirs, store) -> tuple[list[Outcome], dict[str, Task]]:
    """Resolve each point: a refused point's row, a stored row, or a task to run (points that resolve
    to the same scene share one task)."""
    stored = store.load() if store is not None else {}
    outcomes, tasks = [], {}
    for point in points:
        try:
            scene = resolve(load_scene(path, overrides + list(point.overrides), mesh_dirs=mesh_dirs))
        except SceneError as exc:
            outcomes.append(Outcome(point, None, {"status": f"refused: {exc}"}))
            continue
        key = task_key(scene, measure)
        outcomes.append(Outcome(point, key, stored.get(key), key in stored))
        if key not in stored:
            tasks.setdefault(key, Task(key, scene, measure))
    return outcomes, tasks


def _execute(tasks: list[Task], cluster: Cluster, arrived: Callable[[str, dict], None]) -> None:
    if not tasks:
        return
    if cluster.in_process:
        for task in tasks:
            arrived(task.key, run_task(task))
        return
    from distributed import as_completed

    with dask_client(cluster, len(tasks)) as client:
        futures = [client.submit(run_task, task, key=task.key, pure=True) for task in tasks]
        for future in as_completed(futures):
            arrived(future.key, _row_of(future))
            future.release()


def _row_of(future) -> dict:
    """A finished future's row; a task Dask gave up on (a worker died under it too often) is a row too."""
    if future.status == "finished":
        return future.result()
    return {"status": f"lost: {future.exception()!r}"}


@contextlib.contextmanager
def dask_client(cluster: Cluster, n_tasks: int) -> Iterator:
    """A ``distributed.Client`` on the scheduler of ``cluster``, or on a new local cluster of
    ``min(workers, n_tasks)`` processes (closed on exit). Raises ``ConnectionError`` naming the
    address when the scheduler does not answer."""
    from distributed import Client, LocalCluster

    if cluster.scheduler:
        try:
            client = Client(cluster.scheduler, timeout=CONNECT_TIMEOUT)
        except OSError as exc:
            raise ConnectionError(f"--scheduler {cluster.scheduler}: no Dask scheduler answers there ({exc})") from None
        with client:
            yield client
        return
    with LocalCluster(n_workers=min(cluster.workers, n_tasks), threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as local, Client(local) as client:
        yield client


class StudyProgress:
    """One stderr line: runs done of the total, failed, elapsed and estimated time left (drawn only
    on a terminal, or on the ``stream`` given)."""

    def __init__(self, total: int, stream=None):
        self.total, self.done, self.failed = total, 0, 0
        self.stream = stream if stream is not None and (stream.isatty() or stream is not sys.stderr) else None
        self.start = time.perf_counter()

    def update(self, failed: bool) -> None:
        self.done += 1
        self.failed += int(failed)
        if self.stream is not None:
            self.stream.write("\r" + self.line())
            self.stream.flush()

    def line(self) -> str:
        elapsed = time.perf_counter() - self.start
        left = elapsed / self.done * (self.total - self.done) if self.done else math.nan
        bar = "#" * int(24 * self.done / max(self.total, 1))
        return (f"[{bar:<24}] {self.done}/{self.total} runs, {self.failed} failed, {elapsed:.1f} s elapsed, "
                f"~{left:.0f} s left ")

    def close(self) -> None:
        if self.stream is not None and self.done:
            self.stream.write("\n")
            self.stream.flush()
