"""Scenes that travel resolved: a validated scene's tables with the bytes of the files it reads, so a
run on another machine needs nothing from the file system of the machine that started the study.

Generated meshes travel as their generator's name and parameters (they are in the tables already);
mesh files and a ground-motion record travel as bytes, and are written into a private temporary
folder where the run happens.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path, PurePath

from viz3d.scene.load import Scene


@dataclass(frozen=True)
class ResolvedScene:
    """A scene as data.

    Attributes
    ----------
    name : str
        File name of the scene (``bouncing_sphere.toml``); runs name it as their source.
    data : dict
        ``Scene.data``: validated tables, overrides applied, generators expanded (JSON values).
    overrides : tuple of str
        The ``key.path=value`` overrides applied.
    files : tuple of (str, bytes)
        Each file the scene reads, by the name the scene gives it (relative to its folder), and its
        content.
    """

    name: str
    data: dict
    overrides: tuple[str, ...]
    files: tuple[tuple[str, bytes], ...] = ()

    @property
    def key(self) -> str:
        """SHA-256 (hex) of the tables, the overrides and the files' contents: equal keys run alike."""
        h = hashlib.sha256(json.dumps(self.data, sort_keys=True).encode())
        h.update(json.dumps(self.overrides).encode())
        for name, content in self.files:
            h.update(name.encode() + b"\0" + hashlib.sha256(content).digest())
        return h.hexdigest()


def resolve(scene: Scene) -> ResolvedScene:
    """``scene`` as data: its tables and the bytes of every file it names (already checked to lie
    within reach by ``load_scene``)."""
    names = dict.fromkeys(table["file"] for table in file_tables(scene.data))
    files = tuple((name, (scene.base_dir / name).read_bytes()) for name in names)
    return ResolvedScene(scene.path.name, scene.data, tuple(scene.overrides), files)


def file_tables(data: dict) -> list[dict]:
    """The tables of ``data`` that name a file (``file`` key): mesh shapes of bodies and of the
    collision ground, and a hydro scene's ground-motion record."""
    tables = [b.get("shape", {}) for b in data.get("bodies", [])]
    tables += list(data.get("collision", {}).get("ground", []))
    tables.append(data.get("ground_motion", {}))
    return [t for t in tables if isinstance(t, dict) and "file" in t]


@contextlib.contextmanager
def scene_on_disk(resolved: ResolvedScene) -> Iterator[Scene]:
    """The ``Scene`` of ``resolved``, its files written into a private temporary folder (removed on
    exit); file names in the tables are renamed to the copies (``files/<i>-<name>``)."""
    if not resolved.files:
        yield Scene(Path(resolved.name), resolved.data, resolved.overrides)
        return
    with tempfile.TemporaryDirectory(prefix="viz3d-run-") as folder:
        root = Path(folder)
        (root / "files").mkdir()
        copies = {}
        for i, (name, content) in enumerate(resolved.files):
            copies[name] = f"files/{i}-{PurePath(name).name}"
            (root / copies[name]).write_bytes(content)
        data = json.loads(json.dumps(resolved.data))
        for table in file_tables(data):
            table["file"] = copies[table["file"]]
        yield Scene(root / resolved.name, data, resolved.overrides)
