"""Running a study's points: in this process, on a local Dask cluster (one worker process per core),
or on an existing Dask scheduler (``--scheduler tcp://host:8786``), with one task function for all.

A run is a pure task: ``run_task(task) -> row`` depends only on the task (the resolved scene and the
measure), so Dask may run it again elsewhere when a worker dies. A run that fails, diverges or raises
comes back as a row carrying its diagnosis; a point the scene refuses is a row too. Rows are plain
data (``dict``), appended to the results store (``Store``) as they arrive, keyed by the hash of the
resolved scene and the measure, so a study started again runs only what is missing. A study sent
to a scheduler that has no worker for ``Cluster.worker_timeout`` seconds stops with ``NoWorkers``.
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
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any, Protocol

from viz3d.interrupts import InterruptGuard
from viz3d.scene.load import Scene, load_scene
from viz3d.scene.schema import SceneError
from viz3d.studies import WORKER_TIMEOUT
from viz3d.studies.plan import Point
from viz3d.studies.resolved import ResolvedScene, resolve, scene_on_disk

#: Seconds to wait for an existing scheduler to answer.
CONNECT_TIMEOUT = "10s"
#: Seconds between two looks at a scheduler's workers, and between two looks for finished runs.
WORKER_POLL_S, RESULT_POLL_S = 1.0, 0.05
#: File name of the results store in a study's output folder.
STORE_NAME = "runs.jsonl"


class Measure(Protocol):
    """What one run computes: ``measure(scene) -> row`` (a ``dict`` of plain values). Measures are
    frozen dataclasses (picklable, compared by value); a row's ``status`` is ``"ok"`` or a diagnosis.

    A measure's identity (``measure_identity``, part of every run's key) is its class and the fields
    that take part in comparison: a field derived from others that would not hash alike twice (a
    reference trajectory, with its wall time) is declared ``field(compare=False)`` beside a field
    that identifies it (its digest)."""

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
    worker_timeout : float
        Seconds [s] the study waits on ``scheduler`` while it has no worker, then stops (``NoWorkers``).
    """

    workers: int = 1
    scheduler: str | None = None
    worker_timeout: float = WORKER_TIMEOUT

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
    """``viz3d-run-<sha256>`` of viz3d's version, the resolved scene's key and the measure's identity:
    equal keys, equal rows."""
    from viz3d import __version__

    h = hashlib.sha256(__version__.encode() + b"\0" + scene.key.encode() + measure_identity(measure))
    return f"viz3d-run-{h.hexdigest()[:32]}"


def measure_identity(measure: Measure) -> bytes:
    """The pickled class name and compared fields of a dataclass measure (see ``Measure``); the
    pickled measure otherwise."""
    if not is_dataclass(measure):
        return pickle.dumps(measure)
    kind = f"{type(measure).__module__}.{type(measure).__qualname__}"
    return pickle.dumps((kind, [(f.name, getattr(measure, f.name)) for f in fields(measure) if f.compare]))


def run_task(task: Task) -> dict:
    """The row of one run (pure: a function of ``task`` only). Whatever the run raises becomes the
    row's ``status`` (``raised <Type>: message``), so a study never loses a point to an exception.
    Ctrl-C (or SIGTERM under the command line) during the run raises ``KeyboardInterrupt`` after it:
    a run stops itself on Ctrl-C and returns what it computed (``viz3d.simulate``), but that row
    describes the interruption, not the scene, and must not enter a study's results."""
    with InterruptWatch() as watch:
        try:
            with scene_on_disk(task.scene) as scene:
                row = task.measure(scene)
        except Exception as exc:  # noqa: BLE001 - a row with the diagnosis instead of a lost study
            row = {"status": f"raised {type(exc).__name__}: {exc}"}
    if watch.received:
        raise KeyboardInterrupt
    return {"status": "ok", **row}


class InterruptWatch(InterruptGuard):
    """Context manager noting whether SIGINT or SIGTERM arrived while it was entered (then handled
    as before: the handler it wraps is called). Only Python-callable handlers on the main thread are
    wrapped (``viz3d.interrupts.InterruptGuard``'s rule); elsewhere ``received`` stays False."""

    received = False

    def _receive(self, signum, frame) -> None:
        self.received = True
        self._previous[signum](signum, frame)


@dataclass(frozen=True)
class Store:
    """The results store of a study: JSON lines ``{"key": ..., "row": {...}}`` in ``path``, one per run,
    appended as runs finish. A line cut short (the process killed while writing it) is ignored when
    read back, and the next line starts on a line of its own; so an interrupted study leaves nothing
    a rerun would misread. One study at a time per store."""

    path: Path

    @classmethod
    def in_folder(cls, out: Path | None) -> Store | None:
        """The store of a study whose output folder is ``out`` (``out/STORE_NAME``); None without a folder."""
        return None if out is None else cls(Path(out) / STORE_NAME)

    def load(self) -> dict[str, dict]:
        """Key -> row of every complete line (the last line of a key wins)."""
        rows = {}
        if self.path.is_file():
            for line in self.path.read_text(encoding="utf-8", errors="replace").splitlines():
                with contextlib.suppress(ValueError, KeyError, TypeError, AttributeError):
                    entry = json.loads(line)
                    if isinstance(entry["row"]["status"], str):
                        rows[entry["key"]] = entry["row"]
        return rows

    def append(self, key: str, row: dict) -> None:
        """Append one line (after a newline if the last line was cut short)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        line = json.dumps({"key": key, "row": row}, default=_plain) + "\n"
        with self.path.open("a+b") as fh:
            if fh.tell() > 0:
                fh.seek(-1, os.SEEK_END)
                line = ("" if fh.read(1) == b"\n" else "\n") + line
            fh.write(line.encode("utf-8"))
            fh.flush()


def plain_row(row: dict) -> dict:
    """``row`` as the results store gives it back (JSON values: arrays and tuples as lists, numpy
    scalars as numbers), so a fresh row and a stored one read alike."""
    return json.loads(json.dumps(row, default=_plain))


def _plain(x: Any) -> Any:
    """JSON form of numpy scalars and arrays."""
    return x.tolist() if hasattr(x, "tolist") else str(x)


def store_note(store: Store | None, outcomes: Sequence[Outcome]) -> str:
    """One line on what a study took from its results store (empty without a store)."""
    if store is None:
        return ""
    runs = [o for o in outcomes if o.key is not None]
    reused = sum(o.cached for o in runs)
    return f"results store {store.path}: {reused} of {len(runs)} runs reused, {len(runs) - reused} run now"


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
        rows[key] = row = plain_row(row)
        if store is not None and not row["status"].startswith("lost"):
            store.append(key, row)
        bar.update(not row["status"] == "ok")

    try:
        _execute(todo, cluster, arrived)
    except NoWorkers as exc:
        kept = (f"; finished runs are kept in {store.path} ({len(rows)} of them from this start), and the same "
                f"command runs only the missing ones" if store is not None else "")
        raise NoWorkers(f"{exc}{kept}") from None
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
        finished = as_completed(futures)
        watch = WorkerWatch(client, cluster) if cluster.scheduler else None
        while not finished.is_empty():
            batch = finished.next_batch(block=watch is None)
            for future in batch:
                arrived(future.key, _row_of(future))
                future.release()
            if watch is not None and batch:
                watch.seen = time.monotonic()  # a run came back: a worker was there
            elif not batch:
                watch.check(finished.count())
                time.sleep(RESULT_POLL_S)


class NoWorkers(ConnectionError):
    """A study's scheduler has had no worker for ``Cluster.worker_timeout`` seconds."""


class WorkerWatch:
    """Looks at a scheduler's workers (at most every ``WORKER_POLL_S``) while a study waits for runs;
    ``check`` raises ``NoWorkers`` once none has been attached for ``cluster.worker_timeout`` [s]."""

    def __init__(self, client, cluster: Cluster):
        self.client, self.cluster = client, cluster
        self.seen = self.looked = time.monotonic()

    def check(self, n_waiting: int) -> None:
        now = time.monotonic()
        if now - self.looked < WORKER_POLL_S:
            return
        self.looked = now
        if self.client.nthreads():
            self.seen = now
        elif now - self.seen > self.cluster.worker_timeout:
            address = self.cluster.scheduler
            raise NoWorkers(f"--scheduler {address}: no Dask worker attached for {self.cluster.worker_timeout:g} s "
                            f"(--worker-timeout) while {n_waiting} run(s) were waiting. Start "
                            f"workers with `dask worker {address} --nthreads 1` (one per core of each machine), "
                            f"give them longer with --worker-timeout SECONDS, or leave out --scheduler to run on "
                            f"this machine's cores")


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
