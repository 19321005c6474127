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
