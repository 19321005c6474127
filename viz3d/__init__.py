"""viz3d: spatial multibody simulation you can watch.

Public entry points::

    scene = viz3d.load_scene("scenes/heavy_top.toml", overrides=["sim.dt=5e-4"])
    traj = viz3d.simulate(scene)          # headless run -> Trajectory
    traj.save("top.npz")
    system, state = viz3d.build(scene)    # the frozen model and its initial state
"""

from __future__ import annotations

__version__ = "0.1.0"

from viz3d.scene.build import build
from viz3d.scene.load import Scene, load_scene
from viz3d.scene.schema import SceneError
from viz3d.simulate import Simulation, simulate
from viz3d.trajectory import Trajectory

__all__ = ["__version__", "Scene", "SceneError", "Simulation", "Trajectory", "build", "load_scene", "simulate"]
