"""Every study resumes: ``viz3d stability`` (and bench, stowage) keep finished runs in ``--out``'s results
store, as ``viz3d sweep`` does. A study killed mid-way (SIGINT like Ctrl-C, or SIGKILL) and started
again runs only the missing points, and its table equals an uninterrupted run's; an input that changes
a run (its scene, or a setting of the study's measure) runs it again; a study sent to a scheduler with
no worker stops after ``--worker-timeout`` with a message naming the address, and the store keeps
what it had."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from viz3d.bench import BenchRun, bench, reference_digest
from viz3d.cli import EXIT_INTERRUPTED, main
from viz3d.scene.load import load_scene
from viz3d.simulate import simulate
from viz3d.stowagestudy import stowage_study
from viz3d.studies.execute import STORE_NAME, Store, task_key
from viz3d.studies.resolved import resolve

from conftest import ROOT, SCENES

SCENE = SCENES / "spherical_pendulum.toml"
METHODS = ["rk4", "heun", "euler", "trapezoidal", "rk4+quaternion", "heun+quaternion"]
#: A methods map of six short NumPy-path runs (0.2-0.5 s each: a kill lands between two rows).
STUDY = ["stability", str(SCENE), "--methods", ",".join(METHODS), "--dt", "1e-3", "--t-end", "0.3",
         "--set", "sim.compiled=false", "--workers", "1"]
DASK = Path(sys.executable).parent / "dask"
#: Seconds a started process may take (startup, the reference run, the study) before the test gives up.
PATIENCE = 120.0


def _viz3d(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "viz3d", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _entries(out: Path) -> list[str]:
    """Keys of the store's complete lines, in order (a line cut short by a kill is not one)."""
    keys = []
    for line in (out / STORE_NAME).read_text().splitlines() if (out / STORE_NAME).exists() else []:
        try:
            keys.append(json.loads(line)["key"])
        except ValueError:
            pass
    return keys


def _kill_after_rows(proc: subprocess.Popen, out: Path, rows: int, sig: int) -> tuple[int, str]:
    """Send ``sig`` to ``proc`` once the store holds ``rows`` complete lines; the lines it held at
    the end, and its stderr."""
    deadline = time.monotonic() + PATIENCE
    while len(_entries(out)) < rows and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=PATIENCE)
    return len(_entries(out)), stderr


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    """The study's folder after one run from start to end."""
    out = tmp_path_factory.mktemp("uninterrupted")
    assert main([*STUDY, "--out", str(out)]) == 0
    return out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
def test_a_killed_study_started_again_runs_only_the_missing_points(sig, uninterrupted, tmp_path):
    out = tmp_path / "study"
    proc = _viz3d(*STUDY, "--out", str(out))
    done, stderr = _kill_after_rows(proc, out, 2, sig)
    assert 2 <= done < len(METHODS), f"not killed mid-study: {done} rows"
    if sig == signal.SIGINT:
        assert proc.returncode == EXIT_INTERRUPTED
        assert "the same command runs only the missing ones" in stderr
    before = _entries(out)
    again = _viz3d(*STUDY, "--out", str(out))
    stdout, stderr = again.communicate(timeout=PATIENCE)
    assert again.returncode == 0, stderr[-2000:]
    assert f"{done} of {len(METHODS)} runs reused, {len(METHODS) - done} run now" in stdout
    keys = _entries(out)
    assert keys[:done] == before and len(keys) == len(set(keys)) == len(METHODS)  # none ran twice
    assert sorted(keys) == sorted(_entries(uninterrupted))
    assert (out / "stability.csv").read_text() == (uninterrupted / "stability.csv").read_text()


@pytest.mark.parametrize("change", [["--t-end", "0.25"], ["--dt", "2e-3"], ["--set", "bodies.rod.density=2800.0"]],
                         ids=["measure t_end", "step", "scene value"])
def test_an_input_that_changes_the_runs_runs_them_again(change, uninterrupted, tmp_path, capsys):
    (tmp_path / STORE_NAME).write_bytes((uninterrupted / STORE_NAME).read_bytes())
    assert main([*STUDY, "--out", str(tmp_path), *change]) == 0
    assert f"0 of {len(METHODS)} runs reused, {len(METHODS)} run now" in capsys.readouterr().out
    assert len(_entries(tmp_path)) == 2 * len(METHODS)


def test_a_line_cut_short_by_a_kill_is_never_read_and_the_next_starts_its_own_line(tmp_path):
    store = Store(tmp_path / STORE_NAME)
    store.append("a", {"status": "ok", "x": 1.0})
    with store.path.open("ab") as fh:
        fh.write(b'{"key": "b", "row": {"status": "ok", "x"')  # SIGKILL while writing
    store.append("c", {"status": "ok", "x": [1.0, float("nan")]})
    with store.path.open("a") as fh:
        fh.write('{"key": "d", "row": {"x": 2}}\n')  # no status: not a row of a run
    rows = store.load()
    assert list(rows) == ["a", "c"] and rows["c"]["x"][0] == 1.0


def test_a_measure_is_identified_by_its_settings_not_by_its_references_wall_time():
    scene = resolve(load_scene(SCENE, ["sim.t_end=0.05", "sim.compiled=false"]))
    ref = simulate(load_scene(SCENE, ["sim.t_end=0.05", "sim.compiled=false"]))
    again = dataclasses.replace(ref, wall_time=ref.wall_time + 1.0)
    key = task_key(scene, BenchRun(ref, reference_digest(ref), 0.05, 0.01))
    assert task_key(scene, BenchRun(again, reference_digest(again), 0.05, 0.01)) == key
    assert task_key(scene, BenchRun(ref, reference_digest(ref), 0.04, 0.01)) != key
    moved = dataclasses.replace(ref, position=ref.position + 1e-9)
    assert task_key(scene, BenchRun(moved, reference_digest(moved), 0.05, 0.01)) != key


@pytest.mark.parametrize("study", ["bench", "stowage"])
def test_bench_and_stowage_keep_their_runs_in_the_folder(study, tmp_path):
    short = ["sim.compiled=false"]
    if study == "bench":
        def make():
            return bench(SCENE, ["rk4", "heun"], dts=[1e-3, 2e-3], t_end=0.1, progress=False, overrides=short,
                         out=tmp_path)
    else:
        def make():
            return stowage_study(SCENE, {"sim.dt": [1e-3, 2e-3]}, [*short, "sim.t_end=0.1"], out=tmp_path)
    n = 4 if study == "bench" else 2
    first, second = make(), make()
    assert f"0 of {n} runs reused, {n} run now" in first.note
    assert f"{n} of {n} runs reused, 0 run now" in second.note and len(_entries(tmp_path)) == n


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for_port(port: int) -> None:
    deadline = time.monotonic() + PATIENCE
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise TimeoutError(f"no scheduler on port {port}")


def test_a_scheduler_without_workers_stops_the_study_after_the_timeout(uninterrupted, tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        _wait_for_port(port)
        stored = (uninterrupted / STORE_NAME).read_bytes()
        (tmp_path / STORE_NAME).write_bytes(stored)
        study = [*STUDY[:3], ",".join([*METHODS, "euler+quaternion"]), *STUDY[4:-2]]
        done = subprocess.run([sys.executable, "-m", "viz3d", *study, "--scheduler", address, "--worker-timeout", "2",
                               "--out", str(tmp_path)], cwd=ROOT, capture_output=True, text=True, timeout=PATIENCE)
    finally:
        os.killpg(scheduler.pid, signal.SIGKILL)
        scheduler.wait()
    assert done.returncode == 2, done.stderr[-2000:]
    for words in (address, "no Dask worker attached for 2 s", "--worker-timeout", f"dask worker {address}",
                  str(tmp_path / STORE_NAME)):
        assert words in done.stderr, done.stderr
    assert (tmp_path / STORE_NAME).read_bytes() == stored
