"""Shared fixtures: repository paths and a small helper to write scene files."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
sys.path.insert(0, str(Path(__file__).parent))  # tests/references.py


@pytest.fixture(autouse=True)
def _mesh_cache(tmp_path_factory, monkeypatch):
    """Each test its own disk cache of mesh files' mass properties (``viz3d.geometry.mesh_cache_dir``),
    its subprocesses too: none reads another test's entries, nor the user's."""
    monkeypatch.setenv("VIZ3D_CACHE_DIR", str(tmp_path_factory.mktemp("viz3d-cache")))


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
#: cache: the compiled kernel's signatures that many tests share, split so that the two compile at
#: once (about 170 s and 200 s of CPU): on gw0 the rigid one and the adaptive driver, on gw1 the one
#: for systems with shape contacts (``viz3d.compiled.Items.present_only``) and the compiled ALI3-P.
#: A worker that needs a signature the other is compiling waits on its lock
#: (``viz3d.compiled._lock_compiles``), its core idle, and then loads it from the cache; compiled
#: here, they are ready before either worker's first test (measured 2026-11-27: a test that met
#: the adaptive driver being compiled waited 35 s). The callees both kernels call (the projection,
#: the constraint rows) are compiled once too, by the first worker to need them: measured at
#: af6b510, both warm-ups at once on a cold cache, gw0 158 s of CPU in 160 s, gw1 165 s in 201 s
#: (it waited 35 s for them) against 168 and 206 s of CPU before, when each compiled its own; gw1
#: warming up the compiled ALI3-P first instead left gw0 waiting 80 s for the rigid entry the
#: ALI3-P run compiles too. On a warm cache this is a short run of each scene.
WARM_UP = {
    "gw0": (("torque_free.toml", 0.01, ()), ("flexible_pendulum.toml", 0.01, ()),
            ("chain.toml", 0.01, ("sim.formulation=ali3p", "sim.integrator=trapezoidal"))),
    "gw1": (("anchor_hoist.toml", 0.05, ()),),
}


@pytest.fixture(scope="session", autouse=True)
def _warm_kernel(request):
    worker = getattr(request.config, "workerinput", {}).get("workerid")  # (None without xdist)
    from viz3d.simulate import simulate

    for name, t_end, overrides in WARM_UP.get(worker, ()):
        simulate(SCENES / name, overrides=list(overrides), t_end=t_end)
