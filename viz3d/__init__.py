"""viz3d: spatial multibody simulation you can watch.

Public entry points::

    scene = viz3d.load_scene("scenes/heavy_top.toml", overrides=["sim.dt=5e-4"])
    traj = viz3d.simulate(scene)          # headless run -> Trajectory
    traj.save("top.npz")
    system, state = viz3d.build(scene)    # the frozen model and its initial state

The entry points are imported on first use (module ``__getattr__``): ``import viz3d.cli`` or any
submodule does not pay for the whole engine, only for what it imports itself.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: Public name -> the module that defines it.
_API = {
    "build": "viz3d.scene.build",
    "Scene": "viz3d.scene.load",
    "load_scene": "viz3d.scene.load",
    "SceneError": "viz3d.scene.schema",
    "Simulation": "viz3d.simulate",
    "simulate": "viz3d.simulate",
    "Trajectory": "viz3d.trajectory",
}

__all__ = ["__version__", "Scene", "SceneError", "Simulation", "Trajectory", "build", "load_scene", "simulate"]

if TYPE_CHECKING:  # what static tools see; at run time ``__getattr__`` imports on demand
    from viz3d.scene.build import build
    from viz3d.scene.load import Scene, load_scene
    from viz3d.scene.schema import SceneError
    from viz3d.simulate import Simulation, simulate
    from viz3d.trajectory import Trajectory


def __getattr__(name: str):
    """The public entry point ``name``, imported from its module on first use."""
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'viz3d' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))


class _Package(types.ModuleType):
    """The package's module type: importing the submodule ``viz3d.simulate`` binds it as an
    attribute of the package, which would hide the function ``viz3d.simulate``; a public name is
    never replaced by a submodule (the eager imports this replaces rebound it the same way)."""

    def __setattr__(self, name: str, value) -> None:
        if name in _API and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
