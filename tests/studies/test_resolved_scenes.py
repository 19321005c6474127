"""Scenes travel resolved: a run needs nothing from the disk of the machine that started the study
(the mesh file's bytes travel with the tables), and the run's key changes with those bytes."""

from __future__ import annotations

import shutil

from viz3d.scene.load import load_scene
from viz3d.studies.execute import Task, run_task, task_key
from viz3d.studies.resolved import resolve
from viz3d.sweep import Summary

from conftest import SCENES

#: A short run of the mesh scene (steel T-handle, mass properties from the mesh's volume).
SHORT = ["sim.t_end=0.05", "sim.compiled=false"]


def test_a_scene_with_a_mesh_file_runs_after_its_files_are_gone(tmp_path):
    folder = tmp_path / "study"
    shutil.copytree(SCENES / "meshes", folder / "meshes")
    shutil.copy(SCENES / "torque_free.toml", folder)
    resolved = resolve(load_scene(folder / "torque_free.toml", SHORT))
    assert [name for name, _ in resolved.files] == ["meshes/t_handle.stl"]
    expected = run_task(Task("k", resolved, Summary()))
    shutil.rmtree(folder)
    row = run_task(Task("k", resolved, Summary()))
    assert row["status"] == "ok" and row["n_steps"] == expected["n_steps"] > 0
    assert row["energy_drift_rel"] == expected["energy_drift_rel"]


def test_the_key_follows_tables_overrides_and_file_bytes():
    resolved = resolve(load_scene(SCENES / "torque_free.toml", SHORT))
    same = resolve(load_scene(SCENES / "torque_free.toml", SHORT))
    assert task_key(resolved, Summary()) == task_key(same, Summary())
    other = resolve(load_scene(SCENES / "torque_free.toml", ["sim.t_end=0.06", "sim.compiled=false"]))
    assert other.key != resolved.key
    (name, content), = resolved.files
    edited = type(resolved)(resolved.name, resolved.data, resolved.overrides, ((name, content + b"\n"),))
    assert edited.key != resolved.key
