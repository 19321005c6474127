"""Shared fixtures: repository paths and a small helper to write scene files."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
sys.path.insert(0, str(Path(__file__).parent))  # tests/references.py


@pytest.fixture
def write_scene(tmp_path):
    """Write ``text`` to a scene file in a temporary directory and return its path."""

    def write(text: str, name: str = "scene.toml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return write


def scene_files(kind: str = "multibody") -> list[Path]:
    """The shipped scene files of one kind (``viz3d.scene.load.Scene.kind``): "multibody" or "hydro"."""
    from viz3d.scene.load import kind_of_file

    return [p for p in sorted(SCENES.glob("*.toml")) if kind_of_file(p) == kind]


#: What each of the first two pytest-xdist workers compiles before its first test, on a cold numba
#: cache: the compiled kernel's entry for rigid systems, and its second signature, for systems with
#: shape contacts (``viz3d.compiled.Items.present_only``). Each is minutes of CPU; compiled at once on
#: the two workers they cost one compilation's wall time, and a worker that needs the other's waits on
#: its lock (``viz3d.compiled._lock_compiles``) and loads it from the cache instead of compiling it
#: again. On a warm cache this is a short run of each scene.
WARM_UP = {"gw0": ("torque_free.toml", 0.01), "gw1": ("anchor_hoist.toml", 0.05)}


@pytest.fixture(scope="session", autouse=True)
def _warm_kernel(request):
    worker = getattr(request.config, "workerinput", {}).get("workerid")  # (None without xdist)
    if worker not in WARM_UP:
        return
    from viz3d.simulate import simulate

    name, t_end = WARM_UP[worker]
    simulate(SCENES / name, t_end=t_end)
